// bloomref — lane shuffles of GCC/Clang vector-extension types with lane indices known at
// compile time, under both compilers: GCC spells them __builtin_shuffle(a, [b,] mask vector),
// Clang __builtin_shufflevector(a, b, indices...). The same lanes either way (GCC builds are
// unchanged; Clang builds the sanitizer and fuzzing configurations).
//   BLOOMREF_SHUFFLE(I, a, i0, i1, ...)       lanes of a;         I: a's integer twin type
//   BLOOMREF_SHUFFLE2(I, a, b, i0, i1, ...)   lanes of a, then b  (index n + k is b's lane k)
#pragma once

#if defined(__clang__)
#define BLOOMREF_SHUFFLE(I, a, ...) __builtin_shufflevector(a, a, __VA_ARGS__)
#define BLOOMREF_SHUFFLE2(I, a, b, ...) __builtin_shufflevector(a, b, __VA_ARGS__)
#else
#define BLOOMREF_SHUFFLE(I, a, ...) __builtin_shuffle(a, I{__VA_ARGS__})
#define BLOOMREF_SHUFFLE2(I, a, b, ...) __builtin_shuffle(a, b, I{__VA_ARGS__})
#endif
