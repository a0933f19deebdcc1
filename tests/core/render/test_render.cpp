// Path tracer against closed forms: white furnace, a diffuse plane under a constant environment,
// a closed emissive sphere at several depths; and bitwise determinism. Scenes are built in code
// so these tests do not depend on the XML loader.
//
// Tolerances: each test averages M pixel values (each the mean of spp samples) and requires the
// mean within 5 standard errors of the expectation, the standard error measured from the pixel
// values themselves (a false alarm once in ~1.7 million runs for Gaussian errors), plus 1e-5 for
// float rounding.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/render/features.h"
#include "core/render/passes.h"
#include "core/render/wavefront.h"
#include "runtime/error.h"
#include "support.h"

using namespace tandem;

namespace {

Camera make_camera(glm::vec3 origin, glm::vec3 target, glm::vec3 up, float fov, int w, int h) {
    Camera c;
    c.to_world = look_at(origin, target, up);
    c.fov = fov;
    c.width = w;
    c.height = h;
    return c;
}

struct Stats {
    double mean = 0, std_error = 0;
    std::size_t n = 0;
};

/// Mean and standard error of channel `k` over the pixels selected by `use`.
template <class F> Stats pixel_stats(const RenderResult& r, int k, F use) {
    double sum = 0, sum2 = 0;
    std::size_t n = 0;
    for (int y = 0; y < r.height; ++y)
        for (int x = 0; x < r.width; ++x) {
            if (!use(x, y)) continue;
            const double v = r.rgb[3 * (std::size_t(y) * r.width + x) + k];
            sum += v;
            sum2 += v * v;
            ++n;
        }
    Stats s;
    s.n = n;
    s.mean = sum / double(n);
    s.std_error = std::sqrt(std::max(0.0, sum2 / double(n) - s.mean * s.mean) / double(n));
    return s;
}

void check_close(const Stats& s, double expected, const char* what) {
    INFO(what << ": mean " << s.mean << " over " << s.n << " pixels, standard error "
              << s.std_error << ", expected " << expected);
    CHECK(s.n > 100);
    CHECK(std::fabs(s.mean - expected) <= 5.0 * s.std_error + 1e-5);
}

RenderResult render(const SceneDesc& desc, int spp, unsigned seed = 1,
                    LightStrategy strategy = LightStrategy::mis, int bvh_width = 0,
                    int force_env = -1, bool all_code = false) {
    tandem::Context* ctx = test::device_context();
    const RenderScene scene = build_render_scene(desc);
    BuildFlags features = render_features(scene, *ctx, strategy, bvh_width);
    if (force_env >= 0) features.set("HAS_ENV_LIGHT", force_env);
    if (all_code) // every optional family compiled in, whether the scene uses it or not
        for (const char* flag : {"BSDF_CONDUCTOR", "BSDF_DIELECTRIC", "BSDF_PLASTIC", "HAS_TEXTURES",
                                 "HAS_BITMAPS", "HAS_DELTA_LIGHTS", "BVH_ANALYTIC"})
            features.set(flag, 1);
    DeviceScene device(*ctx, KernelLibrary::from_environment(), scene, features);
    RenderOptions opt;
    opt.spp = spp;
    opt.seed = seed;
    return render_image(device, parameter_buffer(*ctx, scene.params), opt);
}

/// Mean and standard error over pixels of a - b: both images estimate the same per-pixel
/// expectation, so the differences are independent zero-mean noise if the estimators agree.
Stats difference_stats(const RenderResult& a, const RenderResult& b) {
    double sum = 0, sum2 = 0;
    const std::size_t n = a.rgb.size();
    for (std::size_t i = 0; i < n; ++i) {
        const double d = double(a.rgb[i]) - b.rgb[i];
        sum += d;
        sum2 += d * d;
    }
    Stats s;
    s.n = n;
    s.mean = sum / double(n);
    s.std_error = std::sqrt(std::max(0.0, sum2 / double(n) - s.mean * s.mean) / double(n));
    return s;
}

SceneDesc cbox(int res, int max_depth) {
    SceneDesc d = load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox.xml");
    d.camera().width = d.camera().height = res;
    d.integrator.max_depth = max_depth;
    return d;
}

Emitter constant_env(float radiance) {
    Emitter e;
    e.id = "env";
    e.type = EmitterType::constant;
    e.radiance = glm::vec3(radiance);
    return e;
}

Bsdf diffuse(float albedo, bool twosided = false) {
    Bsdf b;
    b.id = "white";
    b.type = BsdfType::diffuse;
    b.reflectance.value = glm::vec3(albedo);
    b.twosided = twosided;
    return b;
}

/// The low-resolution knot (two-sided diffuse `albedo`) under a constant environment of 1.
SceneDesc knot_under_env(const char* name, float albedo, int w, int h) {
    SceneDesc d;
    d.path = name;
    d.camera() = make_camera({0, -5, 2}, {0, 0, 0}, {0, 0, 1}, 40.0f, w, h);
    d.bsdfs.push_back(diffuse(albedo, /*twosided=*/true));
    d.emitters.push_back(constant_env(1.0f));
    Shape s;
    s.type = ShapeType::ply;
    s.filename = test::mesh_path("knot_ascii.ply");
    s.bsdf = 0;
    d.shapes.push_back(s);
    return d;
}

/// The wavefront renderer against the megakernels (render_pass, render_two_state) on the scene
/// built from d, or `built` where given (d then names it): the same image bits and guard counts.
/// Returns the wavefront's render.
RenderResult wavefront_against_megakernels(Context* ctx, const SceneDesc& d, int spp, unsigned seed,
                                           const RenderScene* built = nullptr) {
    const RenderScene scene = built ? *built : build_render_scene(d);
    BuildFlags f = render_features(scene, *ctx);
    REQUIRE(wavefront_supported(f));
    if (!ctx->tuning().wavefront) // the default: where PoCL vectorises it, on large films
        CHECK(f.get("WAVEFRONT") ==
              (wavefront_faster(f, ctx->device(), std::size_t(scene.camera().width) *
                                                      scene.camera().height)
                   ? 1
                   : 0));
    RenderResult r[2];
    for (int wavefront : {0, 1}) {
        f.set("WAVEFRONT", wavefront);
        DeviceScene device(*ctx, KernelLibrary::from_environment(), scene, f);
        RenderOptions opt;
        opt.spp = spp;
        opt.seed = seed;
        r[wavefront] = render_image(device, parameter_buffer(*ctx, scene.params), opt);
    }
    INFO(d.path << ", max_depth " << d.integrator.max_depth);
    CHECK(test::same_bytes(r[0].rgb, r[1].rgb));
    CHECK(r[0].nan_guards == r[1].nan_guards);
    // the two-state render (CV-PS), with a previous state whose every parameter differs
    std::vector<float> old_values = scene.params.values();
    for (float& v : old_values)
        v *= 0.7f;
    std::vector<float> two[2][2];
    for (int wavefront : {0, 1}) {
        f.set("WAVEFRONT", wavefront);
        DeviceScene device(*ctx, KernelLibrary::from_environment(), scene, f);
        const Buffer<float> params = parameter_buffer(*ctx, scene.params);
        Buffer<float> params_old(*ctx, "old parameters", old_values);
        Buffer<float> rgb(*ctx, "rgb", 3 * device.pixels()),
            rgb_old(*ctx, "rgb old", 3 * device.pixels());
        render_two_state(device, params, params_old, seed, spp, rgb, rgb_old);
        two[wavefront][0] = rgb.download();
        two[wavefront][1] = rgb_old.download();
    }
    CHECK(test::same_bytes(two[0][0], two[1][0]));
    CHECK(test::same_bytes(two[0][1], two[1][1]));
    // |beta_old| <= |beta| all along (0.7x), so the new state's radiance is the primal's
    // bit for bit (path/two_state.h), and the old state's image differs
    CHECK(test::same_bytes(two[1][0], r[1].rgb));
    if (d.integrator.max_depth != 0) CHECK(!test::same_bytes(two[1][1], r[1].rgb));
    return r[1];
}

} // namespace

TEST_CASE("forward renders: GPUs take the eight-wide tree of records for triangles only, and "
          "the Tuning's BVH width overrides") {
    const std::string dir = std::string(TANDEM_SOURCE_DIR) + "/scenes/";
    const RenderScene triangles = build_render_scene(load_scene(dir + "cbox.xml", {{"res", "8"}}));
    const RenderScene spheres =
        build_render_scene(load_scene(dir + "three-spheres.xml", {{"res", "8"}}));
    DeviceInfo gpu;
    gpu.type = "GPU";
    DeviceInfo cpu;
    cpu.type = "CPU";
    cpu.native_float_width = 8;
    BuildFlags f = forward_render_features(triangles, gpu);
    CHECK(f.get("BVH_WIDTH") == 8);
    CHECK(f.get("BVH_TRI4") == 0);
    CHECK(render_features(triangles, gpu).get("BVH_WIDTH") == 2); // gradient work
    CHECK(forward_render_features(spheres, gpu).get("BVH_WIDTH") == 2);
    f = forward_render_features(triangles, cpu);
    CHECK(f.get("BVH_WIDTH") == 8);
    CHECK(f.get("BVH_TRI4") == 1);
    Tuning two;
    two.bvh_width = 2;
    CHECK(forward_render_features(triangles, gpu, two).get("BVH_WIDTH") == 2);
    // a caller's own width comes before the Tuning's
    CHECK(render_features(triangles, cpu, two, LightStrategy::mis, 4).get("BVH_WIDTH") == 4);
    // the environment's values are checked where it is read, whatever the tree
    {
        const test::ScopedEnv width("TANDEM_BVH_WIDTH", "4");
        CHECK(tuning_from_environment().bvh_width == 4);
    }
    {
        const test::ScopedEnv leaves("TANDEM_BVH_LEAVES", "records");
        CHECK(tuning_from_environment().bvh_tri4_leaves == std::optional<bool>(false));
    }
    const test::ScopedEnv leaves("TANDEM_BVH_LEAVES", "blocks");
    CHECK_THROWS_WITH_AS(
        tuning_from_environment(),
        doctest::Contains("TANDEM_BVH_LEAVES='blocks': expected the BVH leaf format records or tri4"),
        Error);
}

TEST_CASE("BVH_PREFETCH: CPUs prefetch in eight-wide trees of scenes of 16,384 triangles or more") {
    const std::string dir = std::string(TANDEM_SOURCE_DIR) + "/scenes/";
    const RenderScene small = build_render_scene(load_scene(dir + "cbox.xml", {{"res", "8"}}));
    // cbox with the tall box replaced by the 131,072-triangle knot
    const RenderScene large = build_render_scene(
        load_scene(std::string(TANDEM_SOURCE_DIR) + "/tests/core/render/cbox-knot.xml",
                   {{"res", "8"}, {"knot", test::mesh_path("knot.ply")}}));
    REQUIRE(large.mesh.triangle_count() >= k_prefetch_min_triangles);
    DeviceInfo cpu;
    cpu.type = "CPU";
    cpu.native_float_width = 8;
    DeviceInfo gpu;
    gpu.type = "GPU";
    CHECK(render_features(large, cpu).get("BVH_PREFETCH") == 1);
    CHECK(forward_render_features(large, cpu).get("BVH_PREFETCH") == 1);
    CHECK(render_features(small, cpu).get("BVH_PREFETCH") == 0);
    CHECK(forward_render_features(large, gpu).get("BVH_PREFETCH") == 0);
    cpu.native_float_width = 4; // a four-wide tree
    CHECK(render_features(large, cpu).get("BVH_PREFETCH") == 0);
    Tuning off;
    off.bvh_prefetch = false;
    cpu.native_float_width = 8;
    CHECK(render_features(large, cpu, off).get("BVH_PREFETCH") == 0);
}

TEST_CASE("the wavefront on PoCL with AVX-512 for diffuse scenes and films of "
          "k_wavefront_min_pixels or more: the Tuning forces it either way where it covers the "
          "scene") {
    const std::string dir = std::string(TANDEM_SOURCE_DIR) + "/scenes/";
    auto cbox = [&](int res) {
        return build_render_scene(load_scene(dir + "cbox.xml", {{"res", std::to_string(res)}}));
    };
    DeviceInfo avx512;
    avx512.platform = "Portable Computing Language";
    avx512.type = "CPU";
    avx512.name = "pthread-skylake-avx512";
    avx512.native_float_width = 16;
    DeviceInfo avx2 = avx512;
    avx2.name = "pthread-haswell";
    avx2.native_float_width = 8;
    CHECK(k_wavefront_min_pixels == 256 * 256);
    // the film decides: one sample of every pixel is a wave, whose launches small films do not repay
    CHECK(render_features(cbox(64), avx512).get("WAVEFRONT") == 0);
    CHECK(render_features(cbox(255), avx512).get("WAVEFRONT") == 0);
    CHECK(render_features(cbox(256), avx512).get("WAVEFRONT") == 1);
    CHECK(render_features(cbox(512), avx512).get("WAVEFRONT") == 1);
    CHECK(forward_render_features(cbox(512), avx512).get("WAVEFRONT") == 1);
    CHECK(render_features(cbox(512), avx2).get("WAVEFRONT") == 0);
    // other materials than diffuse: the megakernels at every size
    const RenderScene spheres = build_render_scene(
        load_scene(dir + "three-spheres.xml", {{"res", "512"}}));
    CHECK(render_features(spheres, avx512).get("WAVEFRONT") == 0);
    // forced
    Tuning on, off;
    on.wavefront = true;
    off.wavefront = false;
    CHECK(render_features(cbox(8), avx2, on).get("WAVEFRONT") == 1);
    CHECK(render_features(cbox(512), avx512, off).get("WAVEFRONT") == 0);
    // the policy a device scene keeps follows its flags, where the wavefront covers them
    BuildFlags f = render_features(cbox(8), avx2, on);
    CHECK(policy_of(f, Tuning{}).wavefront);
    f.set("LIGHT_STRATEGY", static_cast<int>(LightStrategy::nee_only));
    CHECK(!policy_of(f, Tuning{}).wavefront);
}

TEST_SUITE("device") {
    TEST_CASE("white furnace: an albedo-1 sphere under a constant environment is invisible") {
        TANDEM_REQUIRE_DEVICE(ctx);
        for (int depth : {2, 3, 5, -1}) {
            SceneDesc d;
            d.path = "furnace";
            d.integrator.max_depth = depth;
            d.camera() = make_camera({0, 0, 4}, {0, 0, 0}, {0, 1, 0}, 30.0f, 48, 48);
            d.bsdfs.push_back(diffuse(1.0f));
            d.emitters.push_back(constant_env(1.0f));
            Shape s;
            s.type = ShapeType::sphere;
            s.bsdf = 0;
            d.shapes.push_back(s);
            const RenderResult r = render(d, 64);
            CHECK(r.nan_guards == 0);
            INFO("max_depth " << depth);
            for (int k = 0; k < 3; ++k)
                check_close(pixel_stats(r, k, [](int, int) { return true; }), 1.0, "all pixels");
            // The control: the camera does see the sphere, which at albedo 0.5 darkens the image.
            d.bsdfs[0] = diffuse(0.5f);
            const Stats dark = pixel_stats(render(d, 16), 1, [](int, int) { return true; });
            CHECK(dark.mean < 0.9);
        }
    }

    TEST_CASE("white furnace: the non-convex knot with albedo 1 and unbounded depth gives 1") {
        TANDEM_REQUIRE_DEVICE(ctx);
        SceneDesc d = knot_under_env("furnace-knot", 1.0f, 48, 48);
        // The furnace identity holds for the geometric normals. Interpolated shading normals
        // break it (Veach 1997, Robust Monte Carlo Methods for Light Transport Simulation,
        // §5.3: the adjoint BSDF is no longer the BSDF and energy is not conserved); the knot's
        // file has no normals, so without face_normals it is shaded with derived ones and
        // measured 0.9974 +- 0.0005 here.
        d.shapes[0].face_normals = true;
        const RenderResult r = render(d, 64);
        check_close(pixel_stats(r, 1, [](int, int) { return true; }), 1.0, "all pixels");
        // And with a finite depth, interreflections are cut off: the mean falls below 1.
        d.integrator.max_depth = 2;
        const RenderResult cut = render(d, 64);
        const Stats s2 = pixel_stats(cut, 1, [](int, int) { return true; });
        CHECK(s2.mean < 1.0 - 5.0 * s2.std_error);
    }

    TEST_CASE("a diffuse plane under a constant environment shows its albedo") {
        TANDEM_REQUIRE_DEVICE(ctx);
        for (float albedo : {0.2f, 0.75f}) {
            SceneDesc d;
            d.path = "plane";
            d.camera() = make_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 30.0f, 32, 32);
            d.bsdfs.push_back(diffuse(albedo));
            d.emitters.push_back(constant_env(2.0f));
            Shape s;
            s.type = ShapeType::rectangle; // [-1,1]^2, normal +z, fills the whole view
            s.to_world = glm::mat4(4.0f);
            s.to_world[3][3] = 1.0f;
            s.bsdf = 0;
            d.shapes.push_back(s);
            const RenderResult r = render(d, 32);
            INFO("albedo " << albedo);
            check_close(pixel_stats(r, 0, [](int, int) { return true; }), 2.0 * albedo, "plane");
        }
    }

    TEST_CASE("shapes without a bsdf: diffuse 0.5, black on an area emitter (Mitsuba)") {
        // Two halves of the plane [-1,1]^2 under a constant environment of 1, seen from above
        // (film x in [0, 1/2) sees world x < 0): on the left an area emitter of radiance 0.25
        // with no bsdf, on the right a shape with neither. Mitsuba gives the emitter a black
        // diffuse: its pixels show exactly 0.25, every sample, and nothing the environment
        // throws at it (with diffuse 0.5 they would show 0.25 + 0.5). The plain half shows
        // 0.5 x 1 in expectation.
        TANDEM_REQUIRE_DEVICE(ctx);
        const int res = 32;
        SceneDesc d;
        d.path = "no-bsdf";
        d.camera() = make_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0},
                               2.0f * std::atan(1.0f / 3.0f) * 180.0f / 3.14159265f, res, res);
        d.emitters.push_back(constant_env(1.0f));
        Emitter area;
        area.type = EmitterType::area;
        area.radiance = glm::vec3(0.25f);
        d.emitters.push_back(area);
        for (int side : {-1, 1}) {
            Shape s;
            s.type = ShapeType::rectangle; // [-1,1]^2, normal +z: this half, facing the camera
            s.to_world = glm::mat4(1.0f);
            s.to_world[0][0] = 0.5f;
            s.to_world[3][0] = 0.5f * float(side);
            s.emitter = side < 0 ? 1 : -1;
            d.shapes.push_back(s);
        }
        const RenderResult r = render(d, 16);
        CHECK(r.nan_guards == 0);
        std::size_t exact = 0, left = 0;
        for (int y = 1; y < res - 1; ++y)
            for (int x = 1; x < res / 2 - 1; ++x) {
                const float* c = &r.rgb[3 * (std::size_t(y) * res + x)];
                exact += c[0] == 0.25f && c[1] == 0.25f && c[2] == 0.25f;
                ++left;
            }
        CHECK(exact == left);
        auto plain = [](int x, int y) {
            return x > res / 2 && x < res - 1 && y > 0 && y < res - 1;
        };
        for (int k = 0; k < 3; ++k)
            check_close(pixel_stats(r, k, plain), 0.5, "the shape with neither");
    }

    TEST_CASE("inside a closed emissive diffuse sphere, radiance sums a geometric series by depth") {
        // Every point sees only the sphere, so a path of d segments gathers
        // Le (1 + rho + ... + rho^(d-1)) = Le (1 - rho^d) / (1 - rho), with Russian roulette from
        // the default depth (5) or from the first bounce (1): it changes the noise, not the mean.
        TANDEM_REQUIRE_DEVICE(ctx);
        const float rho = 0.5f, Le = 1.5f;
        for (const auto& [depth, rr_depth] : std::vector<std::pair<int, int>>{
                 {1, 5}, {2, 5}, {3, 5}, {6, 5}, {-1, 5}, {3, 1}, {6, 1}, {-1, 1}}) {
            SceneDesc d;
            d.path = "emissive-sphere";
            d.integrator.max_depth = depth;
            d.integrator.rr_depth = rr_depth;
            d.camera() = make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 60.0f, 32, 32);
            d.bsdfs.push_back(diffuse(rho));
            Emitter e;
            e.type = EmitterType::area;
            e.radiance = glm::vec3(Le);
            d.emitters.push_back(e);
            Shape s;
            s.type = ShapeType::sphere;
            s.flip_normals = true; // normals inward: it emits and reflects toward the centre
            s.bsdf = 0;
            s.emitter = 0;
            d.shapes.push_back(s);
            const RenderResult r = render(d, 32);
            const double expected =
                depth < 0 ? Le / (1.0 - rho) : Le * (1.0 - std::pow(rho, depth)) / (1.0 - rho);
            INFO("max_depth " << depth << ", rr_depth " << rr_depth);
            check_close(pixel_stats(r, 2, [](int, int) { return true; }), expected, "sphere");
        }
    }

    TEST_CASE("NEE only, BSDF sampling only and MIS estimate the same image") {
        // The Cornell box with its small light, and the knot under a constant environment.
        TANDEM_REQUIRE_DEVICE(ctx);
        SceneDesc env = knot_under_env("env-knot", 0.6f, 32, 32);
        env.integrator.max_depth = 4;
        for (const SceneDesc& d : {cbox(32, 4), env}) {
            INFO(d.path);
            const RenderResult mis = render(d, 256, 3, LightStrategy::mis);
            const RenderResult bsdf = render(d, 256, 4, LightStrategy::bsdf_only);
            const RenderResult nee = render(d, 256, 5, LightStrategy::nee_only);
            for (const RenderResult* other : {&bsdf, &nee}) {
                const Stats diff = difference_stats(mis, *other);
                INFO("mean difference " << diff.mean << ", standard error " << diff.std_error);
                CHECK(std::fabs(diff.mean) <= 5.0 * diff.std_error + 1e-6);
            }
            // With a small light, BSDF sampling alone rarely finds it: MIS must be much less
            // noisy (the difference of two MIS renders with other seeds measures its noise).
            // Under the uniform environment cosine sampling is already near-optimal, and no
            // ordering is guaranteed there.
            if (d.path != "env-knot") {
                const RenderResult mis2 = render(d, 256, 6, LightStrategy::mis);
                const double se_mis = difference_stats(mis, mis2).std_error / std::sqrt(2.0);
                const double se_mb = difference_stats(mis, bsdf).std_error;
                const double se_bsdf = std::sqrt(std::max(0.0, se_mb * se_mb - se_mis * se_mis));
                INFO("standard error of the mean pixel: MIS " << se_mis << ", BSDF only " << se_bsdf);
                CHECK(se_bsdf > 1.5 * se_mis);
            }
        }
    }

    TEST_CASE("feature flags: what a scene does not use leaves its image unchanged, bit for bit") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const SceneDesc d = cbox(24, 5);
        const RenderResult base = render(d, 4, 9, LightStrategy::mis, 4, 0);
        // The environment code compiled in (but the scene has no environment).
        CHECK(test::same_bytes(base.rgb, render(d, 4, 9, LightStrategy::mis, 4, 1).rgb));
        // The diffuse-only scene compiles without conductor, dielectric, plastic, texture,
        // point-light and analytic-shape code; compiling all of it in changes nothing.
        const RenderScene plain = build_render_scene(d);
        const BuildFlags lean = render_features(plain, *ctx);
        for (const char* flag : {"BSDF_CONDUCTOR", "BSDF_DIELECTRIC", "BSDF_PLASTIC", "HAS_TEXTURES",
                                 "HAS_BITMAPS", "HAS_DELTA_LIGHTS", "BVH_ANALYTIC"})
            CHECK(lean.get(flag) == 0);
        CHECK(test::same_bytes(base.rgb, render(d, 4, 9, LightStrategy::mis, 4, 0, true).rgb));
        // The other BVH layouts: traversal reports the same hits (ties included).
        CHECK(test::same_bytes(base.rgb, render(d, 4, 9, LightStrategy::mis, 2, 0).rgb));
        CHECK(test::same_bytes(base.rgb, render(d, 4, 9, LightStrategy::mis, 8, 0).rgb));
        // Leaves of four-triangle blocks (BVH_TRI4; on CPUs for every eight-wide tree, but for a
        // four-wide one only for meshes of 1,024 triangles or more, so forced here for both): the
        // same hits, so the same image.
        CHECK(render_features(plain, *ctx, LightStrategy::mis, 4).get("BVH_TRI4") == 0);
        if (ctx->device().type == "CPU")
            CHECK(render_features(plain, *ctx, LightStrategy::mis, 8).get("BVH_TRI4") ==
                  1);
        // `plain` rendered as `base` was, with `flags` (the environment left out, as in `base`).
        auto render_with = [&](BuildFlags flags) {
            flags.set("HAS_ENV_LIGHT", 0);
            DeviceScene device(*ctx, KernelLibrary::from_environment(), plain, flags);
            RenderOptions opt;
            opt.spp = 4;
            opt.seed = 9;
            return render_image(device, parameter_buffer(*ctx, plain.params), opt).rgb;
        };
        // The eight-wide tree with records as well (a CPU's default for it is blocks), with its
        // prefetches (BVH_PREFETCH; on CPUs for large meshes only, so forced here), and with the
        // camera rays traced in packets (CAMERA_PACKETS: blocks only; the CPUs' default there).
        for (const auto& [width, tri4, prefetch, packets] :
             {std::tuple{4, 1, 0, 0}, std::tuple{8, 1, 0, 0}, std::tuple{8, 1, 0, 1},
              std::tuple{8, 0, 0, 0}, std::tuple{8, 1, 1, 1}, std::tuple{8, 0, 1, 0}}) {
            INFO("BVH" << width << (tri4 ? " of blocks" : " of records")
                       << (prefetch ? ", prefetching" : "") << (packets ? ", camera packets" : ""));
            BuildFlags flags = render_features(plain, *ctx, LightStrategy::mis, width);
            flags.set("BVH_TRI4", tri4);
            flags.set("BVH_PREFETCH", prefetch);
            flags.set("CAMERA_PACKETS", packets);
            CHECK(test::same_bytes(base.rgb, render_with(flags)));
        }
        // The other form of the triangle test's leaf loops (BVH_AXIS_LOOPS), every layout.
        for (const int width : {2, 4, 8}) {
            BuildFlags other = render_features(plain, *ctx, LightStrategy::mis, width);
            other.set("BVH_AXIS_LOOPS", 1 - other.get("BVH_AXIS_LOOPS"));
            other.set("CAMERA_PACKETS", 0); // (it needs the tree of blocks; its own case above)
            CHECK(test::same_bytes(base.rgb, render_with(other)));
        }
        // A flag the scene needs cannot be turned off.
        const RenderScene scene = build_render_scene(d);
        BuildFlags no_lights = render_features(scene, *ctx);
        no_lights.set("HAS_AREA_LIGHTS", 0);
        CHECK_THROWS_AS(DeviceScene(*ctx, KernelLibrary::from_environment(), scene, no_lights), Error);
        // A flag missing from the options fails the kernel build, naming the check.
        BuildFlags missing;
        missing.set("BVH_WIDTH", 4);
        CHECK_THROWS_WITH_AS(Program::build(*ctx, KernelLibrary::from_environment(), "render.cl",
                                            missing.options()),
                             doctest::Contains("must be passed"), Error);
    }

    TEST_CASE("the wavefront renderer gives render_pass's images bit for bit") {
        // kernels/wavefront.cl repeats the megakernel's arithmetic stage by stage, in scalars; any
        // difference of operation or order shows as a differing bit somewhere in these images.
        TANDEM_REQUIRE_DEVICE(ctx);
        auto both = [&](const SceneDesc& d, int spp, unsigned seed) {
            return wavefront_against_megakernels(ctx, d, spp, seed);
        };
        // depth 0 (black), 1 (emitters only), 2 (direct light), 12 (past roulette's start, where
        // most paths have ended and the live list is short), and unbounded (roulette ends every
        // path; an empty live list ends the wave)
        for (int depth : {0, 1, 2, 12, -1}) {
            const RenderResult r = both(cbox(24, depth), 3, 5);
            float peak = 0.0f;
            for (float v : r.rgb) peak = std::max(peak, v);
            CHECK((depth == 0) == (peak == 0.0f));
        }
        // textures (the wavefront's own bilinear and nearest lookups and checkerboard)
        SceneDesc wall = load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox-wall.xml");
        wall.camera().width = wall.camera().height = 24;
        REQUIRE(wall.textures.size() == 1);
        both(wall, 3, 5);
        wall.textures[0].filter_type = "nearest";
        both(wall, 3, 5);
        wall.textures[0].kind = Texture::Kind::checkerboard;
        wall.textures[0].to_uv = glm::mat3(7.0f, 0.0f, 0.0f, 0.0f, 5.0f, 0.0f, 0.25f, 0.5f, 1.0f);
        both(wall, 3, 5);
        // seen from inside a sphere whose normals point out: a twosided bsdf flips every frame
        SceneDesc sphere;
        sphere.path = "inside-twosided";
        sphere.camera() = make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 60.0f, 16, 16);
        sphere.bsdfs.push_back(diffuse(0.6f, /*twosided=*/true));
        Emitter e;
        e.type = EmitterType::area;
        e.radiance = glm::vec3(0.7f, 1.1f, 2.0f);
        sphere.emitters.push_back(e);
        Shape lamp, ball;
        lamp.type = ShapeType::rectangle;
        lamp.to_world = glm::mat4(0.3f);
        lamp.to_world[3] = glm::vec4(0.0f, 0.0f, 0.8f, 1.0f);
        lamp.emitter = 0;
        ball.type = ShapeType::sphere;
        ball.bsdf = 0;
        sphere.shapes = {lamp, ball};
        both(sphere, 4, 11);
        // what the wavefront does not cover renders with the megakernel: point and spot lights
        const RenderScene spots = build_render_scene(
            load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/gallery-lights.xml", {{"res", "8"}}));
        CHECK(!wavefront_supported(render_features(spots, *ctx)));
        CHECK(render_features(spots, *ctx).get("WAVEFRONT") == 0);
    }

    TEST_CASE("the wavefront renderer gives render_pass's images bit for bit: environments and other materials") {
        TANDEM_REQUIRE_DEVICE(ctx);
        auto both = [&](const SceneDesc& d, int spp, unsigned seed) {
            return wavefront_against_megakernels(ctx, d, spp, seed);
        };
        // environments: a constant one (a parameter: the two-state render's old state differs);
        // an importance-sampled map alone (env-probe: NEE always picks it); a map rotated, with an
        // area light beside it (NEE picks either, half and half)
        for (int depth : {2, -1}) {
            SceneDesc knot = knot_under_env("env", 0.5f, 20, 16);
            knot.integrator.max_depth = depth;
            both(knot, 3, 5);
        }
        SceneDesc probe = load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/env-probe.xml",
                                     {{"res", "24"}});
        REQUIRE(probe.emitters.size() == 1);
        REQUIRE(probe.emitters[0].type == EmitterType::envmap);
        both(probe, 3, 5);
        probe.emitters[0].to_world =
            glm::rotate(glm::mat4(1.0f), 0.7f, glm::normalize(glm::vec3(0.3f, 1.0f, -0.2f)));
        Emitter panel;
        panel.type = EmitterType::area;
        panel.radiance = glm::vec3(4.0f, 3.0f, 2.0f);
        probe.emitters.push_back(panel);
        Shape lamp_panel;
        lamp_panel.type = ShapeType::rectangle;
        lamp_panel.to_world = glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 2.5f, 0.0f)) *
                              glm::rotate(glm::mat4(1.0f), 1.5707964f, glm::vec3(1.0f, 0.0f, 0.0f)) *
                              glm::scale(glm::mat4(1.0f), glm::vec3(0.5f));
        lamp_panel.emitter = 1;
        probe.shapes.push_back(lamp_panel);
        // a map that varies in azimuth and across its seam (the sky is one column repeated, bar
        // the sun): 16 x 9 random texels, rotated, every lookup and search step distinct
        {
            probe.integrator.max_depth = 4;
            RenderScene noisy = build_render_scene(probe);
            REQUIRE(!noisy.emissive.empty());
            const int w = 16, h = 9;
            std::vector<float> rgb(std::size_t(w) * h * 3);
            std::mt19937 random(17);
            std::uniform_real_distribution<float> radiance(0.05f, 3.0f);
            for (float& v : rgb) v = radiance(random);
            build_envmap(rgb, w, h, probe.emitters[0].to_world, noisy);
            REQUIRE(render_features(noisy, *ctx).get("ENVMAP_SEARCH_STEPS") == 4);
            wavefront_against_megakernels(ctx, probe, 4, 9, &noisy);
        }
        // materials other than diffuse (wf_shade_general, one path at a time, between the
        // vectorised stage's paths): rough conductor and plastic; smooth conductor and
        // dielectric, whose delta lobes leave an infinite density for the next vertex's MIS
        const std::string dir = std::string(TANDEM_SOURCE_DIR);
        both(load_scene(dir + "/tests/scenes/grad-rough.xml", {{"res", "20"}, {"max_depth", "6"}}), 3, 5);
        both(load_scene(dir + "/tests/scenes/grad-delta.xml", {{"res", "20"}, {"max_depth", "-1"}}), 3, 5);
    }

    TEST_CASE("renders are bitwise deterministic, and the seed changes the noise") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const SceneDesc d = knot_under_env("determinism", 0.7f, 40, 30);
        const RenderResult a = render(d, 8, 7), b = render(d, 8, 7), c = render(d, 8, 8);
        CHECK(test::same_bytes(a.rgb, b.rgb));
        CHECK(!test::same_bytes(a.rgb, c.rgb));
    }
}
