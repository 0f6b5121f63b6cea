// The fast approximate blur with 64-byte vectors and fused multiply-adds (-mavx512f for this
// file only): the same operations per lane as the 32-byte build, so the same bits; called only
// where the CPU has AVX-512F (blur_fast.cpp).
#define BLOOMREF_ISA_NAMESPACE isa_avx512_fma
#define BLOOMREF_VEC_BYTES 64
#define BLOOMREF_APPROX_FMA 1
#define BLOOMREF_APPROX_FN blur_approx_avx512
#define BLOOMREF_APPROX_ROWS_FN blur_approx_rows_avx512
#include "blur_approx.inc"
