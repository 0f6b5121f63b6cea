// The plan's row scan with 32-byte vectors (two pixels a vector); built with -mavx2 (no FMA:
// nothing may be fused) and only called where the CPU has AVX2 (scan_kernel_for).
#define BLOOMREF_SCAN_LANES 8
#define BLOOMREF_SCAN_FN scan_row_avx2
#include "scan_kernels.inc"
