// The fast finishing stages' row kernel with 32-byte vectors; built with -mavx2 (no -mfma:
// nothing may be fused) and only called where the CPU has AVX2 (stages_fast.cpp checks).
// Four double lanes (one ymm register) measured faster than eight (GCC splits those in two).
#define BLOOMREF_ISA_NAMESPACE isa_avx2
#define BLOOMREF_FINISH_LANES 4
#define BLOOMREF_FINISH_FN finish_row_avx2
#include "finish_kernels.inc"
