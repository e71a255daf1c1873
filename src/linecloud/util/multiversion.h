// Function multiversioning for the hot kernels of the minimal solvers.
//
// LINECLOUD_TARGET_CLONES compiles a function twice — for x86-64-v3 (AVX2 and
// FMA) and for the build's own target — and the dynamic loader picks one per
// machine (GCC/Clang `target_clones`, an ifunc). The build stays portable: no
// -march flag, the generic clone runs everywhere else. Only code inlined into
// the function gets the wider instructions, so its helpers are marked
// LINECLOUD_INLINE_INTO_CLONES and its loops work on raw storage (no Eigen
// kernel whose out-of-line instantiation another translation unit might
// share). Define LINECLOUD_NO_MULTIVERSIONING to build one generic version.
#pragma once

#if defined(__x86_64__) && defined(__ELF__) && (defined(__GNUC__) || defined(__clang__)) && \
    !defined(LINECLOUD_NO_MULTIVERSIONING)
#define LINECLOUD_TARGET_CLONES __attribute__((target_clones("arch=x86-64-v3", "default")))
#define LINECLOUD_INLINE_INTO_CLONES inline __attribute__((always_inline))
#else
#define LINECLOUD_TARGET_CLONES
#define LINECLOUD_INLINE_INTO_CLONES inline
#endif
