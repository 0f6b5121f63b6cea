// The fast approximate blur with 32-byte vectors and fused multiply-adds (-mavx2 -mfma for this
// file only); called only where the CPU has both (blur_fast.cpp).
#define BLOOMREF_ISA_NAMESPACE isa_avx2_fma
#define BLOOMREF_VEC_BYTES 32
#define BLOOMREF_APPROX_FMA 1
#define BLOOMREF_APPROX_FN blur_approx_avx2_fma
#define BLOOMREF_APPROX_ROWS_FN blur_approx_rows_avx2_fma
#include "blur_approx.inc"
