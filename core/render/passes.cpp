// The render passes.
#include "core/render/passes.h"

#include "core/render/boundary.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <string>

#include "core/render/features.h"
#include "core/render/wavefront.h"
#include "runtime/error.h"

namespace tandem {

namespace {

/// Samples per launch of the progressive passes: short launches, the same sums (see render_image).
constexpr int k_samples_per_launch = 4;
/// render_image's launches where the render pass traces its camera rays in packets of eight
/// (CAMERA_PACKETS): a whole packet per pixel and launch.
constexpr int k_packet_samples_per_launch = 8;
/// The bytes the adjoint keeps between its two kernels: per sample of a launch, 16 for its primal
/// radiance and shadow bits, and 16 per recorded bounce (kernels/adjoint.cl).
constexpr std::size_t k_adjoint_scratch = std::size_t(512) << 20;

void check_params(const DeviceScene& scene, const Buffer<float>& params, const char* pass) {
    if (params.size() != std::max<std::size_t>(1, scene.param_count()))
        throw Error(std::string(pass) + ": the parameter buffer does not match the scene's layout");
}

void check_image(const View& view, const Buffer<float>& rgb, const char* pass) {
    if (rgb.size() != 3 * view.pixels())
        throw Error(std::string(pass) + ": '" + rgb.name() + "' is not 3 floats per pixel");
}

/// Throws Error naming `pass` unless `reservoirs` fit a pass of `spp` samples per pixel of
/// `scene`, which must be built with RESTIR=1.
void check_reservoirs(const View& view, const PathReservoirs& reservoirs, int spp,
                      const char* pass) {
    const DeviceScene& scene = *view.scene;
    const std::string where(pass);
    if (scene.features().get("RESTIR") != 1)
        throw Error(where + ": reservoirs need a scene built with RESTIR=1");
    if (reservoirs.spp != static_cast<unsigned>(spp) ||
        reservoirs.buffer->size() != view.pixels() * reservoirs.spp)
        throw Error(where + ": the reservoirs are not one per sample of every pixel");
    if (reservoirs.direct > RESTIR_DIRECT_AUTO)
        throw Error(where + ": unknown share of direct light " + std::to_string(reservoirs.direct));
    if (const auto& r = reservoirs.resample) {
        if (!r->params_old || !r->prev || !r->active)
            throw Error(where + ": the resampling pass lacks a buffer");
        if (r->params.spp != reservoirs.spp || r->prev->size() != reservoirs.buffer->size())
            throw Error(where + ": the previous reservoirs are not one per sample of every pixel");
    }
}

/// Launches render_pass for samples [begin, begin + count) into scene.accum().
void render_samples(const View& view, const Buffer<float>& params, gpu::RenderParams rp,
                    int begin, int count) {
    DeviceScene& scene = *view.scene;
    if (scene.policy().wavefront)
        return render_samples_wavefront(view, params, rp, begin, count);
    scene.sync_geometry(params);
    scene.refresh_majorants(params);
    rp.sample_begin = static_cast<unsigned>(begin);
    rp.sample_count = static_cast<unsigned>(count);
    scene.launch(view.sensor, scene.kernel("render.cl", "render_pass"), "render", view.pixels(), rp, params,
                 scene.accum(), scene.guards());
}

/// rgb = accum.rgb / accum.w per pixel (kernels/render.cl: resolve_image).
void resolve(const View& view, const Buffer<gpu::float4>& accum, Buffer<float>& rgb) {
    DeviceScene& scene = *view.scene;
    const auto pixels = static_cast<unsigned>(view.pixels());
    scene.kernel("render.cl", "resolve_image")
        .launch(scene.context(), "resolve", pixels, accum, rgb, pixels);
}

/// Elements of delta summed per work item when choosing the gradient scale.
constexpr unsigned k_delta_chunk = 4096;

} // namespace

// (passes.h says what it chooses)
AdjointLaunches adjoint_launches(std::size_t pixels, unsigned max_depth, bool wavefront,
                                 unsigned hit_record_bounces) {
    const unsigned requested = std::min(hit_record_bounces, k_max_hit_record_bounces);
    const std::size_t sample = 16; // bytes of a sample's radiance, and of one recorded hit
    pixels = std::max<std::size_t>(pixels, 1);
    std::size_t bounces = wavefront ? 0 : std::min(requested, max_depth);
    const std::size_t samples = k_adjoint_scratch / (pixels * sample * (1 + bounces));
    AdjointLaunches l;
    l.samples = static_cast<int>(std::clamp<std::size_t>(samples, 1, k_samples_per_launch));
    if (samples == 0) {
        // one sample per launch: its radiance, and the hits of as many bounces as the rest holds
        const std::size_t words = k_adjoint_scratch / (pixels * sample); // 16-byte words per pixel
        bounces = std::min<std::size_t>(bounces, words > 0 ? words - 1 : 0);
    }
    l.hit_bounces = static_cast<unsigned>(bounces);
    return l;
}

void require_surfaces(const DeviceScene& scene, const char* what) {
    if (scene.features().get("HAS_MEDIA") == 1)
        throw Error(std::string(what) +
                    " does not cover participating media or null bsdfs yet: such scenes are "
                    "rendered and differentiated without it");
}

Buffer<float> parameter_buffer(Context& ctx, const ParamRegistry& params) {
    return Buffer<float>(ctx, "parameters", at_least_one(params.values()));
}

std::string shape_gradient_gaps(const RenderScene& scene,
                                const std::vector<const Parameter*>& params) {
    if (std::none_of(params.begin(), params.end(),
                     [](const Parameter* p) { return p->moves_geometry(); }))
        return "";
    auto delta = [&](const gpu::TriangleInfo& info) {
        const std::uint32_t type = scene.materials.at(info.material).type;
        return type == MATERIAL_CONDUCTOR || type == MATERIAL_DIELECTRIC;
    };
    if (std::none_of(scene.infos.begin(), scene.infos.end(), delta)) return "";
    std::string names; // the mesh shapes among them
    for (const MeshShape& s : scene.mesh_shapes)
        if (s.triangle_count && delta(scene.infos[s.first_triangle]))
            names += (names.empty() ? " (" : ", ") + s.name;
    return "warning: shape gradients leave out silhouettes and shadows seen in a mirror or "
           "through glass, and how a moving vertex turns the path after one" +
           (names.empty() ? "" : names + ")") + " (docs/method.md, \"Shape gradients\")\n";
}

bool prepare_shape_passes(DeviceScene& scene, const GradientBuffers& grad,
                          const PathReservoirs& reservoirs) {
    // shapes that the gradient follows move from now on: every pass traces their new positions,
    // and the replay carries the interior term (the megakernels': the wavefront has none)
    if (!differentiates_geometry(scene.scene(), grad)) return false;
    check_shape_gradients(scene.scene(), grad, reservoirs.buffer != nullptr);
    scene.track_geometry();
    scene.enable_shape_gradients();
    return true;
}

void resample_reservoirs(const View& view, const Buffer<float>& params, std::uint32_t seed,
                         const PathReservoirs& reservoirs) {
    require_surfaces(*view.scene, "light-sample reuse (ReSTIR)");
    DeviceScene& scene = *view.scene;
    check_params(scene, params, "resample");
    if (!reservoirs.buffer || !reservoirs.resample)
        throw Error("resample: no reservoirs to resample");
    check_reservoirs(view, reservoirs, static_cast<int>(reservoirs.spp), "resample");
    const PathResample& r = *reservoirs.resample;
    // as the adjoint: the shapes it follows where they are, slots on moving meshes served
    if (r.grad) prepare_shape_passes(scene, *r.grad, reservoirs);
    scene.sync_geometry(params);
    const DeviceScene::GeometryAt old = scene.geometry_at(*r.params_old);
    scene.launch(view.sensor, scene.kernel("restir.cl", "restir_resample"), "restir", view.pixels(),
                 scene.launch_params(seed), params, *r.params_old, *old.nodes, *old.tris,
                 *old.normals, r.params, *r.prev,
                 *reservoirs.buffer, *r.active, r.serve_all ? 1u : 0u, scene.guards());
}

void render(const View& view, const Buffer<float>& params, std::uint32_t seed, int spp,
            Buffer<float>& rgb, const PathReservoirs& reservoirs) {
    DeviceScene& scene = *view.scene;
    check_params(scene, params, "render");
    check_image(view, rgb, "render");
    const int total = std::max(1, spp);
    scene.accum().fill(gpu::float4{});
    if (reservoirs.buffer) {
        check_reservoirs(view, reservoirs, total, "render");
        gpu::RenderParams rp = scene.launch_params(seed);
        rp.sample_begin = 0;
        rp.sample_count = static_cast<unsigned>(total);
        const auto& r = reservoirs.resample;
        if (!r)
            throw Error("render: the primal's reservoirs are resampled by the render itself "
                        "(Restir::resampled_by_paths)");
        // as resample_reservoirs: the shapes followed, and what reuse cannot follow refused,
        // from the first render on (a chain of the primal alone, or resumed, has no adjoint yet)
        if (r->grad) prepare_shape_passes(scene, *r->grad, reservoirs);
        scene.sync_geometry(params);
        const DeviceScene::GeometryAt old = scene.geometry_at(*r->params_old);
        scene.launch(view.sensor, scene.kernel("render.cl", "render_pass_resample"), "render", view.pixels(),
                     rp, params, *reservoirs.buffer, reservoirs.mode(), reservoirs.spp,
                     *r->params_old, *old.nodes, *old.tris, *old.normals, r->params, *r->prev, *r->active, r->serve_all ? 1u : 0u,
                     scene.accum(), scene.guards());
    } else {
        render_samples(view, params, scene.launch_params(seed), 0, total);
    }
    resolve(view, scene.accum(), rgb);
}

void render_two_state(const View& view, const Buffer<float>& params,
                      const Buffer<float>& params_old, std::uint32_t seed, int spp,
                      Buffer<float>& rgb, Buffer<float>& rgb_old) {
    DeviceScene& scene = *view.scene;
    check_params(scene, params, "render_two_state");
    check_params(scene, params_old, "render_two_state");
    check_image(view, rgb, "render_two_state");
    check_image(view, rgb_old, "render_two_state");
    gpu::RenderParams rp = scene.launch_params(seed);
    rp.sample_begin = 0;
    rp.sample_count = static_cast<unsigned>(std::max(1, spp));
    scene.accum().fill(gpu::float4{});
    scene.accum_old().fill(gpu::float4{});
    if (scene.policy().wavefront) {
        render_two_state_wavefront(view, params, params_old, rp);
    } else {
        scene.sync_geometry(params);
        scene.refresh_majorants(params, &params_old);
        scene.launch(view.sensor, scene.kernel("render.cl", "render_two_state"), "render", view.pixels(), rp,
                     params, params_old, scene.accum(), scene.accum_old(), scene.guards());
    }
    resolve(view, scene.accum(), rgb);
    resolve(view, scene.accum_old(), rgb_old);
}

void choose_gradient_scale(DeviceScene& scene, const std::vector<const Buffer<float>*>& deltas,
                           GradientBuffers& grad, const std::vector<std::size_t>& sizes,
                           const std::function<void(std::vector<float>&)>& exchange) {
    if (grad.forced_exponent) {
        if (std::abs(*grad.forced_exponent) > GRAD_MAX_EXPONENT)
            throw Error("backward: the forced gradient scale exponent is out of range");
        grad.exponent.fill(*grad.forced_exponent);
        return;
    }
    if (deltas.empty()) throw Error("backward: no delta to scale the gradients by");
    // every delta's chunk sums in one buffer, in order: one delta gives the sums it always gave
    std::vector<unsigned> firsts, counts;
    unsigned chunks = 0;
    for (std::size_t i = 0; i < deltas.size(); ++i) {
        if (!deltas[i] && (!exchange || i >= sizes.size()))
            throw Error("backward: a view of the batch without its delta or its size");
        const std::size_t n = deltas[i] ? deltas[i]->size() : sizes[i];
        firsts.push_back(chunks);
        counts.push_back((static_cast<unsigned>(n) + k_delta_chunk - 1) / k_delta_chunk);
        chunks += counts.back();
    }
    if (grad.delta_sums.size() != chunks)
        grad.delta_sums = Buffer<float>(scene.context(), "delta chunk sums", chunks);
    Kernel& sums = scene.kernel("adjoint.cl", "grad_delta_sums");
    for (std::size_t i = 0; i < deltas.size(); ++i) {
        if (!deltas[i]) continue;
        const auto n = static_cast<unsigned>(deltas[i]->size());
        sums.launch(scene.context(), "adjoint", counts[i], *deltas[i], grad.delta_sums, firsts[i],
                    k_delta_chunk, n);
    }
    if (exchange) {
        std::vector<float> host = grad.delta_sums.download();
        for (std::size_t i = 0; i < deltas.size(); ++i)
            if (!deltas[i]) std::fill_n(host.begin() + firsts[i], counts[i], 0.0f);
        exchange(host);
        grad.delta_sums.upload(host);
    }
    scene.kernel("adjoint.cl", "grad_exponent")
        .launch(scene.context(), "adjoint", 1, grad.delta_sums, chunks, grad.exponent);
}

void decode_gradients(DeviceScene& scene, GradientBuffers& grad, Buffer<unsigned>* wraps) {
    const auto count = static_cast<unsigned>(grad.value.size());
    scene.kernel("adjoint.cl", "decode_gradients")
        .launch(scene.context(), "decode gradients", count, grad.fixed, grad.exponent, grad.value,
                count, wraps ? *wraps : scene.guards());
}

void backward(const View& view, const Buffer<float>& params, std::uint32_t seed, int spp,
              const Buffer<float>& delta, GradientBuffers& grad, const PathReservoirs& reservoirs) {
    check_image(view, delta, "backward");
    choose_gradient_scale(*view.scene, {&delta}, grad);
    accumulate_gradients(view, params, seed, spp, delta, grad, reservoirs);
    decode_gradients(*view.scene, grad);
}

void accumulate_gradients(const View& view, const Buffer<float>& params, std::uint32_t seed,
                          int spp, const Buffer<float>& delta, GradientBuffers& grad,
                          const PathReservoirs& reservoirs, BoundarySamples boundary) {
    DeviceScene& scene = *view.scene;
    check_params(scene, params, "backward");
    check_image(view, delta, "backward");
    if (grad.value.size() != params.size() || grad.fixed.size() != GRAD_WORDS * params.size())
        throw Error("backward: the gradient buffers do not match the scene's layout");
    const int total = std::max(1, spp);
    if (reservoirs.buffer) check_reservoirs(view, reservoirs, total, "backward");
    const bool shapes = prepare_shape_passes(scene, grad, reservoirs);
    const unsigned reservoir_mode = reservoirs.mode();
    const Buffer<gpu::Reservoir>& slots =
        reservoirs.buffer ? *reservoirs.buffer : scene.no_reservoirs();
    scene.sync_geometry(params);
    scene.refresh_majorants(params);
    gpu::RenderParams rp = scene.launch_params(seed);
    const bool wavefront = scene.policy().wavefront && !shapes;
    const AdjointLaunches launches = adjoint_launches(view.pixels(), rp.max_depth, wavefront,
                                                      scene.policy().hit_record_bounces);
    // the resampling pass, fused into the first kernel where it can be (not the wavefront's)
    const PathResample* fused = nullptr;
    if (reservoirs.resample) {
        if (wavefront)
            resample_reservoirs(view, params, seed, reservoirs);
        else
            fused = &*reservoirs.resample;
    }
    // the geometry where the previous reservoirs' points were (path/resample.h)
    const DeviceScene::GeometryAt old =
        fused ? scene.geometry_at(*fused->params_old) : DeviceScene::GeometryAt{};
    Kernel& primal =
        scene.kernel("adjoint.cl", fused ? "adjoint_primal_resample" : "adjoint_primal");
    Kernel& adjoint = scene.kernel("adjoint.cl", "adjoint_pass");
    const float inv_spp = 1.0f / static_cast<float>(total);
    // Launches of a few samples, as render_image(): the fixed-point sums do not depend on the
    // split. Each launch first stores the samples' primal radiance and records, then replays
    // them (two kernels: on a GPU each is smaller, with fewer registers, than one fused kernel;
    // the replay traces no ray the record holds); on large images fewer samples per launch, or fewer recorded
    // bounces, keep the scratch within k_adjoint_scratch.
    const int per_launch = launches.samples;
    Buffer<gpu::float4>& radiance =
        scene.sample_radiance(static_cast<std::size_t>(per_launch) * view.pixels());
    const unsigned hit_bounces = launches.hit_bounces;
    Buffer<gpu::Hit>& hits =
        scene.sample_hits(std::size_t(hit_bounces) * std::size_t(per_launch) * view.pixels());
    for (int begin = 0; begin < total; begin += per_launch) {
        rp.sample_begin = static_cast<unsigned>(begin);
        rp.sample_count = static_cast<unsigned>(std::min(per_launch, total - begin));
        if (wavefront) {
            adjoint_wavefront(view, params, rp, delta, inv_spp, grad.exponent, radiance,
                              grad.active, grad.fixed,
                              {reservoirs.buffer, reservoir_mode, reservoirs.spp});
            continue;
        }
        if (fused)
            scene.launch(view.sensor, primal, "adjoint", view.pixels(), rp, params, delta, slots,
                         reservoir_mode, reservoirs.spp, radiance, hits, hit_bounces,
                         *fused->params_old, *old.nodes, *old.tris, *old.normals, fused->params, *fused->prev, *fused->active,
                         fused->serve_all ? 1u : 0u, scene.guards());
        else
            scene.launch(view.sensor, primal, "adjoint", view.pixels(), rp, params, delta, slots,
                         reservoir_mode, reservoirs.spp, radiance, hits, hit_bounces);
        scene.launch(view.sensor, adjoint, "adjoint", view.pixels(), rp, params, delta, slots,
                     reservoir_mode, reservoirs.spp, inv_spp, grad.exponent, radiance, hits, hit_bounces,
                     grad.active, grad.fixed, scene.guards());
    }
    if (shapes) accumulate_boundary(view, params, seed, total, delta, grad, boundary);
}

void accumulate_boundary(const View& view, const Buffer<float>& params, std::uint32_t seed,
                         int spp, const Buffer<float>& delta, GradientBuffers& grad,
                         BoundarySamples boundary) {
    const int total = std::max(1, spp);
    accumulate_primary_boundary(view, params, seed,
                                boundary.primary < 0 ? total : boundary.primary, delta, grad);
    accumulate_secondary_boundary(view, params, seed,
                                  boundary.secondary < 0 ? total : boundary.secondary,
                                  boundary.guide, boundary.light_pairs, delta, grad,
                                  boundary.reuse);
}

void prepare_passes(DeviceScene& scene, bool two_state, bool adjoint) {
    scene.kernel("render.cl", "render_pass");
    scene.kernel("render.cl", "resolve_image");
    if (two_state) scene.kernel("render.cl", "render_two_state");
    if (adjoint) {
        scene.kernel("adjoint.cl", "adjoint_primal");
        scene.kernel("adjoint.cl", "adjoint_pass");
        scene.kernel("adjoint.cl", "grad_delta_sums");
        scene.kernel("adjoint.cl", "grad_exponent");
        scene.kernel("adjoint.cl", "decode_gradients");
    }
    if (scene.policy().wavefront) // one program; PoCL compiles each kernel at its first launch
        scene.kernel("wavefront.cl", "wf_shade");
}

RenderResult render_image(const View& view, const Buffer<float>& params,
                          const RenderOptions& opt) {
    DeviceScene& scene = *view.scene;
    check_params(scene, params, "render");
    const int spp = opt.spp > 0 ? opt.spp : scene.scene().sensors.at(view.sensor).spp;
    RenderResult out;
    out.width = static_cast<int>(view.width());
    out.height = static_cast<int>(view.height());
    out.spp = spp;
    Context& ctx = scene.context();
    Buffer<float> rgb(ctx, "image", 3 * view.pixels());
    const std::size_t mark = ctx.stage_mark();
    const std::uint64_t guards_before = scene.read_guards();
    scene.accum().fill(gpu::float4{});
    const gpu::RenderParams rp = scene.launch_params(opt.seed);
    const auto t0 = std::chrono::steady_clock::now();
    const int per_launch =
        scene.policy().camera_packets ? k_packet_samples_per_launch : k_samples_per_launch;
    for (int begin = 0; begin < spp; begin += per_launch) {
        const int count = std::min(per_launch, spp - begin);
        render_samples(view, params, rp, begin, count);
        if (opt.progress) {
            ctx.finish();
            opt.progress(begin + count, spp);
        }
    }
    resolve(view, scene.accum(), rgb);
    out.rgb = rgb.download();
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    out.nan_guards = scene.read_guards() - guards_before;
    if (ctx.stage_timing())
        out.kernel_seconds = stage_seconds(ctx.stage_times_since(mark), "render");
    return out;
}

} // namespace tandem
