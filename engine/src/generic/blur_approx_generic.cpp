// The fast approximate blur with 16-byte vectors and separate multiplies and adds.
#define BLOOMREF_VEC_BYTES 16
#define BLOOMREF_APPROX_FMA 0
#define BLOOMREF_APPROX_FN blur_approx_generic
#define BLOOMREF_APPROX_ROWS_FN blur_approx_rows_generic
#include "blur_approx.inc"
