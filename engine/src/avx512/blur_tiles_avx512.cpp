// The fast blur's tile kernel with 64-byte vectors; built with -mavx512f (nothing may be fused:
// -ffp-contract=off as everywhere in the library) and only called where the CPU has AVX-512F
// (blur_fast.cpp checks at run time).
#define BLOOMREF_ISA_NAMESPACE isa_avx512
#define BLOOMREF_VEC_BYTES 64
// 6: a fused horizontal pass line (32 rows x 3 floats = 96) is six 16-float vectors, one group.
#define BLOOMREF_GROUP 6
#define BLOOMREF_TILE_FN blur_tiles_avx512
#define BLOOMREF_INEXACT_FN blur_inexact_group_avx512
#define BLOOMREF_INEXACT_COLUMNS_FN blur_inexact_columns_avx512
#include "blur_tiles.inc"
