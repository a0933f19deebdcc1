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

#endif // TANDEM_KERNELS_PATH_RANDOM_H
