// The random numbers of one path: counter-based (shared/rng.h), addressed by (seed, pixel, sample,
// dimension) in a fixed layout per bounce, so a later pass can replay the path exactly.
#ifndef TANDEM_KERNELS_PATH_RANDOM_H
#define TANDEM_KERNELS_PATH_RANDOM_H

#include "shared/rng.h"

// Random dimensions: two for the pixel position, then RNG_DIMS_PER_BOUNCE per path vertex.
#define RNG_DIMS_PER_BOUNCE 8u
#define DIM_LIGHT_CHOICE 0u
#define DIM_LIGHT_POINT 1u
#define DIM_BSDF 3u
#define DIM_RR 5u
#define DIM_LOBE 6u
#define DIM_ALIAS 7u

typedef struct PathRng {
    uint seed, pixel, sample;
} PathRng;

static inline PathRng path_rng(uint seed, uint pixel, uint sample) {
    PathRng r;
    r.seed = seed;
    r.pixel = pixel;
    r.sample = sample;
    return r;
}

static inline float path_rand(PathRng rng, uint dim) {
    return rng_uniform(rng.seed, rng.pixel, rng.sample, dim);
}

/// The first dimension of the vertex a ray of this depth finds (depth 0: the camera ray's).
TANDEM_INLINE uint path_dim(uint depth) {
    return 2u + depth * RNG_DIMS_PER_BOUNCE;
}

// The random numbers of one path vertex, dimensions dim + DIM_* (vertex_random). Where the compiler
// targets x86 with AVX (PoCL on CPUs), all eight are hashed at once, in the lanes of one
// rng_uniform8 (about the instructions of one scalar hash: a vertex of indirect-room used five to
// seven of them); elsewhere (GPUs, Oclgrind) each is hashed where it is read, so a path that never
// reads one does not compute it. Both give the same bits. (Packets of camera rays hash their
// samples' pixel positions in lanes on every device: kernels/render.cl.)
#if TANDEM_X86_CLANG
#define PATH_RNG_LANES 1
#else
#define PATH_RNG_LANES 0
#endif

typedef struct VertexRandom {
#if PATH_RNG_LANES
    float8 u; ///< lane k: dimension dim + k
#else
    PathRng rng;
    uint dim;
#endif
} VertexRandom;

/// The random numbers of the vertex whose dimensions start at `dim` (path_dim).
TANDEM_INLINE VertexRandom vertex_random(PathRng rng, uint dim) {
    VertexRandom v;
#if PATH_RNG_LANES
    v.u = rng_uniform8(rng.seed, rng.pixel, rng.sample, dim);
#else
    v.rng = rng;
    v.dim = dim;
#endif
    return v;
}

/// Dimension dim + k of the vertex (k: one of the DIM_* constants): path_rand(rng, dim + k).
TANDEM_INLINE float vertex_rand(VertexRandom v, uint k) {
#if PATH_RNG_LANES
    // k is a constant at every call, so this folds to one lane
    return k == 0u   ? v.u.s0
           : k == 1u ? v.u.s1
           : k == 2u ? v.u.s2
           : k == 3u ? v.u.s3
           : k == 4u ? v.u.s4
           : k == 5u ? v.u.s5
           : k == 6u ? v.u.s6
                     : v.u.s7;
#else
    return path_rand(v.rng, v.dim + k);
#endif
}

#endif // TANDEM_KERNELS_PATH_RANDOM_H
