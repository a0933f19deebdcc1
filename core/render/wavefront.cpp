// The wavefront renderer's scheduling: waves of one sample per pixel, stages per bounce.
#include "core/render/wavefront.h"

#include <algorithm>

#include "runtime/pocl_llvm.h"

namespace tandem {

namespace {

/// The state layout of kernels/wavefront.cl (WF_FLOAT_FIELDS, WF_UINT_FIELDS).
constexpr std::size_t k_float_fields = 37, k_uint_fields = 2;
/// Bounces run without asking whether any path is alive; after them, one blocking check per
/// k_check_every bounces (a few partial sums) ends the wave once every path has.
constexpr unsigned k_free_bounces = 8, k_check_every = 4;
/// Paths per work item of the liveness check.
constexpr unsigned k_alive_chunk = 4096;

bool any_alive(DeviceScene& scene, Buffer<unsigned>& flags, unsigned n, const char* stage) {
    const unsigned chunks = (n + k_alive_chunk - 1) / k_alive_chunk;
    Buffer<unsigned> partial(scene.context(), "wavefront alive", chunks);
    scene.kernel("wavefront.cl", "wf_any_alive")
        .launch(scene.context(), stage, chunks, flags, partial, k_alive_chunk, n);
    const std::vector<unsigned> any = partial.download();
    return std::any_of(any.begin(), any.end(), [](unsigned a) { return a != 0; });
}

} // namespace

bool wavefront_supported(const BuildFlags& f) {
    return f.get("HAS_AREA_LIGHTS") == 1 && f.get("HAS_ENV_LIGHT") == 0 &&
           f.get("HAS_DELTA_LIGHTS") == 0 &&
           f.get("BSDF_CONDUCTOR") == 0 && f.get("BSDF_DIELECTRIC") == 0 &&
           f.get("BSDF_PLASTIC") == 0 && f.get("LIGHT_STRATEGY") == 0 && f.get("RESTIR") == 0;
}

namespace {

/// The path state of a wave, and its kernels.
struct Wave {
    unsigned n;
    Buffer<float>& state;
    Buffer<unsigned>& flags;
};

Wave wave_state(DeviceScene& scene) {
    const auto n = static_cast<unsigned>(scene.pixels());
    return {n, scene.wavefront_floats(k_float_fields * n), scene.wavefront_uints(k_uint_fields * n)};
}

/// The bounces of a generated wave: intersect, shade, shadow until max_depth or no path is
/// alive. L of every path (and L_old, with params_old) is then in the state. `stage`: the pass's
/// name in the stage timings.
void trace_wave(DeviceScene& scene, const Buffer<float>& params, const Buffer<float>* params_old,
                const gpu::RenderParams& rp, Wave& w, const char* stage) {
    Kernel& intersect = scene.kernel("wavefront.cl", "wf_intersect");
    Kernel& shade = scene.kernel("wavefront.cl", params_old ? "wf_shade_two_state" : "wf_shade");
    Kernel& shadow = scene.kernel("wavefront.cl", "wf_shadow");
    const unsigned two_state = params_old ? 1 : 0;
    bool& compiled = scene.wavefront_shade_compiled(two_state);
    auto launch_shade = [&](unsigned depth) {
        if (params_old)
            scene.launch(shade, stage, w.n, rp, params, *params_old, w.state, w.flags, w.n, depth);
        else
            scene.launch(shade, stage, w.n, rp, params, w.state, w.flags, w.n, depth);
    };
    // render_pass's loop: a path has at most max_depth segments (0xFFFFFFFF: unbounded)
    for (unsigned depth = 0; depth < rp.max_depth; ++depth) {
        if (depth >= k_free_bounces && (depth - k_free_bounces) % k_check_every == 0 &&
            !any_alive(scene, w.flags, w.n, stage))
            break;
        scene.launch(intersect, stage, w.n, rp, w.state, w.flags, w.n);
        if (compiled) {
            launch_shade(depth);
        } else {
            // PoCL compiles a kernel at its first launch: this one with SLP off, so that it
            // runs SIMD across paths (runtime/pocl_llvm.h), alone in the scope (the finish
            // before: the kernels ahead of it keep SLP) and done before the scope ends
            scene.context().finish();
            const PoclSlpOff slp_off(scene.context().device());
            launch_shade(depth);
            scene.context().finish();
            compiled = true;
        }
        scene.launch(shadow, stage, w.n, rp, w.state, w.flags, w.n, two_state);
    }
}

} // namespace

void render_samples_wavefront(DeviceScene& scene, const Buffer<float>& params,
                              gpu::RenderParams rp, int begin, int count) {
    Wave w = wave_state(scene);
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& accumulate = scene.kernel("wavefront.cl", "wf_accumulate");
    rp.sample_count = 1;
    for (int k = begin; k < begin + count; ++k) {
        rp.sample_begin = static_cast<unsigned>(k);
        scene.launch(generate, "render", w.n, rp, w.state, w.flags, w.n);
        trace_wave(scene, params, nullptr, rp, w, "render");
        accumulate.launch(scene.context(), "render", w.n, w.state, scene.accum(), scene.guards(),
                          w.n);
    }
}

void render_two_state_wavefront(DeviceScene& scene, const Buffer<float>& params,
                                const Buffer<float>& params_old, gpu::RenderParams rp) {
    Wave w = wave_state(scene);
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& accumulate = scene.kernel("wavefront.cl", "wf_accumulate_two_state");
    const unsigned begin = rp.sample_begin, count = rp.sample_count;
    rp.sample_count = 1;
    for (unsigned k = begin; k < begin + count; ++k) {
        rp.sample_begin = k;
        scene.launch(generate, "render", w.n, rp, w.state, w.flags, w.n);
        trace_wave(scene, params, &params_old, rp, w, "render");
        accumulate.launch(scene.context(), "render", w.n, w.state, scene.accum(),
                          scene.accum_old(), scene.guards(), w.n);
    }
}

void adjoint_radiance_wavefront(DeviceScene& scene, const Buffer<float>& params,
                                gpu::RenderParams rp, const Buffer<float>& delta,
                                Buffer<gpu::float4>& radiance) {
    Wave w = wave_state(scene);
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& skip = scene.kernel("wavefront.cl", "wf_skip_zero_delta");
    Kernel& store = scene.kernel("wavefront.cl", "wf_store_radiance");
    const unsigned begin = rp.sample_begin, count = rp.sample_count;
    rp.sample_count = 1;
    for (unsigned k = 0; k < count; ++k) {
        rp.sample_begin = begin + k;
        scene.launch(generate, "adjoint", w.n, rp, w.state, w.flags, w.n);
        skip.launch(scene.context(), "adjoint", w.n, delta, w.flags, w.n);
        trace_wave(scene, params, nullptr, rp, w, "adjoint");
        store.launch(scene.context(), "adjoint", w.n, w.state, delta, radiance, k, w.n);
    }
}

} // namespace tandem
