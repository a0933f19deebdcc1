// The recursive control variate on the device: the fused two-state kernel (CV-PS) against plain
// renders, the steady state on an unchanging scene, CV-PS against CV-PSS, and determinism.
//
// Statistics: every comparison of expectations uses R independent runs (seeds) and a z-score of
// the difference of means over the image (each run's image mean is one sample; the runs are
// independent, so the standard error comes from the spread across runs); |z| < 4 fails with
// probability < 1e-4 per check under the null hypothesis.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <functional>

#include "core/inverse/control_variate.h"
#include "core/inverse/gradient_step.h"
#include "core/io/atomic_file.h"
#include "support.h"

using namespace tandem;

namespace {

std::string test_scene(const char* name) {
    return std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/" + name;
}

double mean_of(const std::vector<float>& v) {
    double s = 0.0;
    for (float x : v) s += x;
    return s / double(v.size());
}

struct Stat {
    double sum = 0, sum2 = 0;
    int n = 0;
    void add(double x) { sum += x, sum2 += x * x, ++n; }
    double mean() const { return sum / n; }
    double var() const { return std::max(0.0, (sum2 - sum * sum / n) / (n - 1)); }
};

/// A run of `iterations` CV iterations at 1 spp whose parameter buffer moves along `schedule`
/// (theta_n = schedule(n)); returns the final CV image (the estimate of theta_{N-1}).
std::vector<float> run_cv(Context& ctx, DeviceScene& scene, CvMode mode, int iterations, std::uint32_t seed,
                          const std::function<std::vector<float>(int)>& schedule) {
    const std::size_t n = 3 * scene.pixels();
    Buffer<gpu::CvState> state(ctx, "cv state", std::vector<gpu::CvState>(n, gpu::cv_state_zero()));
    ImageLoss loss(ctx, KernelLibrary::from_environment());
    Buffer<float> ref(ctx, "ref", 1), delta(ctx, "delta", n), image(ctx, "image", n), image_old(ctx, "image (old)", n);
    Buffer<float> now(ctx, "theta_n", schedule(0)), old(ctx, "theta_n-1", schedule(0));
    for (int it = 0; it < iterations; ++it) {
        now.upload(schedule(it));
        const std::uint32_t s = primal_seed(seed, std::uint32_t(it));
        if (mode == CvMode::ps) {
            render_two_state(scene, now, old, s, 1, image, image_old);
        } else {
            render(scene, now, s, 1, image);
            render(scene, old, s, 1, image_old);
        }
        loss.evaluate_cv(LOSS_MEAN, image, image_old, state, make_cv_config(unsigned(it), CvVariance::consistent), ref, delta);
        old.copy_from(now);
    }
    std::vector<float> c;
    for (const gpu::CvState& st : state.download()) c.push_back(st.estimate);
    return c;
}

/// A closed box (twosided diffuse "walls", camera and a small ceiling light inside) where paths
/// go far past rr_depth (1) when the walls are bright: the case for two-state Russian roulette.
std::string closed_box_scene() {
    const std::string path = (std::filesystem::temp_directory_path() / "tandem-closed-box.xml").string();
    write_file_atomic(path, R"(<scene version="3.0.0">
        <integrator type="path"><integer name="max_depth" value="64"/><integer name="rr_depth" value="1"/></integrator>
        <sensor type="perspective">
            <float name="fov" value="90"/>
            <transform name="to_world"><lookat origin="0, 0, 0.5" target="0, 0, -1" up="0, 1, 0"/></transform>
            <film type="hdrfilm"><integer name="width" value="12"/><integer name="height" value="12"/></film>
        </sensor>
        <bsdf type="twosided" id="walls"><bsdf type="diffuse"><rgb name="reflectance" value="0.95"/></bsdf></bsdf>
        <shape type="cube"><ref id="walls"/></shape>
        <shape type="rectangle">
            <transform name="to_world">
                <scale value="0.3"/>
                <rotate x="1" angle="90"/>
                <translate y="0.98"/>
            </transform>
            <emitter type="area"><rgb name="radiance" value="1, 1, 1"/></emitter>
        </shape>
    </scene>)");
    return path;
}

} // namespace

TEST_SUITE("control variate") {
    TEST_CASE("the fused two-state kernel reproduces plain renders of both states bit for bit") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(test_scene("grad-delta.xml"), {{"res", "16"}}));
        DeviceScene device(*ctx, lib, scene);
        const Buffer<float> params = parameter_buffer(*ctx, scene.params);
        const std::size_t n = 3 * 16 * 16;
        Buffer<float> f(*ctx, "f", n), h(*ctx, "h", n), plain(*ctx, "plain", n);
        // same state twice: both estimates are the primal image of the same seed
        render_two_state(device, params, params, 9, 4, f, h);
        render(device, params, 9, 4, plain);
        CHECK(test::same_bytes(f.download(), plain.download()));
        CHECK(test::same_bytes(h.download(), plain.download()));
        // a darker old state (albedo, mirror and glass reflectance, sky): |beta_old| <= |beta|
        // along every path, so roulette decides as the primal does and the new estimate is still
        // the primal render of the new state; the old one differs from it
        std::vector<float> other = scene.params.values();
        for (const char* name : {"floor.reflectance", "mirror.specular_reflectance", "glass.specular_reflectance", "sky.radiance"}) {
            const Parameter& p = scene.params.find(name);
            for (std::size_t i = p.offset; i < p.offset + p.size; ++i) other[i] *= 0.7f;
        }
        Buffer<float> old(*ctx, "old", other);
        render_two_state(device, params, old, 9, 4, f, h);
        CHECK(test::same_bytes(f.download(), plain.download()));
        CHECK(!test::same_bytes(h.download(), plain.download()));
    }

    TEST_CASE("two-state paths estimate the old state without bias (against its own renders)") {
        // <F_{n-1}>_n comes from paths sampled from theta_n; its expectation must equal a plain
        // render of theta_{n-1}. Mirror, glass (delta lobes), a rough plastic and albedo change.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        for (const char* file : {"grad-delta.xml", "grad-rough.xml"}) {
            INFO(file);
            const RenderScene scene = build_render_scene(load_scene(test_scene(file), {{"res", "16"}}));
            DeviceScene device(*ctx, lib, scene);
        const Buffer<float> params = parameter_buffer(*ctx, scene.params);
            std::vector<float> other = scene.params.values();
            for (const Parameter& p : scene.params.parameters())
                for (std::size_t i = p.offset; i < p.offset + p.size; ++i)
                    other[i] = p.kind == Parameter::Kind::scalar ? std::min(1.0f, other[i] * 1.6f) : other[i] * 0.6f;
            Buffer<float> old(*ctx, "old", other);
            const std::size_t n = 3 * 16 * 16;
            Buffer<float> f(*ctx, "f", n), h(*ctx, "h", n), plain(*ctx, "plain", n);
            Stat two, direct;
            for (std::uint32_t k = 0; k < 24; ++k) {
                render_two_state(device, params, old, 100 + k, 16, f, h);
                two.add(mean_of(h.download()));
                render(device, old, 500 + k, 16, plain);
                direct.add(mean_of(plain.download()));
            }
            const double z = (two.mean() - direct.mean()) / std::sqrt(two.var() / two.n + direct.var() / direct.n);
            INFO("two-state " << two.mean() << ", plain " << direct.mean() << ", z " << z);
            CHECK(std::abs(z) < 4.0);
        }
    }

    TEST_CASE("two-state roulette on both throughputs: H stays as noisy as the old state's own render") {
        // The old walls reflect 0.95, the new 0.05, in a closed box with roulette from the first
        // bounce. Roulette decided on beta_new alone keeps a path with probability ~0.05 per
        // bounce while beta_old grows ~19x: H's second moment grows ~(0.95^2 / 0.05)^k with depth
        // k (measured: Var[H] ~21x the plain render's, and H's mean 0.05 against 0.24, the rest
        // in paths too rare to sample). Decided on max(|beta|, |beta_old|), H is distributed as
        // the plain render of the old state (~0.94x). Per pixel and channel variances across the
        // runs, summed; means against plain renders.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(closed_box_scene()));
        DeviceScene device(*ctx, lib, scene);
        const Parameter& walls = scene.params.find("walls.reflectance");
        std::vector<float> dark = scene.params.values();
        for (std::size_t i = walls.offset; i < walls.offset + walls.size; ++i) dark[i] = 0.05f;
        const Buffer<float> bright = parameter_buffer(*ctx, scene.params), now(*ctx, "theta_n", dark);
        const std::size_t n = 3 * 12 * 12;
        const int runs = 32, spp = 4;
        Buffer<float> f(*ctx, "f", n), h(*ctx, "h", n), plain_old(*ctx, "plain old", n), plain_new(*ctx, "plain new", n);
        std::vector<Stat> h_px(n), old_px(n);
        Stat h_mean, f_mean, old_mean, new_mean;
        for (int r = 0; r < runs; ++r) {
            render_two_state(device, now, bright, 300u + r, spp, f, h);
            render(device, bright, 700u + r, spp, plain_old);
            render(device, now, 900u + r, spp, plain_new);
            const std::vector<float> hv = h.download(), ov = plain_old.download();
            for (std::size_t i = 0; i < n; ++i) h_px[i].add(hv[i]), old_px[i].add(ov[i]);
            h_mean.add(mean_of(hv)), old_mean.add(mean_of(ov));
            f_mean.add(mean_of(f.download())), new_mean.add(mean_of(plain_new.download()));
        }
        double var_h = 0.0, var_old = 0.0;
        for (std::size_t i = 0; i < n; ++i) var_h += h_px[i].var(), var_old += old_px[i].var();
        auto z = [](const Stat& a, const Stat& b) {
            return (a.mean() - b.mean()) / std::sqrt(a.var() / a.n + b.var() / b.n);
        };
        MESSAGE("Var[H] / Var[plain old] " << var_h / var_old << "; H " << h_mean.mean() << " against "
                << old_mean.mean() << " (z " << z(h_mean, old_mean) << "); F " << f_mean.mean()
                << " against " << new_mean.mean() << " (z " << z(f_mean, new_mean) << ")");
        CHECK(var_h / var_old < 1.5);
        CHECK(std::abs(z(h_mean, old_mean)) < 4.0);
        CHECK(std::abs(z(f_mean, new_mean)) < 4.0);
    }

    TEST_CASE("two-state paths through media: equal states give the primal render, bit for bit") {
        // Free flights under the majorant of both states, probabilities from both throughputs:
        // with theta_{n-1} == theta_n every sum doubles exactly, so both estimates are the primal
        // render's bits (homogeneous ball, grid, and a ball between a light and a wall).
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        for (const char* file : {"grad-media.xml", "grad-media-grid.xml", "grad-media-light.xml"}) {
            INFO(file);
            const RenderScene scene = build_render_scene(load_scene(test_scene(file), {{"res", "12"}}));
            DeviceScene device(*ctx, lib, scene);
            const Buffer<float> params = parameter_buffer(*ctx, scene.params);
            const std::size_t n = 3 * 12 * 12;
            Buffer<float> f(*ctx, "f", n), h(*ctx, "h", n), plain(*ctx, "plain", n);
            render_two_state(device, params, params, 9, 4, f, h);
            render(device, params, 9, 4, plain);
            CHECK(test::same_bytes(f.download(), plain.download()));
            CHECK(test::same_bytes(h.download(), plain.download()));
        }
    }

    TEST_CASE("two-state paths through media estimate both states without bias, and H - F varies "
              "less than two independent renders") {
        // The old state is denser (sigma_t and scale x1.3: the shared majorant must bound it, not
        // the new one), paler (albedo, reflectances and radiances x0.8) and more forward (g
        // +0.15; test_media.cpp's two-state furnace changes g more). Each run's image means of F and H against plain renders of each state (z over
        // the runs); the per-pixel variance of H - F, summed, against that of the difference of
        // two independent plain renders: the correlation that the control variate lives on
        // ("Recursive Control Variates for Inverse Rendering", section 5).
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        for (const char* file : {"grad-media.xml", "grad-media-grid.xml", "grad-media-light.xml"}) {
            INFO(file);
            const RenderScene scene = build_render_scene(load_scene(test_scene(file), {{"res", "8"}}));
            DeviceScene device(*ctx, lib, scene);
            const Buffer<float> params = parameter_buffer(*ctx, scene.params);
            std::vector<float> other = scene.params.values();
            for (const Parameter& p : scene.params.parameters()) {
                const auto ends = [&](const std::string& tail) {
                    return p.name.size() > tail.size() &&
                           p.name.compare(p.name.size() - tail.size(), tail.size(), tail) == 0;
                };
                for (std::size_t i = p.offset; i < p.offset + p.size; ++i)
                    other[i] = ends(".g") ? other[i] + 0.15f
                               : ends(".sigma_t") || ends(".scale") ? other[i] * 1.3f
                                                                    : other[i] * 0.8f;
            }
            Buffer<float> old(*ctx, "old", other);
            const std::size_t n = 3 * 8 * 8;
            const int runs = 16, spp = 8;
            Buffer<float> f(*ctx, "f", n), h(*ctx, "h", n), plain_new(*ctx, "plain new", n),
                plain_old(*ctx, "plain old", n);
            Stat f_mean, h_mean, new_mean, old_mean;
            std::vector<Stat> diff_two(n), diff_plain(n);
            for (int r = 0; r < runs; ++r) {
                render_two_state(device, params, old, 100u + r, spp, f, h);
                render(device, params, 500u + r, spp, plain_new);
                render(device, old, 900u + r, spp, plain_old);
                const std::vector<float> fv = f.download(), hv = h.download(),
                                         nv = plain_new.download(), ov = plain_old.download();
                f_mean.add(mean_of(fv)), h_mean.add(mean_of(hv));
                new_mean.add(mean_of(nv)), old_mean.add(mean_of(ov));
                for (std::size_t i = 0; i < n; ++i)
                    diff_two[i].add(hv[i] - fv[i]), diff_plain[i].add(ov[i] - nv[i]);
            }
            auto z = [](const Stat& a, const Stat& b) {
                return (a.mean() - b.mean()) / std::sqrt(a.var() / a.n + b.var() / b.n);
            };
            double var_two = 0.0, var_plain = 0.0;
            for (std::size_t i = 0; i < n; ++i) var_two += diff_two[i].var(), var_plain += diff_plain[i].var();
            MESSAGE(std::string(file) << ": F " << f_mean.mean() << " against " << new_mean.mean() << " (z "
                         << z(f_mean, new_mean) << "), H " << h_mean.mean() << " against "
                         << old_mean.mean() << " (z " << z(h_mean, old_mean)
                         << "); Var[H - F] / Var[independent] " << var_two / var_plain);
            CHECK(std::abs(z(f_mean, new_mean)) < 4.0);
            CHECK(std::abs(z(h_mean, old_mean)) < 4.0);
            CHECK(var_two / var_plain < 0.5);
        }
    }

    TEST_CASE("steady state: on an unchanging scene the CV image reaches >= 0.9 (64 - 1) effective spp after 64 iterations at 1 spp") {
        // grad-texture.xml (a textured plane under a sky): Var[F] of one 1-spp image and Var[C_63]
        // of the CV image, each across 16 independent runs, summed over pixels and channels.
        // The paper's steady state predicts alpha_n -> n/(n+1), i.e. C_n the mean of all
        // iterations since the warm-up, 63 samples; the consistent variance recursion gives exactly
        // that (tests/core/inverse/test_cv_consistent.cpp; the reference form reached ~32). Relative
        // standard error of the ratio: the variances of 768 elements from 16 runs each, ~ 5 %.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(test_scene("grad-texture.xml"), {{"res", "16"}}));
        DeviceScene device(*ctx, lib, scene);
        const Buffer<float> params = parameter_buffer(*ctx, scene.params);
        const std::vector<float> theta = scene.params.values();
        const std::size_t n = 3 * 16 * 16;
        const int runs = 16;
        std::vector<Stat> f(n), c(n);
        Buffer<float> one(*ctx, "one", n);
        for (int r = 0; r < runs; ++r) {
            const std::vector<float> cv = run_cv(*ctx, device, CvMode::ps, 64, 1000u + r,
                                                 [&](int) { return theta; });
            render(device, params, primal_seed(77u, r), 1, one);
            const std::vector<float> img = one.download();
            for (std::size_t i = 0; i < n; ++i) c[i].add(cv[i]), f[i].add(img[i]);
        }
        double var_f = 0.0, var_c = 0.0;
        for (std::size_t i = 0; i < n; ++i) var_f += f[i].var(), var_c += c[i].var();
        const double effective = var_f / var_c;
        MESSAGE("effective spp after 64 static iterations: " << effective);
        CHECK(effective >= 0.9 * 63.0);
        CHECK(effective <= 64.0 * 1.3); // no more than the mean of all iterations (+ noise)
    }

    TEST_CASE("CV-PS and CV-PSS agree in expectation, and both are unbiased on a static and a "
              "moving scene") {
        // Unbiased on a moving scene: each run's CV estimate of the last state, C_{N-1}, against
        // a reference render of that state (64 chunks of 1024 spp with independent seeds, whose
        // spread gives the reference's own standard error, included in z; the scene's glossy
        // highlights make single pixels heavy-tailed, and with 16 x 256 spp the reference's mean
        // sat 2 % low, 4 of its own standard errors). The weight alpha_n
        // comes from statistics lagged by one iteration (cv.h), so it never sees the noise of
        // the samples it weights: a bias would come from a wrong recursion or from the two
        // states not sharing their paths.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(test_scene("grad-rough.xml"), {{"res", "12"}}));
        DeviceScene device(*ctx, lib, scene);
        const std::vector<float> theta = scene.params.values();
        const Parameter& wall = scene.params.find("wall.reflectance");
        const Parameter& alpha = scene.params.find("plastic.alpha");
        // an optimization-like trajectory: the wall darkens and the plastic roughens each step
        auto moving = [&](int it) {
            std::vector<float> v = theta;
            for (std::size_t i = wall.offset; i < wall.offset + 3; ++i) v[i] *= 1.0f - 0.01f * it;
            v[alpha.offset] += 0.004f * it;
            return v;
        };
        const int iterations = 24, runs = 96;
        Stat ps, pss, ps_static, pss_static;
        for (int r = 0; r < runs; ++r) {
            ps.add(mean_of(run_cv(*ctx, device, CvMode::ps, iterations, 10u + r, moving)));
            pss.add(mean_of(run_cv(*ctx, device, CvMode::pss, iterations, 10u + r, moving)));
            ps_static.add(mean_of(run_cv(*ctx, device, CvMode::ps, iterations, 50u + r, [&](int) { return theta; })));
            pss_static.add(mean_of(run_cv(*ctx, device, CvMode::pss, iterations, 90u + r, [&](int) { return theta; })));
        }
        auto z = [](const Stat& a, const Stat& b) {
            return (a.mean() - b.mean()) / std::sqrt(a.var() / a.n + b.var() / b.n);
        };
        INFO("moving: PS " << ps.mean() << ", PSS " << pss.mean());
        CHECK(std::abs(z(ps, pss)) < 4.0);
        // the reference of a state: its image mean from 64 x 1024 spp, with its standard error
        auto reference = [&](const std::vector<float>& state) {
            Buffer<float> values(*ctx, "reference params", state),
                rgb(*ctx, "reference", 3 * 12 * 12);
            Stat chunks;
            for (int k = 0; k < 64; ++k) {
                render(device, values, 4242u + std::uint32_t(k), 1024, rgb);
                chunks.add(mean_of(rgb.download()));
            }
            return chunks;
        };
        const Stat last = reference(moving(iterations - 1));
        for (const Stat* s : {&ps, &pss}) {
            const double zs =
                (s->mean() - last.mean()) / std::sqrt(s->var() / s->n + last.var() / last.n);
            INFO("moving " << s->mean() << " against " << last.mean() << " of the last state, z "
                           << zs);
            CHECK(std::abs(zs) < 4.0);
        }
        // static: against the reference of the unchanged scene
        const Stat truth = reference(theta);
        for (const Stat* s : {&ps_static, &pss_static}) {
            const double zs =
                (s->mean() - truth.mean()) / std::sqrt(s->var() / s->n + truth.var() / truth.n);
            INFO("static " << s->mean() << " against " << truth.mean() << ", z " << zs);
            CHECK(std::abs(zs) < 4.0);
        }
    }

    TEST_CASE("CV iterations are bit-identical run to run") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(load_scene(test_scene("grad-delta.xml"), {{"res", "12"}}));
        DeviceScene device(*ctx, lib, scene);
        const Buffer<float> params = parameter_buffer(*ctx, scene.params);
        const std::vector<float> theta = scene.params.values();
        auto moving = [&](int it) {
            std::vector<float> v = theta;
            v[0] *= 1.0f - 0.02f * it;
            return v;
        };
        const std::vector<float> a = run_cv(*ctx, device, CvMode::ps, 8, 5, moving);
        const std::vector<float> b = run_cv(*ctx, device, CvMode::ps, 8, 5, moving);
        const std::vector<float> c = run_cv(*ctx, device, CvMode::ps, 8, 6, moving);
        CHECK(test::same_bytes(a, b));
        CHECK(!test::same_bytes(a, c));
    }
}
