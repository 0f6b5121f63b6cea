// The fast finishing stages' row kernel with 64-byte vectors: eight double lanes in one zmm
// register (with AVX2 eight lanes measured slower than four: GCC splits them in two). Built with
// -mavx512f -mf16c (no FMA: nothing may be fused) and only called where the CPU has AVX-512F
// besides AVX2, FMA and F16C (blur_fast.cpp, cpu_has_avx512).
#define BLOOMREF_ISA_NAMESPACE isa_avx512
#define BLOOMREF_FINISH_LANES 8
#define BLOOMREF_FINISH_FN finish_row_avx512
#include "finish_kernels.inc"
