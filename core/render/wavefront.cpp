// The wavefront renderer's scheduling: waves of one sample per pixel, stages per bounce.
#include "core/render/wavefront.h"

#include <algorithm>

#include "runtime/pocl_llvm.h"

namespace tandem {

namespace {

/// The state layout of kernels/wavefront.cl (WF_FLOAT_FIELDS, WF_UINT_FIELDS).
constexpr std::size_t k_float_fields = 55, k_uint_fields = 5;
/// Bounces run without asking whether any path is alive; after them, one blocking check per
/// k_check_every bounces (a few partial sums) ends the wave once every path has.
constexpr unsigned k_free_bounces = 8, k_check_every = 4;
/// Paths per work item of the liveness check.
constexpr unsigned k_alive_chunk = 4096;

/// Whether any path of the wave is alive: partial sums on the device, a few words read back.
bool any_alive(DeviceScene& scene, DeviceScene::Wavefront& w, unsigned n, const char* stage) {
    scene.kernel("wavefront.cl", "wf_any_alive")
        .launch(scene.context(), stage, w.alive.size(), w.flags, w.alive, k_alive_chunk, n);
    const std::vector<unsigned> any = w.alive.download();
    return std::any_of(any.begin(), any.end(), [](unsigned a) { return a != 0; });
}

/// The scene's wavefront scratch, sized for one path per pixel (allocated on the first pass).
DeviceScene::Wavefront& wave_state(DeviceScene& scene) {
    DeviceScene::Wavefront& w = scene.wavefront();
    const std::size_t n = scene.pixels(), chunks = (n + k_alive_chunk - 1) / k_alive_chunk;
    if (w.state.size() != k_float_fields * n) {
        w.state = Buffer<float>(scene.context(), "wavefront path state", k_float_fields * n);
        w.flags = Buffer<unsigned>(scene.context(), "wavefront path flags", k_uint_fields * n);
        w.alive = Buffer<unsigned>(scene.context(), "wavefront liveness", chunks);
    }
    return w;
}

/// The shading stages' modes (WF_MODE_* in kernels/path/wavefront.h), each its own kernel.
enum class ShadeMode : unsigned { primal = 0, two_state = 1, replay = 2 };

/// The bounces of a generated wave: intersect, shade, shadow until max_depth or no path is
/// alive. `shade(depth)` and `shadow()` launch the mode's shading and shadow stages. `stage`: the
/// pass's name in the stage timings.
template <class Shade, class Shadow>
void trace_wave(DeviceScene& scene, const gpu::RenderParams& rp, DeviceScene::Wavefront& w,
                unsigned n, ShadeMode mode, const char* stage, Shade&& shade, Shadow&& shadow) {
    Kernel& intersect = scene.kernel("wavefront.cl", "wf_intersect");
    bool& compiled = w.shade_compiled[static_cast<unsigned>(mode)];
    // render_pass's loop: a path has at most max_depth segments (0xFFFFFFFF: unbounded)
    for (unsigned depth = 0; depth < rp.max_depth; ++depth) {
        if (depth >= k_free_bounces && (depth - k_free_bounces) % k_check_every == 0 &&
            !any_alive(scene, w, n, stage))
            break;
        scene.launch(intersect, stage, n, rp, w.state, w.flags, n);
        if (compiled) {
            shade(depth);
        } else {
            // PoCL compiles a kernel at its first launch: this one with SLP off, so that it
            // runs SIMD across paths (runtime/pocl_llvm.h), alone in the scope (the finish
            // before: the kernels ahead of it keep SLP) and done before the scope ends
            scene.context().finish();
            const PoclSlpOff slp_off(scene.context().device());
            shade(depth);
            scene.context().finish();
            compiled = true;
        }
        shadow();
    }
}

/// trace_wave for the primal render (params_old null) or the two-state render.
void trace_render_wave(DeviceScene& scene, const Buffer<float>& params,
                       const Buffer<float>* params_old, const gpu::RenderParams& rp,
                       DeviceScene::Wavefront& w, unsigned n, const char* stage) {
    Kernel& shade = scene.kernel("wavefront.cl", params_old ? "wf_shade_two_state" : "wf_shade");
    Kernel& shadow = scene.kernel("wavefront.cl", "wf_shadow");
    const unsigned two_state = params_old ? 1 : 0;
    trace_wave(
        scene, rp, w, n, params_old ? ShadeMode::two_state : ShadeMode::primal, stage,
        [&](unsigned depth) {
            if (params_old)
                scene.launch(shade, stage, n, rp, params, *params_old, w.state, w.flags, n, depth);
            else
                scene.launch(shade, stage, n, rp, params, w.state, w.flags, n, depth);
        },
        [&] { scene.launch(shadow, stage, n, rp, w.state, w.flags, n, two_state); });
}

} // namespace

bool wavefront_supported(const BuildFlags& f) {
    return f.get("HAS_AREA_LIGHTS") == 1 && f.get("HAS_ENV_LIGHT") == 0 &&
           f.get("HAS_DELTA_LIGHTS") == 0 &&
           f.get("BSDF_CONDUCTOR") == 0 && f.get("BSDF_DIELECTRIC") == 0 &&
           f.get("BSDF_PLASTIC") == 0 && f.get("LIGHT_STRATEGY") == 0 && f.get("RESTIR") == 0;
}

void render_samples_wavefront(DeviceScene& scene, const Buffer<float>& params,
                              gpu::RenderParams rp, int begin, int count) {
    DeviceScene::Wavefront& w = wave_state(scene);
    const auto n = static_cast<unsigned>(scene.pixels());
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& accumulate = scene.kernel("wavefront.cl", "wf_accumulate");
    rp.sample_count = 1;
    for (int k = begin; k < begin + count; ++k) {
        rp.sample_begin = static_cast<unsigned>(k);
        scene.launch(generate, "render", n, rp, w.state, w.flags, n);
        trace_render_wave(scene, params, nullptr, rp, w, n, "render");
        accumulate.launch(scene.context(), "render", n, w.state, scene.accum(), scene.guards(),
                          n);
    }
}

void render_two_state_wavefront(DeviceScene& scene, const Buffer<float>& params,
                                const Buffer<float>& params_old, gpu::RenderParams rp) {
    DeviceScene::Wavefront& w = wave_state(scene);
    const auto n = static_cast<unsigned>(scene.pixels());
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& accumulate = scene.kernel("wavefront.cl", "wf_accumulate_two_state");
    const unsigned begin = rp.sample_begin, count = rp.sample_count;
    rp.sample_count = 1;
    for (unsigned k = begin; k < begin + count; ++k) {
        rp.sample_begin = k;
        scene.launch(generate, "render", n, rp, w.state, w.flags, n);
        trace_render_wave(scene, params, &params_old, rp, w, n, "render");
        accumulate.launch(scene.context(), "render", n, w.state, scene.accum(),
                          scene.accum_old(), scene.guards(), n);
    }
}

void adjoint_radiance_wavefront(DeviceScene& scene, const Buffer<float>& params,
                                gpu::RenderParams rp, const Buffer<float>& delta,
                                Buffer<gpu::float4>& radiance) {
    DeviceScene::Wavefront& w = wave_state(scene);
    const auto n = static_cast<unsigned>(scene.pixels());
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& skip = scene.kernel("wavefront.cl", "wf_skip_zero_delta");
    Kernel& store = scene.kernel("wavefront.cl", "wf_store_radiance");
    const unsigned begin = rp.sample_begin, count = rp.sample_count;
    rp.sample_count = 1;
    for (unsigned k = 0; k < count; ++k) {
        rp.sample_begin = begin + k;
        scene.launch(generate, "adjoint", n, rp, w.state, w.flags, n);
        skip.launch(scene.context(), "adjoint", n, delta, w.flags, n);
        trace_render_wave(scene, params, nullptr, rp, w, n, "adjoint");
        store.launch(scene.context(), "adjoint", n, w.state, delta, radiance, k, n);
    }
}

void adjoint_replay_wavefront(DeviceScene& scene, const Buffer<float>& params,
                              gpu::RenderParams rp, const Buffer<float>& delta, float inv_spp,
                              const Buffer<int>& exponent, const Buffer<gpu::float4>& radiance,
                              const Buffer<unsigned>& active, Buffer<unsigned>& grad) {
    DeviceScene::Wavefront& w = wave_state(scene);
    const auto n = static_cast<unsigned>(scene.pixels());
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& begin_replay = scene.kernel("wavefront.cl", "wf_replay_begin");
    Kernel& shade = scene.kernel("wavefront.cl", "wf_shade_replay");
    Kernel& shadow = scene.kernel("wavefront.cl", "wf_replay_shadow");
    const unsigned begin = rp.sample_begin, count = rp.sample_count;
    rp.sample_count = 1;
    for (unsigned k = 0; k < count; ++k) {
        rp.sample_begin = begin + k;
        scene.launch(generate, "adjoint", n, rp, w.state, w.flags, n);
        begin_replay.launch(scene.context(), "adjoint", n, delta, inv_spp, exponent, radiance, k,
                            w.state, w.flags, scene.guards(), n);
        trace_wave(
            scene, rp, w, n, ShadeMode::replay, "adjoint",
            [&](unsigned depth) {
                scene.launch(shade, "adjoint", n, rp, params, w.state, w.flags, n, depth);
            },
            [&] {
                scene.launch(shadow, "adjoint", n, rp, params, w.state, w.flags, n, active, grad,
                             scene.guards());
            });
    }
}

} // namespace tandem
