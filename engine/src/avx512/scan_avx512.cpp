// The plan's row scan with 64-byte vectors (four pixels a vector); built with -mavx512f and only
// called where the CPU has AVX-512F (scan_kernel_for).
#define BLOOMREF_SCAN_LANES 16
#define BLOOMREF_SCAN_FN scan_row_avx512
#include "scan_kernels.inc"
