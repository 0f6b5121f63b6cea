// bloomref — the inline namespace each instruction set's inline code lives in.
//
// The inline helpers (oracle_math.h, simd_lanes.h) are compiled once per instruction set: in the
// baseline files and in the -mavx2 kernels. A copy the compiler does not inline is a weak
// symbol, of which the linker keeps one for the whole program, so AVX2 code could run where the
// CPU lacks it (or the AVX2 kernel run the baseline copy). A kernel file defines
// BLOOMREF_ISA_NAMESPACE before its includes; everything else gets isa_baseline.
// scripts/check-isa-symbols (a unit test) looks for such shared symbols.
#pragma once

#ifndef BLOOMREF_ISA_NAMESPACE
#define BLOOMREF_ISA_NAMESPACE isa_baseline
#endif
