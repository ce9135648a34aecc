// SPDX-License-Identifier: Apache-2.0
// TESSERA_ISA_CLONES: compile a function twice, for AVX2 and for the x86-64 baseline the project
// builds for, and pick the version once at load time by what the CPU has (GCC's function
// multiversioning: the target_clones attribute and an ifunc resolver).
//
// Why: the SIMD stages of a sample are Highway code, compiled for every target and dispatched at
// run time, but the code between them (a packet's bookkeeping, the lanes' material and primitive
// lookups, the camera rays, the checker's floor) is plain C++ that the compiler vectorizes by
// itself, and at the baseline it may use only SSE2: two-operand instructions, 4-wide vectors,
// floor as a branchy integer sequence. With its AVX2 versions the renderer runs 7 % fewer
// instructions a sample on the Whitted showcase (1450 -> 1348; docs/performance.md, "Packets and
// SIMD stages").
//
// The answers do not depend on the version: the project builds with -ffp-contract=off (no fused
// multiply-add is formed in either), the AVX2 target does not include FMA, and every operation
// is IEEE-rounded alike at either width (floor is exact either way), so both give the same bits.
// Only GCC on x86-64: clang 14 does not accept the attribute on member functions, and the
// sanitizer builds leave it out (an ifunc resolver runs before their run-time is set up). Those
// builds compile the baseline version alone.
//
// TESSERA_ISA_CLONES_FLAT adds `flatten`: every call in the function's body to a function whose
// code the compiler sees is inlined, into each version (a helper left out of line would be
// compiled for the baseline only). Only where the versions are made: under AddressSanitizer a
// flattened radiance_packet took 78 KB of stack per recursion level (every inlined local gets its
// own red zones), and a deep glass tree overflowed a worker thread's stack.
#pragma once

#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__SANITIZE_ADDRESS__) && \
    !defined(__SANITIZE_THREAD__)
#define TESSERA_ISA_CLONES __attribute__((target_clones("avx2", "default")))
#define TESSERA_ISA_CLONES_FLAT __attribute__((target_clones("avx2", "default"), flatten))
#else
#define TESSERA_ISA_CLONES
#define TESSERA_ISA_CLONES_FLAT
#endif
