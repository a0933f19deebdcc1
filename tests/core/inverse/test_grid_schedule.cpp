// The resolution schedule of grid parameters (core/inverse/grid_schedule.h): the resampling
// kernels against the shared host functions and their adjoint against the transpose (the
// dot-product test), then the schedule's step, level change and hand-over on a scene's grid.
#include <doctest/doctest.h>

#include <array>
#include <cmath>

#include "core/inverse/grid_schedule.h"
#include "core/inverse/gradient_step.h"
#include "shared/medium.h"
#include "shared/optim.h"
#include "shared/rng.h"
#include "support.h"

using namespace tandem;

namespace {

using Dims = std::array<unsigned, 3>;

std::size_t count(const Dims& d, unsigned c) { return std::size_t(d[0]) * d[1] * d[2] * c; }

std::vector<float> resample_host(const std::vector<float>& src, const Dims& s, const Dims& d,
                                 unsigned c) {
    std::vector<float> out(count(d, c));
    std::size_t e = 0;
    for (unsigned z = 0; z < d[2]; ++z)
        for (unsigned y = 0; y < d[1]; ++y)
            for (unsigned x = 0; x < d[0]; ++x)
                for (unsigned k = 0; k < c; ++k)
                    out[e++] = gpu::grid_resample_at(src.data(), s[0], s[1], s[2], c, x, y, z,
                                                     d[0], d[1], d[2], k);
    return out;
}

/// The adjoint, on the host: per element of the source grid (dims s), from the adjoint of its
/// resampling to dims d.
std::vector<float> adjoint_host(const std::vector<float>& g, const Dims& d, const Dims& s,
                                unsigned c) {
    std::vector<float> out(count(s, c));
    std::size_t e = 0;
    for (unsigned z = 0; z < s[2]; ++z)
        for (unsigned y = 0; y < s[1]; ++y)
            for (unsigned x = 0; x < s[0]; ++x)
                for (unsigned k = 0; k < c; ++k)
                    out[e++] = gpu::grid_resample_adjoint_at(g.data(), d[0], d[1], d[2], c, x, y,
                                                             z, s[0], s[1], s[2], k);
    return out;
}

std::vector<float> random_values(std::size_t n, unsigned seed) {
    std::vector<float> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = gpu::rng_uniform(seed, unsigned(i), 0, 0) - 0.3f;
    return v;
}

} // namespace

TEST_SUITE("grid schedule") {
    TEST_CASE("grid resampling: the kernels give the host's bits, and the adjoint is the transpose") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const Program program = Program::build(*ctx, KernelLibrary::from_environment(), "optim.cl", "");
        Kernel resample(program, "grid_resample"), adjoint(program, "grid_resample_adjoint");
        // coarse to fine, fine to coarse, odd sizes, a one-voxel axis, one and three channels
        const std::array<std::pair<Dims, Dims>, 4> cases{{{{4, 4, 4}, {8, 8, 8}},
                                                          {{16, 12, 8}, {4, 3, 2}},
                                                          {{5, 3, 7}, {9, 6, 13}},
                                                          {{1, 6, 3}, {2, 11, 6}}}};
        for (const auto& [s, d] : cases)
            for (unsigned c : {1u, 3u}) {
                INFO(s[0] << "x" << s[1] << "x" << s[2] << " -> " << d[0] << "x" << d[1] << "x"
                          << d[2] << ", " << c << " channels");
                const std::vector<float> u = random_values(count(s, c), 11), g = random_values(count(d, c), 12);
                // at offsets inside larger buffers, as the schedule reads theta
                std::vector<float> padded(count(s, c) + 5, 9.0f);
                std::copy(u.begin(), u.end(), padded.begin() + 5);
                Buffer<float> du(*ctx, "u", padded), dout(*ctx, "out", std::vector<float>(count(d, c) + 3, 7.0f));
                resample.launch(*ctx, "test", count(d, c), du, 5u, s[0], s[1], s[2], dout, 3u, d[0], d[1], d[2], c);
                const std::vector<float> out = dout.download();
                const std::vector<float> pu = resample_host(u, s, d, c);
                CHECK(test::same_bytes(std::vector<float>(out.begin() + 3, out.end()), pu));
                CHECK(out[0] == 7.0f);
                Buffer<float> dg(*ctx, "g", g), dgs(*ctx, "g_src", count(s, c));
                adjoint.launch(*ctx, "test", count(s, c), dg, 0u, d[0], d[1], d[2], dgs, 0u, s[0], s[1], s[2], c);
                const std::vector<float> ptg = dgs.download();
                CHECK(test::same_bytes(ptg, adjoint_host(g, d, s, c)));
                // <P u, g> = <u, P^T g>: the two sums differ only by float rounding of the
                // elements (each a sum of at most a few hundred products), far below 1e-5
                double a = 0.0, b = 0.0, scale = 0.0;
                for (std::size_t i = 0; i < pu.size(); ++i) a += double(pu[i]) * g[i], scale += std::fabs(double(pu[i]) * g[i]);
                for (std::size_t i = 0; i < u.size(); ++i) b += double(u[i]) * ptg[i];
                CHECK(std::fabs(a - b) <= 1e-5 * scale);
                // a constant stays constant (the weights sum to 1, up to rounding)
                const std::vector<float> flat = resample_host(std::vector<float>(count(s, c), 0.25f), s, d, c);
                for (float v : flat) CHECK(std::fabs(v - 0.25f) <= 1e-6f);
            }
    }

    TEST_CASE("the schedule steps the coarse grid with P^T g, resamples it at a level change and hands over at full resolution") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(
            load_scene(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-media-grid.xml"));
        const Parameter& p = scene.params.find("cloud.sigma_t");
        REQUIRE(p.kind == Parameter::Kind::volume);
        const Dims full{unsigned(p.width), unsigned(p.height), unsigned(p.depth)};
        const unsigned c = unsigned(p.channels);
        const Dims d0{(full[0] + 3) / 4, (full[1] + 3) / 4, (full[2] + 3) / 4},
            d1{(full[0] + 1) / 2, (full[1] + 1) / 2, (full[2] + 1) / 2};
        OptimizeConfig config;
        config.path = "job.json";
        OptimizedParam q;
        q.name = p.name;
        q.lr = 0.05f;
        q.upsample = {1, 2};
        config.params = {q};
        OptimizerConfig sgd;
        sgd.method = OptimizerConfig::Method::sgd;
        ParamState state(*ctx, scene.params);
        GridSchedule schedule(state, KernelLibrary::from_environment(), config, scene.params, sgd);
        const auto range = [&](const std::vector<float>& all) {
            return std::vector<float>(all.begin() + std::ptrdiff_t(p.offset),
                                      all.begin() + std::ptrdiff_t(p.offset + p.size));
        };
        // the start: sampled at 1/4 of the resolution, resampled back
        std::vector<float> values = scene.params.values();
        schedule.start(values);
        std::vector<float> u = resample_host(range(scene.params.values()), full, d0, c);
        CHECK(test::same_bytes(range(values), resample_host(u, d0, full, c)));
        state.theta().upload(values);
        const std::vector<float> g = random_values(state.size(), 21);
        state.gradient().value.upload(g);
        const auto sgd_host = [&](std::vector<float> v, const std::vector<float>& grad) {
            for (std::size_t i = 0; i < v.size(); ++i)
                v[i] = gpu::sgd_step(v[i], grad[i], q.lr, p.lower, p.upper);
            return v;
        };
        std::vector<float> lr(state.size(), 0.0f);
        std::fill_n(lr.begin() + std::ptrdiff_t(p.offset), p.size, q.lr);
        CHECK(schedule.rates(lr)[p.offset] == 0.0f); // the schedule's, not the state's optimizer's
        // iteration 0 at 1/4, then the level change to 1/2
        schedule.step(0);
        u = sgd_host(u, adjoint_host(range(g), full, d0, c));
        std::vector<float> theta = state.theta().download();
        CHECK(test::same_bytes(range(theta), resample_host(u, d0, full, c)));
        theta.erase(theta.begin() + std::ptrdiff_t(p.offset), theta.begin() + std::ptrdiff_t(p.offset + p.size));
        values.erase(values.begin() + std::ptrdiff_t(p.offset), values.begin() + std::ptrdiff_t(p.offset + p.size));
        CHECK(test::same_bytes(theta, values)); // nothing else moved
        u = resample_host(u, d0, d1, c);
        // iteration 1 at 1/2, then the full grid
        schedule.step(1);
        u = sgd_host(u, adjoint_host(range(g), full, d1, c));
        std::vector<float> now = resample_host(u, d1, full, c);
        CHECK(test::same_bytes(range(state.theta().download()), now));
        // iteration 2 on the full grid itself
        schedule.step(2);
        now = sgd_host(now, range(g));
        CHECK(test::same_bytes(range(state.theta().download()), now));
    }

    TEST_CASE("each level's Adam starts afresh: its first step moves every voxel by the learning rate") {
        // Adam's first step is lr * sign(g) (m and v from one gradient, bias-corrected); moments
        // or a step count carried over from another level would make it several times that.
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(
            load_scene(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-media-grid.xml"));
        const Parameter& p = scene.params.find("cloud.sigma_t");
        OptimizeConfig config;
        config.path = "job.json";
        OptimizedParam q;
        q.name = p.name;
        q.lr = 1e-3f;
        q.upsample = {3};
        config.params = {q};
        ParamState state(*ctx, scene.params);
        GridSchedule schedule(state, KernelLibrary::from_environment(), config, scene.params, OptimizerConfig{});
        std::vector<float> values = scene.params.values();
        for (std::size_t i = p.offset; i < p.offset + p.size; ++i) values[i] = 0.5f;
        schedule.start(values);
        state.theta().upload(values);
        std::vector<float> g(state.size(), 0.0f);
        for (std::size_t i = p.offset; i < p.offset + p.size; ++i) g[i] = 1.0f + float(i % 7);
        state.gradient().value.upload(g);
        for (int it = 0; it < 3; ++it) schedule.step(it); // the coarse level
        const std::vector<float> before = state.theta().download();
        schedule.step(3); // the full level's first step
        const std::vector<float> after = state.theta().download();
        for (std::size_t i = p.offset; i < p.offset + p.size; ++i)
            CHECK(std::fabs((before[i] - after[i]) - q.lr) <= 1e-6f);
    }

    TEST_CASE("the schedule refuses a parameter that is not a grid") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(
            load_scene(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-media-grid.xml"));
        OptimizeConfig config;
        config.path = "job.json";
        OptimizedParam q;
        q.name = "cloud.scale";
        q.upsample = {1};
        config.params = {q};
        ParamState state(*ctx, scene.params);
        CHECK_THROWS_WITH_AS(GridSchedule(state, KernelLibrary::from_environment(), config, scene.params, OptimizerConfig{}),
                             "job.json: params.cloud.scale: 'upsample' is a grid's schedule, and this is a scalar parameter",
                             Error);
    }
}
