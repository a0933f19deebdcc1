// The wavefront renderer's scheduling: waves of one sample per pixel, stages per bounce.
#include "core/render/wavefront.h"

#include <algorithm>

#include "runtime/pocl_llvm.h"

namespace tandem {

namespace {

/// The state layout of kernels/wavefront.cl (WF_FLOAT_FIELDS, WF_UINT_FIELDS).
constexpr std::size_t k_float_fields = 28, k_uint_fields = 2;
/// Bounces run without asking whether any path is alive; after them, one blocking check per
/// k_check_every bounces (a few partial sums) ends the wave once every path has.
constexpr unsigned k_free_bounces = 8, k_check_every = 4;
/// Paths per work item of the liveness check.
constexpr unsigned k_alive_chunk = 4096;

bool any_alive(DeviceScene& scene, Buffer<unsigned>& flags, unsigned n) {
    const unsigned chunks = (n + k_alive_chunk - 1) / k_alive_chunk;
    Buffer<unsigned> partial(scene.context(), "wavefront alive", chunks);
    scene.kernel("wavefront.cl", "wf_any_alive")
        .launch(scene.context(), "render", chunks, flags, partial, k_alive_chunk, n);
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

void render_samples_wavefront(DeviceScene& scene, const Buffer<float>& params,
                              gpu::RenderParams rp, int begin, int count) {
    const auto n = static_cast<unsigned>(scene.pixels());
    Buffer<float>& state = scene.wavefront_floats(k_float_fields * n);
    Buffer<unsigned>& flags = scene.wavefront_uints(k_uint_fields * n);
    Kernel& generate = scene.kernel("wavefront.cl", "wf_generate");
    Kernel& intersect = scene.kernel("wavefront.cl", "wf_intersect");
    Kernel& shade = scene.kernel("wavefront.cl", "wf_shade");
    Kernel& shadow = scene.kernel("wavefront.cl", "wf_shadow");
    Kernel& accumulate = scene.kernel("wavefront.cl", "wf_accumulate");
    rp.sample_count = 1;
    for (int k = begin; k < begin + count; ++k) {
        rp.sample_begin = static_cast<unsigned>(k);
        scene.launch(generate, "render", n, rp, state, flags, n);
        // render_pass's loop: a path has at most max_depth segments (0xFFFFFFFF: unbounded)
        for (unsigned depth = 0; depth < rp.max_depth; ++depth) {
            if (depth >= k_free_bounces && (depth - k_free_bounces) % k_check_every == 0 &&
                !any_alive(scene, flags, n))
                break;
            scene.launch(intersect, "render", n, rp, state, flags, n);
            if (scene.wavefront_shade_compiled()) {
                scene.launch(shade, "render", n, rp, params, state, flags, n, depth);
            } else {
                // PoCL compiles a kernel at its first launch: this one with SLP off, so that it
                // runs SIMD across paths (runtime/pocl_llvm.h), alone in the scope (the finish
                // before: the kernels ahead of it keep SLP) and done before the scope ends
                scene.context().finish();
                const PoclSlpOff slp_off(scene.context().device());
                scene.launch(shade, "render", n, rp, params, state, flags, n, depth);
                scene.context().finish();
                scene.wavefront_shade_compiled() = true;
            }
            scene.launch(shadow, "render", n, rp, state, flags, n);
        }
        accumulate.launch(scene.context(), "render", n, state, scene.accum(), scene.guards(), n);
    }
}

} // namespace tandem
