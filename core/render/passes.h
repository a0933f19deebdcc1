// The render passes: functions of a device scene and parameter buffers. Each enqueues its kernels
// and returns without waiting; results are valid once the queue has finished (a download, or
// Context::finish). Stages are named "render", "resolve", "adjoint" and "decode gradients" for
// the device timing (Context::set_stage_timing). Adding a pass means a kernel file and a function
// here, not a change to a class that owns everything.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/render/device_scene.h"
#include "core/render/gradient_buffers.h"
#include "shared/reservoir.h"

namespace tandem {

/// The flat parameter buffer (layout of scene.params) with the scene's own values.
Buffer<float> parameter_buffer(Context& ctx, const ParamRegistry& params);

/// Throws Error naming `what` where the scene has participating media or null bsdfs (HAS_MEDIA):
/// light-sample reuse covers surfaces only so far (the primal and two-state renders and the path
/// replay cover both).
void require_surfaces(const DeviceScene& scene, const char* what);

/// A resampling pass (kernels/path/resample.h) not run yet: the pass whose paths read the
/// reservoirs runs it at each path's own first hit, so that the camera ray is traced once for
/// both (docs/restir.md, "One pass fewer"). What it reads besides the paths' parameters and seed.
struct PathResample {
    const Buffer<float>* params_old = nullptr;    ///< theta_{n-1}: the previous reservoirs' domain
    const Buffer<gpu::Reservoir>* prev = nullptr; ///< the previous iteration's reservoirs
    const Buffer<unsigned>* active = nullptr;     ///< bits of the differentiated elements
    /// the gradient they serve: where it differentiates vertex positions, the pass follows the
    /// shapes as the adjoint does (prepare_shape_passes)
    const GradientBuffers* grad = nullptr;
    gpu::RestirParams params{};                   ///< its spp is PathReservoirs::spp
    bool serve_all = false; ///< every slot gets a reservoir (a light's radiance is differentiated)
};

/// Light-sample reservoirs a pass's paths read at their primary vertex instead of drawing NEE's
/// sample (ReSTIR: core/inverse/restir.h, kernels/path/restir.h): the adjoint's (backward) or
/// the primal chain's (render). None by default.
struct PathReservoirs {
    const Buffer<gpu::Reservoir>* buffer = nullptr; ///< `spp` slots per pixel, pixel-major
    unsigned spp = 0;                               ///< must equal the pass's spp
    bool trace_visibility = false; ///< resampled without visibility: the paths trace it
    /// the share of direct light they estimate (RESTIR_DIRECT_*, kernels/shared/reservoir.h): as
    /// the pass that resampled them (RestirParams::direct)
    unsigned direct = RESTIR_DIRECT_MIS;
    /// Set: `buffer` is to be resampled first, by the pass itself (fused where it can, else by
    /// resample_reservoirs() before its paths), from the paths' parameters and seed.
    std::optional<PathResample> resample;

    /// The word the kernels read them by (kernels/path/restir.h: RESERVOIR_MODE_* |
    /// RESTIR_DIRECT_* << RESERVOIR_DIRECT_SHIFT); 0 without a buffer.
    unsigned mode() const {
        if (!buffer) return 0u;
        return (trace_visibility ? 2u : 1u) | direct << 2u;
    }
};

/// Primal render (kernels/render.cl: render_pass): spp paths per pixel of the parameter state
/// `params` with `seed`; writes their mean to rgb (3 floats per pixel, row-major from the top
/// left). Non-finite samples are dropped and counted in scene.guards(). With `reservoirs` (a
/// scene built with RESTIR=1, and `resample` set; kernels/render.cl: render_pass_resample), each
/// path first resamples its slot's reservoir at its first hit, then takes its primary NEE term
/// from it; that render is a megakernel whose camera rays are traced one by one, whatever the
/// scene's WAVEFRONT and CAMERA_PACKETS flags.
void render(const View& view, const Buffer<float>& params, std::uint32_t seed, int spp,
            Buffer<float>& rgb, const PathReservoirs& reservoirs = {});

/// The resampling pass of `reservoirs` (its `resample`, which must be set) on its own
/// (kernels/restir.cl: restir_resample), for the paths of parameters `params` and seed `seed`:
/// writes *reservoirs.buffer. Non-finite targets and weights are counted in scene.guards().
void resample_reservoirs(const View& view, const Buffer<float>& params, std::uint32_t seed,
                         const PathReservoirs& reservoirs);

/// The fused two-state render (CV-PS; kernels/render.cl: render_two_state): spp paths per pixel
/// sampled from `params` (theta_n) with `seed`, each also estimating `params_old`
/// (theta_{n-1}) along the same path; writes <F_n>_n to rgb and <F_{n-1}>_n to rgb_old.
void render_two_state(const View& view, const Buffer<float>& params,
                      const Buffer<float>& params_old, std::uint32_t seed, int spp,
                      Buffer<float>& rgb, Buffer<float>& rgb_old);

/// How backward() runs the adjoint's megakernels: samples per launch, and the bounces whose hits
/// adjoint_primal records for adjoint_pass (kernels/path/record.h).
struct AdjointLaunches {
    int samples;
    unsigned hit_bounces;
};

/// The launches of backward() for `pixels` pixels and paths of at most `max_depth` bounces
/// (0xFFFFFFFF: unbounded). Every bounce a path can trace is recorded (max_depth of them), at
/// most `hit_record_bounces` (the policy's: DevicePolicy::hit_record_bounces, 32 unless the
/// Tuning asks for fewer), unless the wavefront runs the adjoint (`wavefront`: it has its own
/// record). The replay reads what it would have traced instead of tracing it again, so the
/// gradients keep their bits and the replay saves the traversals. The scratch (16 bytes per
/// sample of a launch, and 16 per recorded bounce) stays within 512 MiB: fewer samples per
/// launch first (4 at most), then fewer recorded bounces.
AdjointLaunches adjoint_launches(std::size_t pixels, unsigned max_depth, bool wavefront,
                                 unsigned hit_record_bounces = k_max_hit_record_bounces);

/// Path Replay Backpropagation (kernels/adjoint.cl): given delta = dloss/d(image) (3 floats per
/// pixel) of an image of spp samples per pixel, replays spp paths per pixel of `params` with
/// `seed` and writes dloss/d(params) to grad.value (grad.fixed is left zero). Use a seed
/// independent of the one of the image that fed the loss, so that the product of the two
/// estimates is unbiased. Deterministic bit for bit. The fixed-point units are scaled by 2^s, s
/// chosen on the device from sum |delta| (grad.exponent; kernels/shared/fixed_point.h), so
/// delta 2^k gives a gradient exactly 2^k times as large. Non-finite samples, saturated gradient
/// contributions and wrapped gradient sums are counted in scene.guards(). With `reservoirs`
/// (a scene built with RESTIR=1), each path's primary NEE term is its slot's reservoir's; with
/// reservoirs.resample, the first kernel resamples them first (adjoint_primal_resample), or
/// resample_reservoirs() does where the wavefront runs the adjoint.
void backward(const View& view, const Buffer<float>& params, std::uint32_t seed, int spp,
              const Buffer<float>& delta, GradientBuffers& grad,
              const PathReservoirs& reservoirs = {});

/// backward() in three steps, for a batch of views whose gradients add into one accumulator:
/// choose_gradient_scale() once from every view's delta, accumulate_gradients() per view, then
/// decode_gradients() once. The fixed-point sums are exact and independent of the order of
/// additions, so the batch's words are the sum of its views' words (at the same scale), whatever
/// the order of the views.
///
/// The scale 2^s of the coming accumulation into grad.exponent, chosen on the device from the sum
/// of |delta| over `deltas` in order (each summed in chunks of 4096 elements, in index order; no
/// read-back), or grad.forced_exponent. One delta gives backward()'s scale.
///
/// Where the views of a batch are spread over processes (core/inverse/ranks.h), `deltas` holds
/// null for the views of others, `sizes` every view's element count, and `exchange` makes the
/// host's chunk sums every view's (this process's own are in place, the others' zero); they go
/// back to the device before the exponent, which is then the one a single process chooses.
void choose_gradient_scale(DeviceScene& scene, const std::vector<const Buffer<float>*>& deltas,
                           GradientBuffers& grad, const std::vector<std::size_t>& sizes = {},
                           const std::function<void(std::vector<float>&)>& exchange = {});
/// The sample budgets of the boundary terms of shape gradients, per pixel of the film (Mitsuba's
/// sppp, psdr's sppe and sppse): -1 takes the interior's (the adjoint's spp), 0 leaves the term
/// out.
class SecondaryReservoirs;

struct BoundarySamples {
    int primary = -1;   ///< edge samples on the image plane (kernels/boundary.cl)
    int secondary = -1; ///< edge samples of shadows and reflections
    /// the secondary term's guide (core/render/boundary_guide.h): -1 where secondary_guided(),
    /// 0 off, 1 on (secondary_guide_mode)
    int guide = -1;
    /// the secondary term's light pairs (core/render/boundary.h; off by default: see there)
    bool light_pairs = false;
    /// the secondary term's reservoirs across iterations (core/render/boundary_reuse.h), which
    /// the pass reads and advances; null: no reuse. Light pairs are left out where it is set.
    SecondaryReservoirs* reuse = nullptr;
};

/// What shape gradients of `scene` leave out, as a warning line (with its newline), or "" where
/// none of `params` moves geometry or they leave out nothing: where the scene has mirrors or
/// glass (delta BSDFs), the boundary terms of edges seen through them (no estimator connects an
/// edge to the camera across a delta vertex), and, where one follows a moving vertex on a path,
/// the turn the vertex's motion gives the path after it, which the interior term does not follow
/// (docs/method.md, "Shape gradients").
std::string shape_gradient_gaps(const RenderScene& scene,
                                const std::vector<const Parameter*>& params);

/// Where grad differentiates vertex positions: checks that the passes can follow them
/// (check_shape_gradients, with how `reservoirs` reuse light samples), makes the scene read them
/// back before each pass and builds its kernels with the interior term. Returns whether it does.
bool prepare_shape_passes(DeviceScene& scene, const GradientBuffers& grad,
                          const PathReservoirs& reservoirs);

/// backward()'s replay of spp paths per pixel of view `view`, adding into grad.fixed at the scale
/// grad.exponent holds, without decoding. Where grad differentiates vertex positions
/// (differentiates_geometry), the boundary terms add their samples (`boundary`;
/// core/render/boundary.h).
void accumulate_gradients(const View& view, const Buffer<float>& params, std::uint32_t seed,
                          int spp, const Buffer<float>& delta, GradientBuffers& grad,
                          const PathReservoirs& reservoirs = {}, BoundarySamples boundary = {});
/// accumulate_gradients()'s boundary terms of shape gradients alone (core/render/boundary.h), the
/// same samples for the same seed, on a scene that prepare_shape_passes() prepared for grad and
/// whose geometry is synced to `params` (DeviceScene::sync_geometry).
void accumulate_boundary(const View& view, const Buffer<float>& params, std::uint32_t seed,
                         int spp, const Buffer<float>& delta, GradientBuffers& grad,
                         BoundarySamples boundary = {});
/// grad.value <- the float values of grad.fixed (which is reset to zero); wrapped sums count in
/// scene.guards(), or in `wraps` (a process that decodes the words other processes sum too, whose
/// first process counts them).
void decode_gradients(DeviceScene& scene, GradientBuffers& grad, Buffer<unsigned>* wraps = nullptr);

/// Builds the programs of render() and backward() now (else their first call does), so that
/// a timed loop measures rendering, not compilation.
void prepare_passes(DeviceScene& scene, bool two_state, bool adjoint);

struct RenderOptions {
    int spp = 0;            ///< samples per pixel; 0: the scene's sample_count
    std::uint32_t seed = 0; ///< RNG seed; the same seed gives the same image bit for bit
    /// Called after each pass of a few samples with (samples done, samples total), e.g. for a
    /// progress bar; the render waits for each pass when it is set.
    std::function<void(int, int)> progress;
};

struct RenderResult {
    int width = 0, height = 0, spp = 0;
    std::vector<float> rgb;       ///< linear RGB, row-major from the top-left pixel
    double seconds = 0.0;         ///< wall time of the render passes
    double kernel_seconds = 0.0;  ///< device time of the render passes (with stage timing on)
    std::uint64_t nan_guards = 0; ///< samples of this render dropped because they were not finite
};

/// render() in passes of a few samples (progress, and no driver watchdog on GPUs; every pixel
/// adds its samples in order whatever the split, so the image is the same), then the image on
/// the host. Blocks.
RenderResult render_image(const View& view, const Buffer<float>& params,
                          const RenderOptions& options);

} // namespace tandem
