// The fast blur's tile kernel with 32-byte vectors; built with -mavx2 (no -mfma: nothing may
// be fused) and only called where the CPU has AVX2 (blur_fast.cpp checks at run time).
#define BLOOMREF_ISA_NAMESPACE isa_avx2
#define BLOOMREF_VEC_BYTES 32
#define BLOOMREF_GROUP 4
#define BLOOMREF_TILE_FN blur_tiles_avx2
#define BLOOMREF_INEXACT_FN blur_inexact_group_avx2
#define BLOOMREF_INEXACT_COLUMNS_FN blur_inexact_columns_avx2
#include "blur_tiles.inc"
