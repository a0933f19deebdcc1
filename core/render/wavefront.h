// The renderer and the PRB adjoint as a wavefront (kernels/wavefront.cl): the same samples as
// render_pass, render_two_state, adjoint_primal and adjoint_pass, stage by stage over a structure
// of arrays of path state, so that PoCL runs the shading stages SIMD across paths
// (docs/wavefront.md). Chosen by the device policy (core/render/policy.h), the WAVEFRONT flag.
#pragma once

#include "core/render/device_scene.h"

namespace tandem {

/// Whether kernels/wavefront.cl can render a scene with these content flags: area lights and an
/// environment (constant or a map), no point or spot light, MIS. Diffuse materials (textured or
/// not) are shaded in SIMD across paths, the others one path at a time, and so are the primary
/// vertices that read a light-sample reservoir (RESTIR). (What it does not cover renders with the
/// megakernels.)
bool wavefront_supported(const BuildFlags& features);

/// Adds samples [begin, begin + count) of every pixel to scene.accum() (and dropped samples to
/// scene.guards()), the same bits as render_pass: one wave per sample, each a sequence of
/// launches (generate; intersect, shade, shadow per bounce; accumulate). Enqueued, but for one
/// blocking read per bounce: the count of paths alive, which sizes its launches.
void render_samples_wavefront(const View& view, const Buffer<float>& params,
                              gpu::RenderParams rp, int begin, int count);

/// The two-state render (kernels/render.cl: render_two_state) as waves: samples
/// [rp.sample_begin, rp.sample_begin + rp.sample_count) of every pixel, <F_n>_n into
/// scene.accum() and <F_{n-1}>_n into scene.accum_old(), the same bits.
void render_two_state_wavefront(const View& view, const Buffer<float>& params,
                                const Buffer<float>& params_old, gpu::RenderParams rp);

/// Light-sample reservoirs for the adjoint's primary vertices (passes.h: PathReservoirs, as
/// the kernels take them): none where buffer is null.
struct WaveReservoirs {
    const Buffer<gpu::Reservoir>* buffer = nullptr;
    /// RESERVOIR_MODE_* | RESTIR_DIRECT_* << RESERVOIR_DIRECT_SHIFT (kernels/path/restir.h); 0:
    /// none
    unsigned mode = 0;
    unsigned spp = 0;  ///< slots per pixel
};

/// The adjoint (kernels/adjoint.cl: adjoint_primal then adjoint_pass) as waves, the same sums,
/// the primary vertices' light samples read from `reservoirs` where it has a buffer: for each
/// sample rp.sample_begin + k, k < rp.sample_count, of every pixel
/// whose delta is not zero, a wave computes its primal radiance L into radiance[k pixels + pixel],
/// recording the path's hits and shadow rays; then a second wave replays it from L, on the
/// recorded hits rather than traced again (deeper bounces than the record holds are), pushing
/// delta 2^s inv_spp times each term's derivative into grad (fixed point) for the elements set
/// in active. Saturated contributions and dropped samples count in scene.guards().
void adjoint_wavefront(const View& view, const Buffer<float>& params, gpu::RenderParams rp,
                       const Buffer<float>& delta, float inv_spp, const Buffer<int>& exponent,
                       Buffer<gpu::float4>& radiance, const Buffer<unsigned>& active,
                       Buffer<unsigned>& grad, const WaveReservoirs& reservoirs = {});

} // namespace tandem
