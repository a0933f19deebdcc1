// The wavefront renderer's scheduling: waves of one sample per pixel, stages per bounce.
#include "core/render/wavefront.h"

#include <algorithm>
#include <cstddef>
#include <string>

#include "runtime/pocl_llvm.h"
#include "shared/bvh_layout.h"
#include "shared/scene_layout.h"
#include "shared/wavefront_layout.h"

namespace tandem {

namespace {

// The wavefront's vectorised stages read these records as arrays of 32-bit words, by offset
// (kernels/path/wavefront_lookup.h, wavefront.h), where the vectoriser's gathers want a flat
// address: the offsets they use. The layout test (tests/kernels/test_layout.cpp) checks that the
// device compiler lays the structs out as the host does.
constexpr std::size_t word(std::size_t byte_offset) {
    return byte_offset / 4;
}
static_assert(word(offsetof(gpu::EmissiveTriangle, p0.w)) == 3 &&
                  word(offsetof(gpu::EmissiveTriangle, p1.w)) == 7 &&
                  word(offsetof(gpu::EmissiveTriangle, nx)) == 12,
              "nee_triangle_sample (kernels/path/nee.h) reads area, pmf and normal at 3, 7, 12");
static_assert(word(offsetof(gpu::ShadingPrimitive, v1)) == 4 &&
                  word(offsetof(gpu::ShadingPrimitive, v1.w)) == 7 &&
                  word(offsetof(gpu::ShadingPrimitive, v2)) == 8 &&
                  word(offsetof(gpu::ShadingPrimitive, v2.w)) == 11 &&
                  word(offsetof(gpu::ShadingPrimitive, n_front)) == 12,
              "wf_primitive_point (kernels/path/wavefront_lookup.h) reads the vertices, kind and normal there");
static_assert(word(offsetof(gpu::TextureInfo, color1)) == 4 &&
                  word(offsetof(gpu::TextureInfo, uv_row0)) == 8 &&
                  word(offsetof(gpu::TextureInfo, uv_row1)) == 12 &&
                  word(offsetof(gpu::TextureInfo, kind)) == 16 &&
                  word(offsetof(gpu::TextureInfo, offset)) == 17 &&
                  word(offsetof(gpu::TextureInfo, width)) == 18 &&
                  word(offsetof(gpu::TextureInfo, height)) == 19 &&
                  word(offsetof(gpu::TextureInfo, filter)) == 20 &&
                  word(offsetof(gpu::TextureInfo, param)) == 21,
              "wf_texture reads the texture record by these word offsets");
static_assert(offsetof(gpu::Material, reflectance) == 0,
              "the wavefront's shading reads a material's reflectance at word 0");

/// Paths per work item of the live list's prefix sums.
constexpr unsigned k_live_chunk = 256;
/// The adjoint records at most k_record_bytes of hits for its replay (20 bytes per path and
/// bounce), and at most Wavefront::record_bounces bounces; deeper ones are traced again.
constexpr std::size_t k_record_bytes = std::size_t(256) << 20;

/// The record's slot of bounce `depth` when the first `record_depth` bounces are recorded.
unsigned record_slot(unsigned depth, unsigned record_depth) {
    return depth < record_depth ? depth : WF_NO_RECORD;
}

/// The paths alive now into w.live, in increasing order (kernels/wavefront.cl: wf_live_counts,
/// wf_live_offsets, wf_live_list); returns how many, which the host waits for: it sizes the
/// bounce's launches, and 0 ends the wave.
unsigned live_list(DeviceScene& scene, DeviceScene::Wavefront& w, unsigned n, const char* stage) {
    // this view's chunks only: the scratch holds the largest film's, and the counts of chunks
    // past n would be a larger view's, left from its last wave
    const unsigned chunks = (n + k_live_chunk - 1) / k_live_chunk;
    scene.kernel("wavefront.cl", "wf_live_counts")
        .launch(scene.context(), stage, chunks, w.flags, w.live_counts, k_live_chunk, n);
    scene.kernel("wavefront.cl", "wf_live_offsets")
        .launch(scene.context(), stage, 1, w.live_counts, chunks, w.live_offsets, w.live_total);
    scene.kernel("wavefront.cl", "wf_live_list")
        .launch(scene.context(), stage, chunks, w.flags, w.live_offsets, w.live, k_live_chunk, n);
    return w.live_total.download()[0];
}

/// The scene's wavefront scratch, sized for one path per pixel (allocated on the first pass).
DeviceScene::Wavefront& wave_state(DeviceScene& scene) {
    DeviceScene::Wavefront& w = scene.wavefront();
    const std::size_t n = scene.max_pixels(), chunks = (n + k_live_chunk - 1) / k_live_chunk;
    // The stages index a field of a path as field * n + path in 32 bits (kernels/path/wavefront.h)
    if (std::size_t(WF_FLOAT_FIELDS) * n > 0xffffffffu)
        throw Error("the wavefront renderer indexes its path state in 32 bits: at most " +
                    std::to_string(0xffffffffu / WF_FLOAT_FIELDS) + " pixels, not " +
                    std::to_string(n) + " (render with TANDEM_WAVEFRONT=0)");
    if (w.state.size() != std::size_t(WF_FLOAT_FIELDS) * n) {
        Context& ctx = scene.context();
        w.state = Buffer<float>(ctx, "wavefront path state", std::size_t(WF_FLOAT_FIELDS) * n);
        w.flags = Buffer<unsigned>(ctx, "wavefront path flags", std::size_t(WF_UINT_FIELDS) * n);
        w.live = Buffer<unsigned>(ctx, "wavefront live paths", n);
        w.live_counts = Buffer<unsigned>(ctx, "wavefront live counts", chunks);
        w.live_offsets = Buffer<unsigned>(ctx, "wavefront live offsets", chunks);
        w.live_total = Buffer<unsigned>(ctx, "wavefront live total", 1);
        w.hits = Buffer<unsigned>(ctx, "wavefront recorded hits", 1); // sized by the adjoint
        w.seen = Buffer<unsigned>(ctx, "wavefront recorded shadow rays", 1);
    }
    return w;
}

/// Runs launch(), which launches `kernel`, a stage written for PoCL's loop vectoriser (the
/// shading stages). PoCL compiles a kernel at its first launch: that one runs with
/// SLP off, so that the stage runs SIMD across paths (runtime/pocl_llvm.h), alone in the scope (the
/// finish before: the kernels ahead of it keep SLP) and done before the scope ends.
template <class Launch>
void launch_vectorised(DeviceScene& scene, const Kernel& kernel, Launch&& launch) {
    std::vector<const Kernel*>& compiled = scene.wavefront().vectorised;
    if (std::find(compiled.begin(), compiled.end(), &kernel) != compiled.end())
        return launch();
    scene.context().finish();
    const PoclSlpOff slp_off(scene.context().device(), scene.context().tuning());
    launch();
    scene.context().finish();
    compiled.push_back(&kernel);
}

/// Launches wf_generate for sample rp.sample_begin.
void generate_wave(const View& view, const gpu::RenderParams& rp, DeviceScene::Wavefront& w,
                   unsigned n, const char* stage) {
    DeviceScene& scene = *view.scene;
    scene.launch(view.sensor, scene.kernel("wavefront.cl", "wf_generate"), stage, n, rp, w.state, w.flags, n);
}

/// Whether wf_shade_general has paths to shade at bounce `depth`: the scene has materials other
/// than diffuse or surfaces shaded with vertex normals, or it is built with RESTIR and the bounce is the first, whose vertices with a
/// reservoir it shades (kernels/path/wavefront.h: WF_GENERAL, wf_general_hit).
bool general_paths(const DeviceScene& scene, unsigned depth) {
    const BuildFlags& f = scene.features();
    return f.get("BSDF_CONDUCTOR") || f.get("BSDF_DIELECTRIC") || f.get("BSDF_PLASTIC") ||
           f.get("HAS_SHADING_NORMALS") || (f.get("RESTIR") && depth == 0);
}

/// The bounces of a generated wave: intersect, shade, shadow until max_depth or no path is
/// alive, each over the paths alive at the bounce's start (live_list): `intersect`, `shade` (of
/// shade_kernel), `general` (where it may have paths: general_paths)
/// and `shadow`, called as f(depth, count), launch the stages over w.live[0, count). `stage`: the
/// pass's name in the stage timings.
template <class Intersect, class Shade, class General, class Shadow>
void trace_wave(const View& view, const gpu::RenderParams& rp, DeviceScene::Wavefront& w,
                unsigned n, const Kernel& shade_kernel, const char* stage, Intersect&& intersect,
                Shade&& shade, General&& general, Shadow&& shadow) {
    DeviceScene& scene = *view.scene;
    // render_pass's loop: a path has at most max_depth segments (0xFFFFFFFF: unbounded)
    for (unsigned depth = 0; depth < rp.max_depth; ++depth) {
        const unsigned count = live_list(scene, w, n, stage);
        if (count == 0) break;
        intersect(depth, count);
        launch_vectorised(scene, shade_kernel, [&] { shade(depth, count); });
        if (general_paths(scene, depth)) general(depth, count);
        shadow(depth, count);
    }
}

/// trace_wave for the primal render (params_old null) or the two-state render. With `record`,
/// the first `record_depth` bounces leave their hits and shadow-ray results in w.hits and w.seen
/// for a replay (shared/wavefront_layout.h: WF_NO_RECORD). The primal render's primary vertices
/// take their light samples from `reservoirs` where it has a buffer.
void trace_render_wave(const View& view, const Buffer<float>& params,
                       const Buffer<float>* params_old, const gpu::RenderParams& rp,
                       DeviceScene::Wavefront& w, unsigned n, const char* stage,
                       unsigned record_depth = 0, const WaveReservoirs& reservoirs = {}) {
    DeviceScene& scene = *view.scene;
    const Buffer<gpu::Reservoir>& slots =
        reservoirs.buffer ? *reservoirs.buffer : scene.no_reservoirs();
    Kernel& intersect = scene.kernel("wavefront.cl", "wf_intersect");
    Kernel& shade = scene.kernel("wavefront.cl", params_old ? "wf_shade_two_state" : "wf_shade");
    Kernel& shadow = scene.kernel("wavefront.cl", "wf_shadow");
    const unsigned two_state = params_old ? 1 : 0;
    trace_wave(
        scene, rp, w, n, shade, stage,
        [&](unsigned depth, unsigned count) {
            scene.launch(view.sensor, intersect, stage, count, rp, w.state, w.flags, n, w.live, count, w.hits,
                         record_slot(depth, record_depth));
        },
        [&](unsigned depth, unsigned count) {
            if (params_old)
                scene.launch(view.sensor, shade, stage, count, rp, params, *params_old, w.state, w.flags, n,
                             depth, w.live, count);
            else
                scene.launch(view.sensor, shade, stage, count, rp, params, w.state, w.flags, n, depth, w.live,
                             count, slots, reservoirs.mode, reservoirs.spp);
        },
        [&](unsigned depth, unsigned count) {
            if (params_old)
                scene.launch(view.sensor, scene.kernel("wavefront.cl", "wf_shade_general_two_state"), stage,
                             count, rp, params, *params_old, w.state, w.flags, n, depth, w.live,
                             count);
            else
                scene.launch(view.sensor, scene.kernel("wavefront.cl", "wf_shade_general"), stage, count, rp,
                             params, w.state, w.flags, n, depth, w.live, count, slots,
                             reservoirs.mode, reservoirs.spp);
        },
        [&](unsigned depth, unsigned count) {
            scene.launch(view.sensor, shadow, stage, count, rp, w.state, w.flags, n, w.live, count, two_state,
                         w.seen, record_slot(depth, record_depth));
        });
}

} // namespace

bool wavefront_supported(const BuildFlags& f) {
    return (f.get("HAS_AREA_LIGHTS") == 1 || f.get("HAS_ENV_LIGHT") == 1) &&
           f.get("HAS_DELTA_LIGHTS") == 0 && f.get("LIGHT_STRATEGY") == 0 &&
           f.get("HAS_MEDIA") == 0;
}

void render_samples_wavefront(const View& view, const Buffer<float>& params,
                              gpu::RenderParams rp, int begin, int count) {
    DeviceScene& scene = *view.scene;
    DeviceScene::Wavefront& w = wave_state(scene);
    const auto n = static_cast<unsigned>(view.pixels());
    Kernel& accumulate = scene.kernel("wavefront.cl", "wf_accumulate");
    rp.sample_count = 1;
    for (int k = begin; k < begin + count; ++k) {
        rp.sample_begin = static_cast<unsigned>(k);
        generate_wave(view, rp, w, n, "render");
        trace_render_wave(view, params, nullptr, rp, w, n, "render");
        accumulate.launch(scene.context(), "render", n, w.state, scene.accum(), scene.guards(),
                          n);
    }
}

void render_two_state_wavefront(const View& view, const Buffer<float>& params,
                                const Buffer<float>& params_old, gpu::RenderParams rp) {
    DeviceScene& scene = *view.scene;
    DeviceScene::Wavefront& w = wave_state(scene);
    const auto n = static_cast<unsigned>(view.pixels());
    Kernel& accumulate = scene.kernel("wavefront.cl", "wf_accumulate_two_state");
    const unsigned begin = rp.sample_begin, count = rp.sample_count;
    rp.sample_count = 1;
    for (unsigned k = begin; k < begin + count; ++k) {
        rp.sample_begin = k;
        generate_wave(view, rp, w, n, "render");
        trace_render_wave(view, params, &params_old, rp, w, n, "render");
        accumulate.launch(scene.context(), "render", n, w.state, scene.accum(),
                          scene.accum_old(), scene.guards(), n);
    }
}

void adjoint_wavefront(const View& view, const Buffer<float>& params, gpu::RenderParams rp,
                       const Buffer<float>& delta, float inv_spp, const Buffer<int>& exponent,
                       Buffer<gpu::float4>& radiance, const Buffer<unsigned>& active,
                       Buffer<unsigned>& grad, const WaveReservoirs& reservoirs) {
    DeviceScene& scene = *view.scene;
    DeviceScene::Wavefront& w = wave_state(scene);
    const Buffer<gpu::Reservoir>& slots =
        reservoirs.buffer ? *reservoirs.buffer : scene.no_reservoirs();
    const auto n = static_cast<unsigned>(view.pixels());
    // the bounces recorded for the replay, and their buffers (kept between calls)
    const auto record_depth = static_cast<unsigned>(std::min<std::size_t>(
        {rp.max_depth, w.record_bounces, k_record_bytes / (20 * std::size_t(n))}));
    if (w.seen.size() < std::size_t(record_depth) * n ||
        w.hits.size() < 4 * std::size_t(record_depth) * n) {
        w.hits = Buffer<unsigned>(scene.context(), "wavefront recorded hits",
                                  4 * std::size_t(record_depth) * n);
        w.seen = Buffer<unsigned>(scene.context(), "wavefront recorded shadow rays",
                                  std::size_t(record_depth) * n);
    }
    Kernel& skip = scene.kernel("wavefront.cl", "wf_skip_zero_delta");
    Kernel& store = scene.kernel("wavefront.cl", "wf_store_radiance");
    Kernel& begin_replay = scene.kernel("wavefront.cl", "wf_replay_begin");
    Kernel& intersect = scene.kernel("wavefront.cl", "wf_intersect");
    Kernel& recall = scene.kernel("wavefront.cl", "wf_recall");
    Kernel& shade = scene.kernel("wavefront.cl", "wf_shade_replay");
    Kernel& shadow = scene.kernel("wavefront.cl", "wf_replay_shadow");
    const unsigned begin = rp.sample_begin, count = rp.sample_count;
    rp.sample_count = 1;
    for (unsigned k = 0; k < count; ++k) {
        rp.sample_begin = begin + k;
        // the primal radiance L of the sample (adjoint_primal), recording the path
        generate_wave(view, rp, w, n, "adjoint");
        skip.launch(scene.context(), "adjoint", n, delta, w.flags, n);
        trace_render_wave(view, params, nullptr, rp, w, n, "adjoint", record_depth, reservoirs);
        store.launch(scene.context(), "adjoint", n, w.state, delta, radiance, k, n);
        // its replay from L (adjoint_pass), on the recorded hits
        generate_wave(view, rp, w, n, "adjoint");
        begin_replay.launch(scene.context(), "adjoint", n, delta, inv_spp, exponent, radiance, k,
                            w.state, w.flags, scene.guards(), n);
        trace_wave(
            scene, rp, w, n, shade, "adjoint",
            [&](unsigned depth, unsigned live) {
                if (depth < record_depth)
                    recall.launch(scene.context(), "adjoint", live, w.state, w.flags, n, w.live,
                                  live, w.hits, depth);
                else
                    scene.launch(view.sensor, intersect, "adjoint", live, rp, w.state, w.flags, n, w.live,
                                 live, w.hits, WF_NO_RECORD);
            },
            [&](unsigned depth, unsigned live) {
                scene.launch(view.sensor, shade, "adjoint", live, rp, params, w.state, w.flags, n, depth,
                             w.live, live, slots, reservoirs.mode, reservoirs.spp);
            },
            [&](unsigned depth, unsigned live) {
                scene.launch(view.sensor, scene.kernel("wavefront.cl", "wf_shade_general_replay"), "adjoint",
                             live, rp, params, w.state, w.flags, n, depth, w.live, live, slots,
                             reservoirs.mode, reservoirs.spp, active, grad, scene.guards());
            },
            [&](unsigned depth, unsigned live) {
                scene.launch(view.sensor, shadow, "adjoint", live, rp, params, w.state, w.flags, n, w.live,
                             live, w.seen, record_slot(depth, record_depth), active, grad, scene.guards());
            });
    }
}

} // namespace tandem
