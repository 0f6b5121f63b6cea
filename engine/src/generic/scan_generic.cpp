// The plan's row scan with the build's baseline vectors (SSE2 on x86-64: one pixel a vector).
#define BLOOMREF_SCAN_LANES 4
#define BLOOMREF_SCAN_FN scan_row_generic
#include "scan_kernels.inc"
