// Path tracer against closed forms: white furnace, a diffuse plane under a constant environment,
// a closed emissive sphere at several depths; and bitwise determinism. Scenes are built in code
// so these tests do not depend on the XML loader.
//
// Tolerances: each test averages M pixel values (each the mean of spp samples) and requires the
// mean within 5 standard errors of the expectation, the standard error measured from the pixel
// values themselves (a false alarm once in ~1.7 million runs for Gaussian errors), plus 1e-5 for
// float rounding.
#include <doctest/doctest.h>

#include <cmath>

#include "core/renderer.h"
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

RenderResult render(const SceneDesc& desc, int spp, unsigned seed = 1) {
    tandem::Context* ctx = test::device_context();
    const RenderScene scene = build_render_scene(desc);
    Renderer renderer(*ctx, KernelLibrary::from_environment(), scene);
    RenderOptions opt;
    opt.spp = spp;
    opt.seed = seed;
    return renderer.render(opt);
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

} // namespace

TEST_SUITE("device") {
    TEST_CASE("white furnace: an albedo-1 sphere under a constant environment is invisible") {
        TANDEM_REQUIRE_DEVICE(ctx);
        for (int depth : {2, 3, 5, -1}) {
            SceneDesc d;
            d.path = "furnace";
            d.integrator.max_depth = depth;
            d.camera = make_camera({0, 0, 4}, {0, 0, 0}, {0, 1, 0}, 30.0f, 48, 48);
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
        }
    }

    TEST_CASE("white furnace: the non-convex knot with albedo 1 and unbounded depth gives 1") {
        TANDEM_REQUIRE_DEVICE(ctx);
        SceneDesc d;
        d.path = "furnace-knot";
        d.camera = make_camera({0, -5, 2}, {0, 0, 0}, {0, 0, 1}, 40.0f, 48, 48);
        d.bsdfs.push_back(diffuse(1.0f, /*twosided=*/true));
        d.emitters.push_back(constant_env(1.0f));
        Shape s;
        s.type = ShapeType::ply;
        s.filename = test::mesh_path("knot_ascii.ply");
        s.bsdf = 0;
        d.shapes.push_back(s);
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
            d.camera = make_camera({0, 0, 3}, {0, 0, 0}, {0, 1, 0}, 30.0f, 32, 32);
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

    TEST_CASE("inside a closed emissive diffuse sphere, radiance sums a geometric series by depth") {
        // Every point sees only the sphere, so a path of d segments gathers
        // Le (1 + rho + ... + rho^(d-1)) = Le (1 - rho^d) / (1 - rho).
        TANDEM_REQUIRE_DEVICE(ctx);
        const float rho = 0.5f, Le = 1.5f;
        for (int depth : {1, 2, 3, 6, -1}) {
            SceneDesc d;
            d.path = "emissive-sphere";
            d.integrator.max_depth = depth;
            d.camera = make_camera({0, 0, 0}, {0, 0, 1}, {0, 1, 0}, 60.0f, 32, 32);
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
            INFO("max_depth " << depth);
            check_close(pixel_stats(r, 2, [](int, int) { return true; }), expected, "sphere");
        }
    }

    TEST_CASE("renders are bitwise deterministic, and the seed changes the noise") {
        TANDEM_REQUIRE_DEVICE(ctx);
        SceneDesc d;
        d.path = "determinism";
        d.camera = make_camera({0, -5, 2}, {0, 0, 0}, {0, 0, 1}, 40.0f, 40, 30);
        d.bsdfs.push_back(diffuse(0.7f, true));
        d.emitters.push_back(constant_env(1.0f));
        Shape s;
        s.type = ShapeType::ply;
        s.filename = test::mesh_path("knot_ascii.ply");
        s.bsdf = 0;
        d.shapes.push_back(s);
        const RenderResult a = render(d, 8, 7), b = render(d, 8, 7), c = render(d, 8, 8);
        CHECK(test::same_bytes(a.rgb, b.rgb));
        CHECK(!test::same_bytes(a.rgb, c.rgb));
    }
}
