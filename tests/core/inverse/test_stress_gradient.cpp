// The forward stress scene (test_lights.cpp: GGX alpha 1e-4 and 1, radiance 1e-6 and 1e6, a mesh
// with zero-area and duplicate triangles, grazing views) through the gradient kernels: 100
// iterations of PRB with the fused two-state control variate (CV-PS) and Adam over every
// differentiable parameter of the scene. No NaN or Inf may reach the gradients, the CV images,
// the CV state or the parameters; the guards (dropped non-finite samples, clamped contributions,
// saturated sums) may fire and are reported.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/gtc/matrix_transform.hpp>

#include "core/inverse/gradient_step.h"
#include "core/inverse/optimizer.h"
#include "../render/render_fixtures.h"
#include "support.h"

using namespace tandem;

namespace {


/// Non-finite values among `count` floats at `data`.
std::size_t non_finite(const float* data, std::size_t count) {
    std::size_t bad = 0;
    for (std::size_t i = 0; i < count; ++i) bad += !std::isfinite(data[i]);
    return bad;
}
template <class T> std::size_t non_finite(const std::vector<T>& v) {
    static_assert(sizeof(T) % sizeof(float) == 0, "a struct of floats");
    std::vector<float> f(v.size() * sizeof(T) / sizeof(float));
    if (!v.empty()) std::memcpy(f.data(), v.data(), f.size() * sizeof(float));
    return non_finite(f.data(), f.size());
}

} // namespace

TEST_SUITE("device") {
    TEST_CASE("stress: the adjoint and two-state kernels keep gradients, CV and parameters finite") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const int res = 16, iterations = 100;
        // The target: the same scene with moderate values, so that the loss and its delta are
        // large where the start is extreme (radiance 1e6 against 1, alpha 1e-4 against 0.3).
        const std::vector<float> target = test::render_desc(*ctx, test::stress_scene(0.3f, 1.0f, res), 16).rgb;
        for (float alpha : {1e-4f, 1.0f})
            for (float radiance : {1e-6f, 1e6f}) {
                const RenderScene scene = build_render_scene(test::stress_scene(alpha, radiance, res));
                DeviceScene device(*ctx, lib, scene);
                GradientStep step(device, lib, LOSS_L2, target, CvMode::ps);
                ParamState state(*ctx, scene.params);
                Optimizer optimizer(state, lib, OptimizerConfig{});
                step.attach(state);
                std::vector<const Parameter*> all;
                std::string names;
                for (const Parameter& p : scene.params.parameters()) {
                    if (p.moves_geometry()) continue; // the materials and lights, not shapes
                    all.push_back(&p);
                    names += " " + p.name;
                }
                state.learning_rates().upload(std::vector<float>(state.size(), 0.02f));
                state.differentiate_only(all);
                device.reset_guards();
                std::size_t bad_gradient = 0, bad_cv_image = 0, zero_gradient = 0;
                for (int it = 0; it < iterations; ++it) {
                    const auto n = std::uint32_t(it);
                    step.evaluate(state, unsigned(it), primal_seed(7, n), 1, adjoint_seed(7, n), 1);
                    state.remember_theta();
                    const std::vector<float> g = state.gradient().value.download();
                    bad_gradient += non_finite(g);
                    zero_gradient +=
                        std::all_of(g.begin(), g.end(), [](float x) { return x == 0.0f; });
                    bad_cv_image += non_finite(step.image().download()) + non_finite(step.image_old().download());
                    optimizer.step();
                }
                const std::uint64_t guards = device.read_guards();
                const std::size_t bad_cv_state =
                    non_finite(state.buffer<gpu::CvState>(GradientStep::k_cv_state).download());
                const std::vector<float> theta = state.theta().download();
                const std::vector<float> start = scene.params.values();
                std::size_t moved = 0; // parameters of which some element left its start
                std::string still;
                for (const Parameter* p : all) {
                    const bool m =
                        !std::equal(theta.begin() + p->offset, theta.begin() + p->offset + p->size,
                                    start.begin() + p->offset);
                    moved += m;
                    if (!m) still += " " + p->name;
                }
                const float loss = step.loss();
                MESSAGE("alpha " << alpha << ", radiance " << radiance << " (" << all.size()
                                 << " parameters:" << names << "): " << guards << " guards over "
                                 << iterations << " iterations, final loss " << loss << ", "
                                 << zero_gradient << " iterations with an all-zero gradient, "
                                 << moved << " parameters moved (not:" << still << ")");
                CHECK(all.size() >= 6);
                CHECK(bad_gradient == 0);
                CHECK(bad_cv_image == 0);
                CHECK(bad_cv_state == 0);
                CHECK(non_finite(theta) == 0);
                CHECK(non_finite(optimizer.moment1().download()) == 0);
                CHECK(non_finite(optimizer.moment2().download()) == 0);
                CHECK(std::isfinite(loss));
                // ... and the guards do not keep the gradients from working: every iteration has
                // a gradient, most parameters move (not all can: a radiance of 1e6 takes no step
                // of 0.02 in float, and an alpha or reflectance at the end of its range pushed
                // beyond it stays there), and the guards drop under 5 % of the samples (16² pixels,
                // a primal and an adjoint sample each per iteration).
                CHECK(zero_gradient == 0);
                CHECK(2 * moved >= all.size());
                CHECK(guards * 20 < std::uint64_t(2 * res * res * iterations));
            }
    }
}
