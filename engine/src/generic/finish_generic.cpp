// The fast finishing stages' row kernel with the build's baseline vectors (SSE2 on x86-64).
#define BLOOMREF_FINISH_LANES 4
#define BLOOMREF_FINISH_FN finish_row_generic
#include "finish_kernels.inc"
