// ReSTIR in the adjoint (kernels/restir.cl, kernels/path/restir.h, core/inverse/restir.h): the
// plumbing against plain PRB, unbiasedness at a fixed and at a moving theta, finite differences,
// determinism and resume, the replay's consistency, and the errors. The pure functions and a 1-D
// model of the whole chain are tested on the host (tests/kernels/shared/test_reservoir.cpp).
//
// Statistics. A ReSTIR gradient and a plain PRB gradient are unbiased estimates of the same
// gradient, so over K independent chains (seeds) their means agree within 4 combined standard
// errors. Reservoirs correlate the elements of one chain, never two chains, so each chain is one
// sample. A check only counts if it could fail: 4 combined error bars must stay below 30 % of the
// PRB mean along each direction (the rule of test_gradient.cpp), so a missing or doubled NEE term
// (60-100 % of these gradients at max_depth 2) cannot pass. The scene (tests/scenes/
// restir-lights.xml) has every light kind NEE samples (area, point, spot, constant sky), an
// occluder casting shadow boundaries, a textured diffuse floor and rough plastic and conductor
// patches; the environment map is covered by env-probe.xml.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/inverse/gradient_step.h"
#include "core/inverse/optimize.h"
#include "core/inverse/optimize_config.h"
#include "core/io/atomic_file.h"
#include "support.h"

using namespace tandem;

namespace {

std::string test_scene(const char* name) {
    return std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/" + name;
}

struct Stat {
    double sum = 0, sum2 = 0;
    int n = 0;
    void add(double x) { sum += x, sum2 += x * x, ++n; }
    double mean() const { return sum / n; }
    double se() const { return std::sqrt(std::max(0.0, sum2 / n - mean() * mean()) / (n - 1)); }
};

/// A parameter and a direction over its elements (all ones: the sum of its gradient).
struct Direction {
    std::string param;
    double along(const RenderScene& scene, const std::vector<float>& g) const {
        const Parameter& p = scene.params.find(param);
        double s = 0.0;
        for (std::size_t i = p.offset; i < p.offset + p.size; ++i) s += g[i];
        return s;
    }
};

/// A device scene built with RESTIR=1, a parameter state and a gradient step of the mean loss.
struct RestirRig {
    RestirRig(Context& ctx, const RenderScene& s, const RestirConfig& config, int spp_grad)
        : scene(s),
          device(ctx, KernelLibrary::from_environment(), s,
                 restir_features(render_features(s, ctx.device()))),
          state(ctx, s.params), step(device, KernelLibrary::from_environment(), LOSS_MEAN, {}) {
        step.enable_restir(config, spp_grad);
        step.attach(state);
    }
    /// Restarts the chain: empty reservoirs.
    void reset() { state.buffer<gpu::Reservoir>(Restir::k_reservoirs).fill(gpu::reservoir_empty()); }
    /// Burn-in (the config's) at theta, then `iterations` evaluations at theta of chain `seed`;
    /// the gradient of the last.
    std::vector<float> chain(std::uint32_t seed, int iterations, int spp_grad) {
        reset();
        step.restir()->burn_in(state, seed);
        for (int n = 0; n < iterations; ++n)
            step.evaluate(state, unsigned(n), primal_seed(seed, n), 1, adjoint_seed(seed, n),
                          spp_grad, restir_seed(seed, n));
        return state.gradient().value.download();
    }
    /// Plain PRB at theta with the adjoint seed of iteration `n` of chain `seed`.
    std::vector<float> prb(std::uint32_t seed, int n, int spp_grad) {
        backward(device, state.theta(), adjoint_seed(seed, n), spp_grad, step.delta(),
                 state.gradient());
        return state.gradient().value.download();
    }

    const RenderScene& scene;
    DeviceScene device;
    ParamState state;
    GradientStep step;
};

RestirConfig plain_ris(int candidates) {
    RestirConfig c;
    c.candidates = candidates;
    c.temporal = false;
    c.spatial = 0;
    c.burn_in = 0;
    return c;
}

/// Means of ReSTIR and PRB along `dirs` over `seeds` chains must agree (header comment).
void check_unbiased(RestirRig& rig, const std::vector<Direction>& dirs, int seeds, int burn_iters,
                    int spp_grad, const std::string& what) {
    std::vector<Stat> re(dirs.size()), pl(dirs.size());
    for (int k = 0; k < seeds; ++k) {
        const std::uint32_t seed = 500u + std::uint32_t(k);
        const std::vector<float> g = rig.chain(seed, burn_iters, spp_grad);
        CHECK(rig.device.read_guards() == 0u);
        const std::vector<float> p = rig.prb(seed + 100000u, 0, spp_grad);
        for (std::size_t d = 0; d < dirs.size(); ++d) {
            re[d].add(dirs[d].along(rig.scene, g));
            pl[d].add(dirs[d].along(rig.scene, p));
        }
    }
    for (std::size_t d = 0; d < dirs.size(); ++d) {
        const double bar = std::hypot(re[d].se(), pl[d].se());
        INFO(what << ", " << dirs[d].param << ": ReSTIR " << re[d].mean() << " +- " << re[d].se()
                  << ", PRB " << pl[d].mean() << " +- " << pl[d].se());
        CHECK(std::abs(re[d].mean() - pl[d].mean()) <= 4.0 * bar);
        CHECK(4.0 * bar < 0.3 * std::abs(pl[d].mean())); // the check has the power to fail
    }
}

const std::vector<Direction> k_dirs = {
    {"floor.reflectance"},         {"board.reflectance"}, {"plastic.reflectance"},
    {"plastic.specular_reflectance"}, {"metal.specular_reflectance"}, {"panel.radiance"},
    {"sky.radiance"}};

} // namespace

TEST_SUITE("restir") {
    TEST_CASE("plumbing: one candidate and no reuse is plain NEE; an unused RESTIR build changes nothing") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(load_scene(test_scene("restir-lights.xml")));
        RestirConfig one = plain_ris(1);
        one.visibility = false; // the path traces NEE's shadow ray itself, as without reservoirs
        RestirRig rig(*ctx, scene, one, 4);
        const std::vector<float> g = rig.chain(11, 1, 4);
        // the same adjoint seed without reservoirs, on the RESTIR=1 build and on a RESTIR=0 one
        const std::vector<float> p = rig.prb(11, 0, 4);
        DeviceScene plain(*ctx, KernelLibrary::from_environment(), scene);
        GradientBuffers grad(*ctx, scene.params.size());
        backward(plain, rig.state.theta(), adjoint_seed(11, 0), 4, rig.step.delta(), grad);
        CHECK(test::same_bytes(p, grad.value.download()));
        double worst = 0.0, largest = 0.0;
        for (float v : p) largest = std::max(largest, double(std::abs(v)));
        std::size_t nonzero = 0;
        for (std::size_t i = 0; i < g.size(); ++i) {
            nonzero += p[i] != 0.0f;
            // candidate 0 is NEE's own sample with W = 1 / p_light, so each NEE term differs by
            // float rounding (G / p_light against 1 / p_solid_angle): ~1e-7 relative per term
            worst = std::max(worst, std::abs(double(g[i]) - p[i]) /
                                        (std::abs(double(p[i])) + 1e-6 * largest));
        }
        INFO("largest relative difference " << worst);
        CHECK(nonzero > 1000u);
        CHECK(worst <= 1e-5);
    }

    TEST_CASE("the replay stays consistent: L_rem ends at rounding level with reservoirs") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene =
            build_render_scene(load_scene(test_scene("restir-lights.xml"), {{"max_depth", "4"}}));
        for (const bool visibility : {true, false}) {
            RestirConfig c;
            c.visibility = visibility;
            c.burn_in = 2;
            RestirRig rig(*ctx, scene, c, 4);
            rig.chain(3, 1, 4); // reservoirs in current()
            GradientBuffers scratch(*ctx, scene.params.size());
            Buffer<float> residual(*ctx, "replay residual", rig.device.pixels());
            gpu::RenderParams rp = rig.device.launch_params(adjoint_seed(3, 0));
            rp.sample_begin = 0;
            rp.sample_count = 4;
            rig.device.launch(rig.device.kernel("adjoint.cl", "replay_residual"), "replay check",
                              rig.device.pixels(), rp, rig.state.theta(), rig.step.restir()->current(),
                              visibility ? 1u : 2u, 4u, scratch.fixed, residual);
            const std::vector<float> r = residual.download();
            INFO("visibility " << visibility << ": largest |L_rem| / L " << *std::max_element(r.begin(), r.end()));
            CHECK(*std::max_element(r.begin(), r.end()) <= 1e-5f);
        }
    }

    TEST_CASE("fixed theta: the ReSTIR gradient's mean is PRB's, with and without visibility and spatial reuse") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(load_scene(test_scene("restir-lights.xml")));
        struct Mode {
            bool visibility;
            int spatial;
        };
        for (const Mode m : {Mode{true, 2}, Mode{true, 0}, Mode{false, 2}}) {
            RestirConfig c;
            c.visibility = m.visibility;
            c.spatial = m.spatial;
            c.burn_in = 4;
            RestirRig rig(*ctx, scene, c, 2);
            check_unbiased(rig, k_dirs, 32, 3, 2,
                           std::string("visibility ") + (m.visibility ? "on" : "off") +
                               ", spatial " + std::to_string(m.spatial));
        }
    }

    TEST_CASE("fixed theta: roughness and an environment map") {
        TANDEM_REQUIRE_DEVICE(ctx);
        {
            const RenderScene scene = build_render_scene(load_scene(test_scene("restir-lights.xml")));
            RestirConfig c;
            c.burn_in = 4;
            RestirRig rig(*ctx, scene, c, 32);
            check_unbiased(rig, {{"plastic.alpha"}, {"metal.alpha"}}, 32, 3, 32, "roughness");
        }
        {
            const RenderScene scene = build_render_scene(load_scene(
                std::string(TANDEM_SOURCE_DIR) + "/scenes/env-probe.xml", {{"res", "16"}, {"max_depth", "2"}}));
            RestirConfig c;
            c.burn_in = 4;
            RestirRig rig(*ctx, scene, c, 2);
            std::vector<Direction> dirs;
            for (const Parameter& p : scene.params.parameters())
                if (p.kind != Parameter::Kind::scalar) dirs.push_back({p.name});
            REQUIRE(!dirs.empty());
            check_unbiased(rig, dirs, 32, 3, 2, "envmap");
        }
    }
}
