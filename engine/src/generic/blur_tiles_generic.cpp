// The fast blur's tile kernel with 16-byte vectors (SSE2 on x86-64, NEON elsewhere).
#define BLOOMREF_VEC_BYTES 16
#define BLOOMREF_GROUP 8
#define BLOOMREF_TILE_FN blur_tiles_generic
#define BLOOMREF_INEXACT_FN blur_inexact_group_generic
#define BLOOMREF_INEXACT_COLUMNS_FN blur_inexact_columns_generic
#include "blur_tiles.inc"
