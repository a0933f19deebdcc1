// Stratified pixel positions: where in its pixel a camera sample lands. Pure functions of their
// arguments, shared by the kernels (kernels/path/scene.h: path_camera_ray; kernels/render.cl's
// packets of camera rays; kernels/wavefront.cl: wf_generate) and the host tests
// (tests/kernels/shared/test_pixel_sample.cpp).
//
// A 2 x 2 jittered grid whose quadrants a pixel's samples take in turn. Sample k of a pixel lands
// in quadrant (k + o) mod 4, where o, hashed once per pixel and seed, is uniform over 0..3; the
// camera's random numbers (the path's dimensions 0 and 1) place it uniformly inside the quadrant.
// On its own every sample is therefore uniform over its pixel, so any sample count, and any range
// of samples a pass renders, estimates the pixel's integral without bias; and every four
// consecutive samples of a pixel cover its four quadrants once each, which removes the variance
// between quadrants from their mean ("Stratified sampling", Physically Based Rendering, 4th ed.,
// Sec. 8.5; Mitsuba 3's `stratified` sampler stratifies by a random permutation instead).
#ifndef TANDEM_SHARED_PIXEL_SAMPLE_H
#define TANDEM_SHARED_PIXEL_SAMPLE_H

#include "shared/rng.h"

TANDEM_NAMESPACE_BEGIN

/// The sample index of the hash that draws a pixel's quadrant offset: one no path has.
#define PIXEL_OFFSET_SAMPLE 0xffffffffu

/// The quadrant offset o of pixel `pixel` under `seed`, in 0..3.
TANDEM_INLINE uint pixel_quadrant_offset(uint seed, uint pixel) {
    return (uint)(rng_uniform(seed, pixel, PIXEL_OFFSET_SAMPLE, 0u) * 4.0f); // u < 1, exact
}

/// The quadrant of sample `sample` of a pixel whose offset is `offset`: bit 0 the horizontal
/// half, bit 1 the vertical one.
TANDEM_INLINE uint pixel_quadrant(uint sample, uint offset) {
    return (sample + offset) & 3u;
}

/// The coordinate across the pixel, in [0, 1], of the point at u in [0, 1) across its half `side`
/// (0 or 1). Exact but for 1 + u, which rounds to a multiple of 2^-23 (to 2, the pixel's edge,
/// for the largest u, 1 - 2^-24).
TANDEM_INLINE float pixel_stratified(float u, uint side) {
    return 0.5f * ((float)side + u);
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_PIXEL_SAMPLE_H
