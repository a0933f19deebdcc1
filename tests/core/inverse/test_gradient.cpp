// Path Replay Backpropagation (kernels/adjoint.cl and the path pieces under kernels/path/):
// gradients of the mean loss against finite differences, against brute-force references, exact
// zeros, determinism, and the fixed-point accumulation (shared/fixed_point.h) including its
// saturation, wrap detection and scale choice (the scaled accumulation against float64 references:
// test_gradient_scale.cpp).
//
// How the finite-difference check works. PRB runs with Russian roulette from the first bounce
// (rr_depth 1), so its handling of roulette (the survival probability detached, the throughput
// divided by it) is part of every check. For each of K seeds s, the PRB gradient (adjoint seed
// s, spp samples) and a Richardson-extrapolated central difference of the mean image rendered
// with the same seed s and spp but without roulette,
//     D = (4 D_h - D_2h) / 3,  D_h = (I(theta + h v) - I(theta - h v)) / (2 h),
// estimate the directional derivative g.v. Roulette does not change the expected image, so D
// estimates its derivative too; rendering the differences without it keeps them free of the
// decisions that flip as theta moves (measured with roulette: 10-50 % error bars on the
// directions that move the throughput's largest channel, against 1 % without). The same seed
// draws the same camera rays and BSDF samples (the brute-force references below rest on that),
// so PRB_s and D_s are strongly correlated and their difference d_s = PRB_s - D_s has a small
// variance. Both are unbiased up to the extrapolation's O(h^4) truncation (D_h alone would carry
// h^2 I'''/6), so E[d_s] = 0. Required: |mean d| <= 4 se(d) + r, se measured from the K values
// of d (K = 32: Student's t with 31 degrees of freedom puts 4 standard errors at a two-sided
// 4e-4), and r a bound on float rounding: each pixel of a render is a float sum of spp path
// contributions, each a product of fewer than 4 max_depth rounded factors, so a mean image is off
// by at most eps = (4 max_depth + spp) 2^-24 relative, D by 1.5 eps |I| / h, and PRB by eps |PRB|
// (its sums are exact fixed point). There is no relative slack: a term missing from the gradient
// on a fraction of the paths shows as a bias of that fraction. The check must have the power to
// fail: its tolerance must stay below 10 % of |g.v| (measured: 0.3-1.1 % for the radiances,
// 0.4-9 % elsewhere), so a missing or doubled term (the emission, NEE and BSDF-sampled terms each
// carry 20-100 % of these gradients), or an emitter's gradient missing on the few percent of
// paths that reach it by BSDF sampling, cannot pass.
//
// Brute-force references (exact identities of the renderer, not of PRB): with the mean loss and
// the adjoint's own seed, the rendered image I is linear in each emitter's radiance, and, with
// direct light only (max_depth 2) on a plane filling the view, linear in the texels. Euler's
// theorem for homogeneous functions then gives sum_i theta_i dI/dtheta_i = I exactly, path by
// path, so PRB must reproduce the mean image of the same seed up to float rounding (1e-4 relative:
// each contribution is a float product of a few terms, ~1e-6, summed exactly in fixed point).
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <random>

#include "core/render/wavefront.h"
#include "inverse_fixtures.h"
#include "shared/fixed_point.h"
#include "probes/probes.h"
#include "support.h"

using namespace tandem;

namespace {

std::string test_scene(const char* name) {
    return std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/" + name;
}

/// Mean over all pixel channels of the image of `values` rendered with (seed, spp).
double mean_image(Context& ctx, DeviceScene& scene, const std::vector<float>& values, std::uint32_t seed, int spp) {
    Buffer<float> params(ctx, "test params", values);
    Buffer<float> rgb(ctx, "test image", 3 * scene.pixels());
    scene.reset_guards();
    render(scene, params, seed, spp, rgb);
    CHECK(scene.read_guards() == 0u);
    double sum = 0.0;
    for (float v : rgb.download()) sum += v;
    return sum / double(rgb.size());
}

struct Direction {
    std::string param;
    std::vector<float> v; ///< over the parameter's elements
    float h;              ///< step along v
};

using test::Stat;

/// PRB against finite differences of the same seed along each direction (see the header comment).
void check_against_fd(const std::string& scene_file,
                      const std::vector<std::pair<std::string, std::string>>& defines,
                      const std::vector<Direction>& dirs, int seeds, int spp) {
    TANDEM_REQUIRE_DEVICE(ctx);
    RenderScene scene = build_render_scene(load_scene(scene_file, defines));
    scene.rr_depth = 1; // PRB with roulette from the first bounce
    test::Inverse inv(*ctx, scene);
    RenderScene no_roulette = scene; // the finite differences' renders: the same expectation
    no_roulette.rr_depth = 1 << 20;
    DeviceScene fd_device(*ctx, KernelLibrary::from_environment(), no_roulette);
    const std::vector<float> theta = scene.params.values();
    const double eps = (4.0 * scene.max_depth + spp) * std::ldexp(1.0, -24);
    std::vector<Stat> diff(dirs.size()), prb(dirs.size());
    std::vector<double> rounding(dirs.size(), 0.0);
    for (int k = 0; k < seeds; ++k) {
        const std::uint32_t seed = 1000u + k;
        const std::vector<float> g = inv.gradient(1u, 1, seed, spp);
        CHECK(inv.guards() == 0u);
        const double image = mean_image(*ctx, fd_device, theta, seed, spp);
        for (std::size_t d = 0; d < dirs.size(); ++d) {
            const Parameter& p = scene.params.find(dirs[d].param);
            // the central difference with step t, rendered with the adjoint's seed
            auto central = [&](float t) {
                std::vector<float> plus = theta, minus = theta;
                for (std::size_t i = 0; i < p.size; ++i) {
                    plus[p.offset + i] += t * dirs[d].v[i];
                    minus[p.offset + i] -= t * dirs[d].v[i];
                }
                return (mean_image(*ctx, fd_device, plus, seed, spp) -
                        mean_image(*ctx, fd_device, minus, seed, spp)) /
                       (2.0 * t);
            };
            double gv = 0.0;
            for (std::size_t i = 0; i < p.size; ++i)
                gv += double(g[p.offset + i]) * dirs[d].v[i];
            const double fd = (4.0 * central(dirs[d].h) - central(2.0f * dirs[d].h)) / 3.0;
            prb[d].add(gv);
            diff[d].add(gv - fd);
            rounding[d] =
                std::max(rounding[d], 1.5 * eps * std::abs(image) / dirs[d].h + eps * std::abs(gv));
        }
    }
    for (std::size_t d = 0; d < dirs.size(); ++d) {
        const double tolerance = 4.0 * diff[d].se() + rounding[d];
        INFO(dirs[d].param << ": PRB " << prb[d].mean() << " +- " << prb[d].se() << ", PRB - FD "
                           << diff[d].mean() << " +- " << diff[d].se() << " (rounding bound "
                           << rounding[d] << ")");
        MESSAGE(dirs[d].param << ": g.v " << prb[d].mean() << ", tolerance "
                              << tolerance / std::abs(prb[d].mean()) << " of it, (PRB - FD) / g.v "
                              << diff[d].mean() / prb[d].mean());
        CHECK(std::abs(diff[d].mean()) <= tolerance);
        CHECK(tolerance < 0.1 * std::abs(prb[d].mean())); // the check has the power to fail
    }
}

std::vector<float> unit(std::size_t n, std::size_t i) {
    std::vector<float> v(n, 0.0f);
    v[i] = 1.0f;
    return v;
}

} // namespace

TEST_SUITE("gradient") {
    TEST_CASE("PRB matches finite differences: diffuse albedo, texture and area light, direct and indirect") {
        // three-spheres at 24x24 with max_depth 3: direct light and one indirect bounce. The
        // texture moves along the left half of its texels (the floor repeats it 3x3).
        std::vector<Direction> dirs;
        for (std::size_t c = 0; c < 3; ++c) {
            dirs.push_back({"matte.reflectance", unit(3, c), 0.02f});
            dirs.push_back({"light-emitter.radiance", unit(3, c), 0.5f});
        }
        dirs.push_back({"plastic.reflectance", {1, 1, 1}, 0.02f});
        std::vector<float> half(256 * 256 * 3, 0.0f);
        for (std::size_t i = 0; i < 256 * 256; ++i)
            if (i % 256 < 128) half[3 * i] = half[3 * i + 1] = half[3 * i + 2] = 1.0f;
        dirs.push_back({"floor.reflectance", half, 0.02f});
        check_against_fd(std::string(TANDEM_SOURCE_DIR) + "/scenes/three-spheres.xml",
                         {{"res", "24"}, {"max_depth", "3"}}, dirs, 32, 32);
    }

    TEST_CASE("PRB matches finite differences: GGX roughness and specular reflectance") {
        std::vector<Direction> dirs;
        dirs.push_back({"metal.alpha", {1}, 0.01f});
        dirs.push_back({"plastic.alpha", {1}, 0.01f});
        dirs.push_back({"metal.specular_reflectance", {1, 1, 1}, 0.02f});
        dirs.push_back({"plastic.specular_reflectance", {1, 1, 1}, 0.02f});
        dirs.push_back({"plastic.reflectance", {1, 1, 1}, 0.02f});
        dirs.push_back({"wall.reflectance", {1, 1, 1}, 0.02f});
        check_against_fd(test_scene("grad-rough.xml"), {}, dirs, 32, 32);
    }

    TEST_CASE("PRB matches finite differences: delta lobes (mirror, glass) and a constant environment") {
        std::vector<Direction> dirs;
        dirs.push_back({"mirror.specular_reflectance", {1, 1, 1}, 0.02f});
        dirs.push_back({"glass.specular_reflectance", {1, 1, 1}, 0.02f});
        dirs.push_back({"floor.reflectance", {1, 1, 1}, 0.02f});
        for (std::size_t c = 0; c < 3; ++c) dirs.push_back({"sky.radiance", unit(3, c), 0.05f});
        dirs.push_back({"lamp-emitter.radiance", {1, 1, 1}, 0.5f});
        check_against_fd(test_scene("grad-delta.xml"), {}, dirs, 32, 32);
    }

    TEST_CASE("PRB matches finite differences: a homogeneous medium's sigma_t, albedo, scale and g under a sky") {
        // The ball of grad-media.xml: the free flights' transmittance (its derivative as the
        // line integral, not the null-collision weights: kernels/path/media.h), the scattering
        // factor, the phase function's value in NEE and in its sampled direction (g). Mitsuba 3's
        // prbvolpath marks a medium under a constant sky as failing.
        std::vector<Direction> dirs;
        for (std::size_t c = 0; c < 3; ++c) dirs.push_back({"fog.sigma_t", unit(3, c), 0.2f});
        dirs.push_back({"fog.albedo", {1, 1, 1}, 0.05f});
        dirs.push_back({"fog.scale", {1}, 0.1f});
        dirs.push_back({"fog.g", {1}, 0.15f});
        dirs.push_back({"sky.radiance", {1, 1, 1}, 0.05f});
        check_against_fd(test_scene("grad-media.xml"), {}, dirs, 32, 192);
    }

    TEST_CASE("PRB matches finite differences: a medium between an area light and a wall (shadow rays through it)") {
        // The ball of grad-media-light.xml: its shadow on the wall (the shadow rays'
        // transmittance) and the light it scatters towards the camera.
        std::vector<Direction> dirs;
        dirs.push_back({"fog.sigma_t", {1, 1, 1}, 0.2f});
        dirs.push_back({"fog.albedo", {1, 1, 1}, 0.05f});
        dirs.push_back({"light.radiance", {1, 1, 1}, 2.0f});
        check_against_fd(test_scene("grad-media-light.xml"), {}, dirs, 32, 128);
    }

    TEST_CASE("PRB matches finite differences: a grid medium's voxels (extinction and albedo) and scale") {
        // grad-media-grid.xml (scale 2) with the random grids of gen_grad_media_grid.py: 6^3
        // densities in [0.25, 1.5] (one channel) and 4^3 rgb albedos in [0.3, 0.9]. The directions
        // move every voxel by its own random amount (the majorant grid is recomputed for each
        // render: DeviceScene::refresh_majorants), so every trilinear weight of the line-integral
        // and scattering terms counts.
        std::mt19937 rng(11);
        std::uniform_real_distribution<float> u(0.0f, 1.0f);
        const auto random_direction = [&](std::size_t n) {
            std::vector<float> v(n);
            for (float& x : v) x = u(rng);
            return v;
        };
        std::vector<Direction> dirs;
        dirs.push_back({"cloud.sigma_t", random_direction(216), 0.05f});
        dirs.push_back({"cloud.albedo", random_direction(192), 0.05f});
        dirs.push_back({"cloud.scale", {1}, 0.1f});
        check_against_fd(test_scene("grad-media-grid.xml"), {}, dirs, 32, 64);
    }

    TEST_CASE("PRB matches finite differences: a grid medium's empty voxels (differential ratio tracking)") {
        // The density grid with its half x < 1/2 empty (gen_grad_media_grid.py): a voxel there,
        // and the trilinear blend around it, is 0, so no path ever scatters there, and the
        // replay's scattering term cannot see d sigma_t there. The derivative is not 0 (light
        // would begin to scatter): differential ratio tracking's points, drawn from the majorant,
        // reach it (path/media_drt.h). The directions move the empty voxels only. (The finite
        // differences' lower side has densities down to -0.05: the null-collision estimators are
        // polynomial in sigma_t, so they continue it analytically.)
        std::mt19937 rng(12);
        std::uniform_real_distribution<float> u(0.0f, 1.0f);
        std::vector<float> v(216, 0.0f);
        for (std::size_t i = 0; i < v.size(); ++i)
            if (i % 6 < 3) v[i] = u(rng);
        check_against_fd(test_scene("grad-media-grid.xml"),
                         {{"density", "grad-media-density-empty.vol"}},
                         {{"cloud.sigma_t", v, 0.05f}}, 32, 64);
    }

    TEST_CASE("brute-force reference: the image is homogeneous in radiance and texels, and PRB reproduces it") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        for (const char* file : {"grad-texture.xml", "grad-delta.xml"}) {
            INFO(file);
            RenderScene scene = build_render_scene(load_scene(test_scene(file)));
            scene.rr_depth = 1; // roulette's probability is detached: the identity holds with it
            test::Inverse inv(*ctx, scene);
            const std::uint32_t seed = 77;
            const int spp = 8;
            const std::vector<float> g = inv.gradient(1, 1, seed, spp);
            const std::vector<float>& theta = scene.params.values();
            const double image = mean_image(*ctx, inv.device, theta, seed, spp);
            auto euler = [&](const std::vector<std::string>& names) {
                double s = 0.0;
                for (const std::string& n : names) {
                    const Parameter& p = scene.params.find(n);
                    for (std::size_t i = p.offset; i < p.offset + p.size; ++i) s += double(theta[i]) * g[i];
                }
                return s;
            };
            if (std::string(file) == "grad-texture.xml") {
                CHECK(euler({"paint.reflectance"}) == doctest::Approx(image).epsilon(1e-4));
                CHECK(euler({"sky.radiance"}) == doctest::Approx(image).epsilon(1e-4));
            } else {
                CHECK(euler({"sky.radiance", "lamp-emitter.radiance"}) == doctest::Approx(image).epsilon(1e-4));
            }
        }
    }

    TEST_CASE("the replay retraces its primal: every term it subtracts leaves L_rem at rounding level") {
        // The primal (path/primal.h) and the replay (path/replay.h) are separate loops built from
        // the same pieces; PRB is unbiased only if the replay takes every branch its primal took.
        // Each term the replay subtracts from L_rem = L is the one the primal added, so what is
        // left is float rounding: at most ~depth * 2^-23 of L for these non-negative terms (the
        // bound 1e-5 leaves a margin of 10x at depth 10). A term missed or added leaves a whole
        // term. Measured: at most 1.3e-7 on these scenes; with the replay's NEE subtraction
        // removed (kernels copied into TANDEM_KERNEL_DIR and edited), 0.8 to 1.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary lib = probe_library(); // with the replay check (tests/kernels/probes)
        const std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::string>>>> scenes = {
            {test_scene("grad-delta.xml"), {{"res", "16"}}},
            {test_scene("grad-rough.xml"), {{"res", "16"}}},
            {test_scene("grad-texture.xml"), {{"res", "16"}}},
            {std::string(TANDEM_SOURCE_DIR) + "/scenes/three-spheres.xml", {{"res", "16"}}},
            {std::string(TANDEM_SOURCE_DIR) + "/scenes/env-probe.xml", {{"res", "16"}}},
            {std::string(TANDEM_SOURCE_DIR) + "/scenes/indirect-room.xml", {{"res", "16"}}}};
        for (const auto& [file, defines] : scenes) {
            INFO(file);
            const RenderScene scene = build_render_scene(load_scene(file, defines));
            DeviceScene device(*ctx, lib, scene);
            const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
            GradientBuffers scratch(*ctx, scene.params.size());
            Buffer<float> residual(*ctx, "replay residual", device.pixels());
            gpu::RenderParams rp = device.launch_params(31);
            rp.sample_begin = 0;
            rp.sample_count = 8;
            device.launch(0, device.kernel("probes/replay_check.cl", "replay_residual"), "replay check", device.pixels(), rp,
                          theta, device.no_reservoirs(), 0u, 0u, scratch.fixed, residual);
            const std::vector<float> r = residual.download();
            const float worst = *std::max_element(r.begin(), r.end());
            INFO("largest |L_rem| / L: " << worst);
            CHECK(worst <= 1e-5f);
        }
    }

    TEST_CASE("a NaN in the parameter buffer: every pass drops and counts the samples it reaches, "
              "and no image or gradient sees it") {
        // The red wall's reflectance is NaN: every path that shades it carries NaN from there
        // on. render_pass, the fused two-state kernel and the adjoint, as megakernels and as the
        // wavefront, must each drop those samples (kernels/render.cl, wavefront.cl, adjoint.cl:
        // all_finite; the adjoint also drops the NaN contributions of paths whose radiance stayed
        // finite, as saturated ones) and count them in the guards, so the images and the
        // gradient stay finite, and the two forms agree on every bit and every count.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene =
            build_render_scene(load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox-wall.xml",
                                          {{"res", "9"}, {"max_depth", "4"}}));
        const Parameter& red = scene.params.find("red.reflectance");
        const Parameter& white = scene.params.find("white.reflectance");
        std::vector<float> poisoned = scene.params.values();
        for (std::size_t i = red.offset; i < red.offset + red.size; ++i)
            poisoned[i] = std::nanf("");
        const std::uint32_t seed = 11;
        const int spp = 6;
        auto all_finite = [](const std::vector<float>& v) {
            return std::all_of(v.begin(), v.end(), [](float x) { return std::isfinite(x); });
        };
        struct Outputs {
            std::vector<float> image, image_new, image_old, gradient;
            std::uint64_t guards[3] = {0, 0, 0}; // render, two-state, adjoint
        };
        Outputs out[2];
        for (int wavefront : {0, 1}) {
            INFO("WAVEFRONT=" << wavefront);
            BuildFlags features = render_features(scene, ctx->device());
            REQUIRE(wavefront_supported(features));
            features.set("WAVEFRONT", wavefront);
            DeviceScene device(*ctx, lib, scene, features);
            Buffer<float> theta(*ctx, "poisoned params", poisoned);
            Buffer<float> clean = parameter_buffer(*ctx, scene.params);
            Buffer<float> rgb(*ctx, "image", 3 * device.pixels()),
                rgb_old(*ctx, "old image", 3 * device.pixels());
            Outputs& o = out[wavefront];
            device.reset_guards();
            render(device, theta, seed, spp, rgb);
            o.guards[0] = device.read_guards();
            o.image = rgb.download();
            CHECK(o.guards[0] > 0u);
            CHECK(all_finite(o.image));
            // the two-state render with the poisoned state new and the clean one old: a sample
            // is dropped from both when either is not finite
            device.reset_guards();
            render_two_state(device, theta, clean, seed, spp, rgb, rgb_old);
            o.guards[1] = device.read_guards();
            o.image_new = rgb.download();
            o.image_old = rgb_old.download();
            CHECK(o.guards[1] > 0u);
            CHECK(all_finite(o.image_new));
            CHECK(all_finite(o.image_old));
            Buffer<float> delta(*ctx, "delta", std::vector<float>(3 * device.pixels(), 0.01f));
            GradientBuffers grad(*ctx, scene.params.size());
            device.reset_guards();
            backward(device, theta, seed, spp, delta, grad);
            o.guards[2] = device.read_guards();
            o.gradient = grad.value.download();
            CHECK(o.guards[2] > 0u);
            CHECK(all_finite(o.gradient));
            CHECK(o.gradient[white.offset] > 0.0f); // the samples kept still carry gradients
        }
        for (int k = 0; k < 3; ++k)
            CHECK(out[1].guards[k] == out[0].guards[k]);
        CHECK(test::same_bytes(out[1].image, out[0].image));
        CHECK(test::same_bytes(out[1].image_new, out[0].image_new));
        CHECK(test::same_bytes(out[1].image_old, out[0].image_old));
        CHECK(test::same_bytes(out[1].gradient, out[0].gradient));
    }

    TEST_CASE("a parameter that does not affect the image has a gradient of exactly zero") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(test_scene("grad-delta.xml")));
        test::Inverse inv(*ctx, scene);
        const std::vector<float> g = inv.gradient(1, 1, 2, 8);
        const Parameter& unused = scene.params.find("unused.reflectance");
        for (std::size_t i = unused.offset; i < unused.offset + unused.size; ++i) CHECK(g[i] == 0.0f);
        const Parameter& floor = scene.params.find("floor.reflectance"); // and a used one is not
        CHECK(g[floor.offset] > 0.0f);
    }

    TEST_CASE("gradients are bit-identical run to run, and depend on the adjoint seed") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(
            std::string(TANDEM_SOURCE_DIR) + "/scenes/three-spheres.xml", {{"res", "16"}, {"max_depth", "4"}}));
        const std::vector<float> ref(3 * 16 * 16, 0.3f);
        test::Inverse inv(*ctx, scene, LOSS_L1, ref);
        const std::vector<float> a = inv.gradient(1, 4, 2, 4);
        const std::vector<float> b = inv.gradient(1, 4, 2, 4);
        const std::vector<float> c = inv.gradient(1, 4, 3, 4);
        CHECK(test::same_bytes(a, b));
        CHECK(!test::same_bytes(a, c));
    }

    TEST_CASE("the wavefront's adjoint gives the megakernels' gradients and guards bit for bit") {
        // core/render/wavefront.h: adjoint_wavefront replaces adjoint_primal and adjoint_pass
        // where the scene allows: every contribution is the same float, so every fixed-point
        // sum, and every gradient bit, agrees.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        // scene: a bundled scene's file; min_nonzero: gradient elements that must be reached
        auto check = [&](const std::string& file, std::size_t min_nonzero) {
            INFO(file);
            RenderScene scene =
                build_render_scene(load_scene(file, {{"res", "16"}, {"max_depth", "5"}}));
            scene.rr_depth = 1; // the wavefront's own roulette stage, against the megakernels'
            BuildFlags features = render_features(scene, ctx->device());
            REQUIRE(wavefront_supported(features));
            // delta of every sign, and zero in a block of pixels (whose paths both passes skip)
            std::vector<float> d(3 * 16 * 16);
            for (std::size_t i = 0; i < d.size(); ++i)
                d[i] = (i / 3) % 16 < 5 ? 0.0f : 0.01f * float(int(i % 7) - 3);
            // the megakernels, the wavefront replaying every bounce from its record, and the
            // wavefront recording only the first two (later bounces traced again)
            std::vector<float> grads[3], saturated_grads[3];
            std::uint64_t guards[3], saturated[3];
            for (int run : {0, 1, 2}) {
                features.set("WAVEFRONT", run == 0 ? 0 : 1);
                DeviceScene device(*ctx, lib, scene, features);
                if (run == 2) device.wavefront().record_bounces = 2;
                const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
                Buffer<float> delta(*ctx, "delta", d);
                GradientBuffers grad(*ctx, scene.params.size());
                backward(device, theta, 3, 6, delta, grad); // two launches of samples: 4 + 2
                grads[run] = grad.value.download();
                guards[run] = device.read_guards();
                // scaled by 2^40, most contributions pass GRAD_MAX_CONTRIBUTION: the count of the
                // saturated ones, and the sums of the clamped values, agree too
                device.reset_guards();
                grad.forced_exponent = 40;
                backward(device, theta, 3, 6, delta, grad);
                saturated_grads[run] = grad.value.download();
                saturated[run] = device.read_guards();
            }
            for (int run : {1, 2}) {
                INFO("run " << run);
                CHECK(test::same_bytes(grads[0], grads[run]));
                CHECK(guards[0] == guards[run]);
                CHECK(test::same_bytes(saturated_grads[0], saturated_grads[run]));
                CHECK(saturated[0] == saturated[run]);
            }
            CHECK(saturated[1] > 4 * min_nonzero);
            std::size_t nonzero = 0;
            for (float g : grads[1]) nonzero += g != 0.0f;
            CHECK(nonzero >= min_nonzero);
        };
        // area lights and a bitmap texture: texels of the wall, the emitter and the other bsdfs
        check(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox-wall.xml", 1000);
        // an environment map alone (escaped rays and its light samples; not a parameter): the two
        // albedos
        check(std::string(TANDEM_SOURCE_DIR) + "/scenes/env-probe.xml", 6);
        // a constant environment, whose radiance is a parameter, over a bitmap texture
        check(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-texture.xml", 1000);
        // materials other than diffuse (wf_shade_general_replay): rough conductor and plastic
        // (specular, alpha), smooth conductor and dielectric
        check(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-rough.xml", 14);
        check(std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-delta.xml", 12);
    }

    TEST_CASE("a wavefront record of 0 bounces (TANDEM_WAVEFRONT_RECORD=0) retraces every bounce of the replay with the same bits, and a bad value is a one-line error") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(
            std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox-wall.xml", {{"res", "8"}, {"max_depth", "4"}}));
        BuildFlags features = render_features(scene, *ctx);
        const std::vector<float> d(3 * 8 * 8, 0.02f);
        // record: unset (the policy's record), or the bounces the Tuning asks for
        auto gradient = [&](int wavefront, std::optional<unsigned> record) {
            const test::ScopedTuning tuning(*ctx,
                                            [&](Tuning& t) { t.wavefront_record_bounces = record; });
            features.set("WAVEFRONT", wavefront);
            DeviceScene device(*ctx, lib, scene, features);
            const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
            Buffer<float> delta(*ctx, "delta", d);
            GradientBuffers grad(*ctx, scene.params.size());
            backward(device, theta, 5, 3, delta, grad);
            return grad.value.download();
        };
        const std::vector<float> mega = gradient(0, std::nullopt);
        CHECK(test::same_bytes(gradient(1, std::nullopt), mega));
        CHECK(test::same_bytes(gradient(1, 0u), mega));
        {
            const test::ScopedEnv zero("TANDEM_WAVEFRONT_RECORD", "0");
            CHECK(tuning_from_environment().wavefront_record_bounces == std::optional<unsigned>(0));
        }
        for (const char* bad : {"x", "-1", "", "1e3"}) {
            INFO("TANDEM_WAVEFRONT_RECORD='" << bad << "'");
            const test::ScopedEnv env("TANDEM_WAVEFRONT_RECORD", bad);
            try {
                tuning_from_environment();
                FAIL("no error");
            } catch (const Error& e) {
                const std::string what = e.what();
                CHECK(what.find("TANDEM_WAVEFRONT_RECORD") != std::string::npos);
                CHECK(what.find('\n') == std::string::npos);
            }
        }
    }

    TEST_CASE("differentiating only some elements gives them the same bits, and the others exactly zero") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(test_scene("grad-texture.xml"), {{"res", "8"}}));
        DeviceScene device(*ctx, lib, scene);
        const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
        Buffer<float> delta(*ctx, "delta", std::vector<float>(3 * 64, 1.0f / 192.0f));
        GradientBuffers all(*ctx, scene.params.size()), some(*ctx, scene.params.size());
        // one whole parameter, and a range inside another that straddles a mask word
        const Parameter& sky = scene.params.find("sky.radiance");
        const Parameter& tex = scene.params.find("paint.reflectance");
        REQUIRE(tex.size > 40);
        some.differentiate_only({{sky.offset, sky.size}, {tex.offset + 5, 33}});
        backward(device, theta, 5, 4, delta, all);
        backward(device, theta, 5, 4, delta, some);
        const std::vector<float> a = all.value.download(), b = some.value.download();
        std::size_t kept = 0, nonzero = 0;
        for (std::size_t i = 0; i < a.size(); ++i) {
            const bool selected = (i >= sky.offset && i < sky.offset + sky.size) ||
                                  (i >= tex.offset + 5 && i < tex.offset + 38);
            INFO("element " << i);
            if (selected) {
                CHECK(std::memcmp(&a[i], &b[i], sizeof(float)) == 0);
                ++kept;
            } else {
                CHECK(b[i] == 0.0f);
                nonzero += a[i] != 0.0f;
            }
        }
        CHECK(kept == sky.size + 33);
        CHECK(nonzero > 0); // the skipped elements do have gradients when computed
    }

    TEST_CASE("a huge adjoint is scaled into range, and in unscaled units it saturates and wraps, both counted") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(test_scene("grad-texture.xml"), {{"res", "8"}}));
        DeviceScene device(*ctx, lib, scene);
        const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
        GradientBuffers grad(*ctx, scene.params.size());
        const Parameter& sky = scene.params.find("sky.radiance");
        // the guard count of one backward() pass
        auto dropped = [&](const Buffer<float>& delta) {
            device.reset_guards();
            backward(device, theta, 5, 2, delta, grad);
            return device.read_guards();
        };
        Buffer<float> normal(*ctx, "delta", std::vector<float>(3 * 64, 1.0f / 192.0f));
        CHECK(dropped(normal) == 0u);
        // The scale follows sum |delta|: 1e12 per element leaves every contribution in range.
        Buffer<float> huge(*ctx, "delta", std::vector<float>(3 * 64, 1e12f));
        CHECK(dropped(huge) == 0u);
        std::vector<float> g = grad.value.download();
        for (std::size_t i = 0; i < g.size(); ++i) REQUIRE(std::isfinite(g[i]));
        CHECK(g[sky.offset] > 1e12f); // ~1e12 * 64 pixels * the mean image
        CHECK(grad.exponent.download()[0] == GRAD_TARGET_EXPONENT - 47); // 192e12 ~ 2^47.4
        // All of delta in one pixel: the scale follows it there too (one contribution < 2 phi /
        // spp after scaling), so nothing saturates, and the gradient is that pixel's alone.
        std::vector<float> one(3 * 64, 0.0f);
        one[3 * 27] = one[3 * 27 + 1] = one[3 * 27 + 2] = 1e12f;
        Buffer<float> single(*ctx, "delta", one);
        CHECK(dropped(single) == 0u);
        g = grad.value.download();
        CHECK(std::isfinite(g[sky.offset]));
        CHECK(g[sky.offset] > 0.0f);
        CHECK(g[sky.offset] < 1e12f * 3.0f); // one pixel's worth: 1e12 times its radiance share

        // In the unscaled units of 2^-40 (s = 0), the same delta gives contributions beyond 2^22:
        // clamped and counted, and their sums past 2^23 wrap: detected, saturated to +2^23 (the
        // side they left on, never a wrapped negative or NaN) and counted.
        grad.forced_exponent = 0;
        CHECK(dropped(huge) > 0u);
        g = grad.value.download();
        for (std::size_t i = 0; i < g.size(); ++i) REQUIRE(std::isfinite(g[i]));
        for (std::size_t c = 0; c < 3; ++c) CHECK(g[sky.offset + c] == GRAD_RANGE);

        // A wrap without any saturated contribution: delta = 2^21 gives contributions below 2^21
        // each, but 2.4e7 to 6.2e7 per sky channel in all (texels: below 2e6). Before wrap
        // detection this passed silently.
        Buffer<float> large(*ctx, "delta", std::vector<float>(3 * 64, std::ldexp(1.0f, 21)));
        grad.forced_exponent.reset();
        CHECK(dropped(large) == 0u);
        const std::vector<float> scaled = grad.value.download(); // in range after scaling
        std::uint64_t beyond = 0; // elements whose true sum is outside the unscaled range
        for (float v : scaled) {
            INFO("an element's gradient: " << v);
            REQUIRE((std::abs(v) >= 1.5f * GRAD_RANGE || std::abs(v) < 0.5f * GRAD_RANGE)); // unambiguous
            beyond += std::abs(v) >= GRAD_RANGE;
        }
        REQUIRE(beyond > 0u);
        CHECK(scaled[sky.offset] >= GRAD_RANGE);
        grad.forced_exponent = 0;
        CHECK(dropped(large) == beyond); // one count per wrapped element, nothing else
        g = grad.value.download();
        for (std::size_t i = 0; i < g.size(); ++i) {
            if (std::abs(scaled[i]) >= GRAD_RANGE)
                CHECK(g[i] == (scaled[i] > 0.0f ? GRAD_RANGE : -GRAD_RANGE));
            else
                CHECK(std::abs(g[i] - scaled[i]) <= 1e-5f * std::abs(scaled[i]) + 1e-3f);
        }
        // the next call starts from zero again: decode resets the sums and the wrap counts
        grad.forced_exponent.reset();
        CHECK(dropped(normal) == 0u);
    }
}

TEST_SUITE("fixed point") {
    TEST_CASE("two 32-bit halves with carries sum exactly like int64, in any order") {
        std::mt19937_64 rng(3);
        std::uniform_real_distribution<float> mag(-4.0f, 4.0f);
        std::vector<float> values;
        for (int i = 0; i < 20000; ++i) values.push_back(std::ldexp(mag(rng), int(rng() % 40) - 30));
        values.push_back(GRAD_MAX_CONTRIBUTION);  // the extremes of the documented range
        values.push_back(-GRAD_MAX_CONTRIBUTION);
        values.push_back(std::ldexp(1.0f, -41)); // rounds to even (0) / to one unit
        values.push_back(std::ldexp(3.0f, -41));
        std::int64_t exact = 0;
        double reference = 0.0;
        for (float v : values) {
            exact += gpu::fixed_encode(v);
            reference += double(v);
        }
        for (int order = 0; order < 3; ++order) {
            unsigned slot[GRAD_WORDS] = {0u, 0u, 0u};
            for (float v : values) gpu::fixed_add(slot, gpu::fixed_encode(v));
            const std::int64_t sum = std::int64_t((std::uint64_t(slot[1]) << 32) | slot[0]);
            CHECK(sum == exact);
            CHECK(slot[2] == 0u); // no wrap
            // float64 reference: each contribution rounds by <= 2^-41
            CHECK(std::abs(double(sum) * std::ldexp(1.0, -40) - reference) <= values.size() * std::ldexp(1.0, -41));
            unsigned wrapped = 1u;
            CHECK(gpu::fixed_decode(slot, 0, &wrapped) == static_cast<float>(double(sum) * std::ldexp(1.0, -40)));
            CHECK(wrapped == 0u);
            // decoding the same integers as contributions scaled by 2^s is exact: 2^-s times
            CHECK(gpu::fixed_decode(slot, 17, &wrapped) == std::ldexp(gpu::fixed_decode(slot, 0, &wrapped), -17));
            CHECK(gpu::fixed_decode(slot, -GRAD_MAX_EXPONENT, &wrapped) ==
                  std::ldexp(gpu::fixed_decode(slot, 0, &wrapped), GRAD_MAX_EXPONENT));
            std::shuffle(values.begin(), values.end(), rng);
        }
        CHECK(gpu::fixed_encode(std::ldexp(1.0f, -41)) == 0);  // ties to even
        CHECK(gpu::fixed_encode(std::ldexp(3.0f, -41)) == 2);
        CHECK(gpu::fixed_encode(-1.0f) == -(std::int64_t(1) << 40));
    }

    TEST_CASE("a sum that leaves the 64-bit range is detected in any order, and one that only passes through it is exact") {
        std::mt19937_64 rng(5);
        const float big = GRAD_MAX_CONTRIBUTION; // 2^62 units: two of one sign leave the range
        auto add_all = [](const std::vector<float>& values, unsigned* slot) {
            slot[0] = slot[1] = slot[2] = 0u;
            for (float v : values) gpu::fixed_add(slot, gpu::fixed_encode(v));
        };
        std::vector<float> values;
        for (int i = 0; i < 1000; ++i) values.push_back(std::ldexp(float(rng() % 1000) - 500.0f, int(rng() % 30) - 30));
        std::int64_t small = 0;
        for (float v : values) small += gpu::fixed_encode(v);
        // three up and three down: the running sum leaves the range in some orders and comes
        // back; the net wrap count is 0 in every order and the sum exact
        std::vector<float> through = values;
        for (int i = 0; i < 3; ++i) {
            through.push_back(big);
            through.push_back(-big);
        }
        // five up: 5 2^22 > 2^23, a wrap in every order; and five down
        std::vector<float> up = values, down = values;
        for (int i = 0; i < 5; ++i) {
            up.push_back(big);
            down.push_back(-big);
        }
        int crossings = 0; // orders in which `through` left the range on the way
        for (int order = 0; order < 20; ++order) {
            unsigned slot[GRAD_WORDS];
            add_all(through, slot);
            CHECK(slot[2] == 0u);
            CHECK(std::int64_t((std::uint64_t(slot[1]) << 32) | slot[0]) == small);
            unsigned wrapped = 1u;
            CHECK(gpu::fixed_decode(slot, 0, &wrapped) == static_cast<float>(double(small) * std::ldexp(1.0, -40)));
            CHECK(wrapped == 0u);
            std::int64_t running = 0; // the same order, in quarter units (int64 holds it)
            bool left = false;
            for (float v : through) {
                running += gpu::fixed_encode(v) / 4; // a quarter: no overflow here
                left |= running >= (std::int64_t(1) << 61) || running < -(std::int64_t(1) << 61);
            }
            crossings += left;
            add_all(up, slot);
            CHECK(slot[2] == 1u);
            CHECK(gpu::fixed_decode(slot, 3, &wrapped) == std::ldexp(GRAD_RANGE, -3));
            CHECK(wrapped == 1u);
            add_all(down, slot);
            CHECK(slot[2] == 0xFFFFFFFFu); // -1
            CHECK(gpu::fixed_decode(slot, 0, &wrapped) == -GRAD_RANGE);
            CHECK(wrapped == 1u);
            std::shuffle(through.begin(), through.end(), rng);
            std::shuffle(up.begin(), up.end(), rng);
            std::shuffle(down.begin(), down.end(), rng);
        }
        CHECK(crossings > 0); // the test saw sums that crossed the boundary and came back
    }

    TEST_CASE("partial sums merge into the single accumulator's slot: a partial that wraps, a total that does, any grouping") {
        // MPI ranks each accumulate their share of the contributions, then fixed_merge adds the
        // slots; the result must be the slot of one accumulator of every contribution, bit for
        // bit (the wrap count included)
        std::mt19937_64 rng(11);
        const float big = GRAD_MAX_CONTRIBUTION; // 2^62 units
        auto slot_of = [](const std::vector<float>& values) {
            std::array<unsigned, GRAD_WORDS> slot{0u, 0u, 0u};
            for (float v : values) gpu::fixed_add(slot.data(), gpu::fixed_encode(v));
            return slot;
        };
        std::vector<float> small;
        for (int i = 0; i < 300; ++i) small.push_back(std::ldexp(float(rng() % 1000) - 500.0f, int(rng() % 30) - 30));
        struct Case {
            const char* what;
            std::vector<std::vector<float>> parts;
            unsigned wraps; // of the total: 0, or 1 (up) / 0xFFFFFFFF (down)
        };
        std::vector<Case> cases;
        { // rank 0 leaves the range upwards, rank 1 brings the total back
            std::vector<float> a = small, b;
            for (int i = 0; i < 5; ++i) a.push_back(big);
            for (int i = 0; i < 4; ++i) b.push_back(-big);
            cases.push_back({"a partial wraps, the total does not", {a, b}, 0u});
        }
        { // neither partial wraps, the total does (3 + 3 times 2^62 > 2^63)
            std::vector<float> a = small, b, c;
            for (int i = 0; i < 3; ++i) {
                a.push_back(big);
                b.push_back(big);
            }
            c.push_back(-1.0f);
            cases.push_back({"the total wraps, no partial does", {a, b, c}, 1u});
        }
        { // downwards, and a partial that wraps twice the other way's
            std::vector<float> a, b = small;
            for (int i = 0; i < 7; ++i) a.push_back(-big); // -1.75 2^64: two wraps down
            for (int i = 0; i < 3; ++i) b.push_back(big);
            cases.push_back({"downwards", {a, b}, 0xFFFFFFFFu});
        }
        for (const Case& c : cases) {
            CAPTURE(c.what);
            std::vector<float> all;
            for (const auto& p : c.parts) all.insert(all.end(), p.begin(), p.end());
            const auto single = slot_of(all);
            CHECK(single[2] == c.wraps);
            // every order of the merges (a chain in each permutation), and a tree
            std::vector<std::size_t> order(c.parts.size());
            for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
            do {
                std::array<unsigned, GRAD_WORDS> merged{0u, 0u, 0u};
                for (std::size_t i : order) {
                    const auto part = slot_of(c.parts[i]);
                    gpu::fixed_merge(merged.data(), part.data());
                }
                CHECK(merged == single);
            } while (std::next_permutation(order.begin(), order.end()));
            if (c.parts.size() == 3) { // (p2 + p1) + p0
                auto left = slot_of(c.parts[2]);
                const auto p1 = slot_of(c.parts[1]);
                gpu::fixed_merge(left.data(), p1.data());
                auto root = slot_of(c.parts[0]);
                gpu::fixed_merge(root.data(), left.data());
                CHECK(root == single);
            }
        }
        // random shares of random contributions among 1 to 5 accumulators
        for (int trial = 0; trial < 200; ++trial) {
            std::vector<float> all;
            const int n = int(rng() % 40);
            for (int i = 0; i < n; ++i)
                all.push_back(rng() % 4 == 0 ? (rng() % 2 ? big : -big)
                                             : std::ldexp(float(rng() % 2000) - 1000.0f, int(rng() % 40) - 30));
            const std::size_t ranks = 1 + rng() % 5;
            std::vector<std::vector<float>> parts(ranks);
            for (float v : all) parts[rng() % ranks].push_back(v);
            std::array<unsigned, GRAD_WORDS> merged{0u, 0u, 0u};
            for (const auto& p : parts) {
                const auto part = slot_of(p);
                gpu::fixed_merge(merged.data(), part.data());
            }
            CHECK(merged == slot_of(all));
        }
    }

    TEST_CASE("the scale exponent puts sum |delta| 2^s between 2^T and 2^(T+1) for the target T, from the float's bits") {
        CHECK(gpu::grad_exponent_for(1.0f) == GRAD_TARGET_EXPONENT);
        CHECK(gpu::grad_exponent_for(1.99f) == GRAD_TARGET_EXPONENT);
        CHECK(gpu::grad_exponent_for(2.0f) == GRAD_TARGET_EXPONENT - 1);
        CHECK(gpu::grad_exponent_for(std::ldexp(1.5f, -30)) == GRAD_TARGET_EXPONENT + 30);
        for (int k = -60; k <= 60; ++k) // scale invariance: sum 2^k gives s - k
            CHECK(gpu::grad_exponent_for(std::ldexp(1.3f, k)) == gpu::grad_exponent_for(1.3f) - k);
        CHECK(gpu::grad_exponent_for(0.0f) == 0);
        CHECK(gpu::grad_exponent_for(std::nanf("")) == 0);
        CHECK(gpu::grad_exponent_for(INFINITY) == -GRAD_MAX_EXPONENT);
        CHECK(gpu::grad_exponent_for(std::ldexp(1.0f, 120)) == -GRAD_MAX_EXPONENT);
        CHECK(gpu::grad_exponent_for(std::ldexp(1.0f, -140)) == GRAD_MAX_EXPONENT); // subnormal
        for (int e = -126; e <= 127; ++e) CHECK(gpu::grad_pow2(e) == std::ldexp(1.0f, e));
    }
}
