// Lights against closed forms on the device: point and spot lights, a small area light (Lambert's
// polygon formula) and environment maps over a diffuse plane; and a stress scene of extreme
// roughness, radiance and degenerate geometry. The environment map's lookup and sampler are
// tested on their own in tests/kernels/shared/test_envmap.cpp.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "core/render/passes.h"
#include "render_fixtures.h"
#include "support.h"

using namespace tandem;

namespace {

/// Irradiance at p (normal n) from a Lambertian polygon of radiance Le: Lambert's formula,
/// E = Le / 2 sum_i angle(v_i, v_i+1) (n . unit(v_i x v_i+1)), v_i = vertex_i - p.
double polygon_irradiance(const std::vector<glm::dvec3>& poly, const glm::dvec3& p,
                          const glm::dvec3& n, double Le) {
    double sum = 0;
    for (std::size_t i = 0; i < poly.size(); ++i) {
        const glm::dvec3 a = glm::normalize(poly[i] - p), b = glm::normalize(poly[(i + 1) % poly.size()] - p);
        const glm::dvec3 c = glm::cross(a, b);
        sum += std::acos(std::clamp(glm::dot(a, b), -1.0, 1.0)) * glm::dot(n, glm::normalize(c));
    }
    return 0.5 * Le * std::fabs(sum);
}

} // namespace

TEST_SUITE("device") {
    TEST_CASE(
        "envmap: a plane under a coarse sky sees the filtered sky, a uniform map is a furnace") {
        // Sky: a 32 x 4 map, rows 0 and 1 (theta = 0 and 60 degrees, local +y up) of radiance 2,
        // rows 2 and 3 (120 and 180 degrees) black. Filtered bilinearly, L = 2 up to theta1 = pi/3
        // and 2 (theta2 - theta) / (theta2 - theta1) after it, theta2 = 2 pi / 3. A plane facing
        // up shows rho / pi * 2 pi * int_0^(pi/2) L cos sin dtheta
        //   = 2 rho (sin^2 theta1 + 2 / (theta2 - theta1) (F(pi/2) - F(theta1))),
        // F(t) = -(theta2 - t) cos 2t / 4 - sin 2t / 8 being the antiderivative of
        // (theta2 - t) sin t cos t: 0.9567 x 2 rho (the nearest texel would give 2 rho, 40
        // standard errors away). Uniform map of 1: an albedo-1 sphere vanishes (white furnace),
        // through the importance sampler's non-uniform solid-angle density.
        TANDEM_REQUIRE_DEVICE(ctx);
        for (int variant = 0; variant < 2; ++variant) {
            const int w = 32, h = variant == 0 ? 4 : 16;
            SceneDesc d;
            d.path = variant == 0 ? "sky-plane" : "envmap-furnace";
            d.camera().to_world = look_at({0, 3, 0}, {0, 0, 0}, {0, 0, -1});
            d.camera().fov = variant == 0 ? 2.0f * std::atan(1.0f / 3.0f) * 180.0f / 3.14159265f : 40.0f;
            d.camera().width = d.camera().height = 24;
            Bsdf b;
            b.reflectance.value = glm::vec3(variant == 0 ? 0.6f : 1.0f);
            d.bsdfs.push_back(b);
            Shape s;
            s.type = variant == 0 ? ShapeType::rectangle : ShapeType::sphere;
            if (variant == 0) s.to_world = look_at({0, 0, 0}, {0, 1, 0}, {0, 0, 1}); // normal +y
            s.bsdf = 0;
            d.shapes.push_back(s);
            RenderScene rs = build_render_scene(d);
            std::vector<float> rgb(std::size_t(w) * h * 3, 1.0f);
            if (variant == 0)
                for (std::size_t i = 0; i < rgb.size(); ++i)
                    rgb[i] = int(i / 3) / w < h / 2 ? 2.0f : 0.0f;
            rs.has_env = true;
            build_envmap(rgb, w, h, glm::mat4(1.0f), rs);
            const RenderResult r = test::render_flat(*ctx, rs, 32);
            double sum = 0, sum2 = 0;
            const double t1 = 3.14159265358979 / 3, t2 = 2 * t1;
            auto F = [&](double t) {
                return -(t2 - t) * std::cos(2 * t) / 4 - std::sin(2 * t) / 8;
            };
            const double sky = std::sin(t1) * std::sin(t1) + 2 / (t2 - t1) * (F(t1 * 1.5) - F(t1));
            const double expected = variant == 0 ? 2.0 * 0.6 * sky : 1.0;
            for (float v : r.rgb) {
                sum += v - expected;
                sum2 += (v - expected) * (v - expected);
            }
            const double n = double(r.rgb.size()), mean = sum / n;
            const double se = std::sqrt(std::max(0.0, sum2 / n - mean * mean) / n);
            INFO(d.path << ": mean difference " << mean << ", standard error " << se);
            CHECK(std::fabs(mean) <= 5.0 * se + 1e-5);
            CHECK(r.nan_guards == 0);
        }
    }

    TEST_CASE("point and spot lights over a diffuse plane match the closed form") {
        // The camera frames the plane [-1,1]^2 exactly (see the checkerboard test). A light at
        // height h over the origin gives L(x, y) = rho / pi * I * falloff * h / r^3, r the
        // distance to the light; the expectation of a pixel is the mean over its footprint,
        // computed here by an 8x8 midpoint rule.
        TANDEM_REQUIRE_DEVICE(ctx);
        const int res = 32;
        const float h = 0.6f, rho = 0.7f, I = 2.0f;
        const float deg = 3.14159265f / 180.0f, cutoff = 40.0f * deg, beam = 25.0f * deg;
        for (EmitterType type : {EmitterType::point, EmitterType::spot}) {
            SceneDesc d;
            d.path = "delta-light";
            d.integrator.max_depth = 2;
            d.camera() = test::top_down_camera(res);
            Bsdf b;
            b.reflectance.value = glm::vec3(rho);
            d.bsdfs.push_back(b);
            Emitter e;
            e.type = type;
            e.intensity = glm::vec3(I);
            e.to_world = look_at({0, 0, h}, {0, 0, 0}, {0, 1, 0}); // spot axis: local +z = down
            e.cutoff_angle = 40.0f;
            e.beam_width = 25.0f;
            d.emitters.push_back(e);
            Shape s;
            s.type = ShapeType::rectangle;
            s.bsdf = 0;
            d.shapes.push_back(s);
            const RenderResult r = test::render_desc(*ctx, d, 16);
            auto radiance = [&](double x, double y) {
                const double r2 = x * x + y * y + double(h) * h, rr = std::sqrt(r2);
                double falloff = 1.0;
                if (type == EmitterType::spot) {
                    const double angle = std::acos(h / rr);
                    falloff = angle <= beam ? 1.0 : (angle < cutoff ? (cutoff - angle) / (cutoff - beam) : 0.0);
                }
                return rho / 3.14159265358979 * I * falloff * h / (r2 * rr);
            };
            test::DiffStats diff;
            for (int py = 0; py < res; ++py)
                for (int px = 0; px < res; ++px) {
                    double expect = 0;
                    for (int j = 0; j < 8; ++j)
                        for (int i = 0; i < 8; ++i)
                            expect += radiance(-1.0 + 2.0 * (px + (i + 0.5) / 8) / res,
                                               1.0 - 2.0 * (py + (j + 0.5) / 8) / res) / 64.0;
                    diff.add(r.rgb[3 * (std::size_t(py) * res + px)] - expect);
                }
            INFO((type == EmitterType::spot ? "spot" : "point") << ": mean difference " << diff.mean()
                 << ", standard error " << diff.std_error() << ", rms " << diff.rms());
            CHECK(std::fabs(diff.mean()) <= 5.0 * diff.std_error() + 1e-4);
            CHECK(diff.rms() < 0.02); // the pixels themselves, not just their mean
        }
    }

    TEST_CASE("a small area light over a diffuse plane matches Lambert's polygon formula") {
        // Light: a 0.3 x 0.3 square at height 0.5 over (0.35, 0.2), facing down. The camera
        // frames the plane [-1,1]^2 from above (see the checkerboard test); pixels whose view the
        // light itself blocks are skipped. Pixel expectation: rho / pi * E over an 8x8 grid.
        TANDEM_REQUIRE_DEVICE(ctx);
        const int res = 32;
        const double rho = 0.8, Le = 5.0, h = 0.5, half = 0.15, cx = 0.35, cy = 0.2;
        SceneDesc d;
        d.path = "area-over-plane";
        d.integrator.max_depth = 2;
        d.camera() = test::top_down_camera(res);
        Bsdf b;
        b.reflectance.value = glm::vec3(float(rho));
        d.bsdfs.push_back(b);
        Emitter e;
        e.type = EmitterType::area;
        e.radiance = glm::vec3(float(Le));
        d.emitters.push_back(e);
        Shape plane;
        plane.type = ShapeType::rectangle;
        plane.bsdf = 0;
        d.shapes.push_back(plane);
        Shape light;
        light.type = ShapeType::rectangle;
        light.to_world = glm::translate(glm::mat4(1.0f), glm::vec3(cx, cy, h)) *
                         glm::scale(glm::mat4(1.0f), glm::vec3(float(half), float(half), 1.0f));
        light.flip_normals = true; // face down, toward the plane
        light.bsdf = 0;
        light.emitter = 0;
        d.shapes.push_back(light);
        const RenderResult r = test::render_desc(*ctx, d, 64);
        const std::vector<glm::dvec3> poly = {{cx - half, cy - half, h}, {cx + half, cy - half, h},
                                              {cx + half, cy + half, h}, {cx - half, cy + half, h}};
        test::DiffStats diff;
        for (int py = 0; py < res; ++py)
            for (int px = 0; px < res; ++px) {
                double expect = 0;
                bool blocked = false;
                for (int j = 0; j < 8; ++j)
                    for (int i = 0; i < 8; ++i) {
                        const glm::dvec3 p(-1.0 + 2.0 * (px + (i + 0.5) / 8) / res,
                                           1.0 - 2.0 * (py + (j + 0.5) / 8) / res, 0.0);
                        const glm::dvec3 at_light = p * (1.0 - h / 3.0); // the view ray at z = h
                        blocked |= std::fabs(at_light.x - cx) <= half + 0.01 &&
                                   std::fabs(at_light.y - cy) <= half + 0.01;
                        expect += rho / 3.14159265358979 * polygon_irradiance(poly, p, {0, 0, 1}, Le) / 64.0;
                    }
                if (blocked) continue;
                diff.add(r.rgb[3 * (std::size_t(py) * res + px)] - expect);
            }
        INFO("mean difference " << diff.mean() << ", standard error " << diff.std_error() << ", rms "
                                << diff.rms() << " over " << diff.n << " pixels");
        CHECK(diff.n > 900);
        CHECK(std::fabs(diff.mean()) <= 5.0 * diff.std_error() + 1e-4);
    }

    TEST_CASE("stress: extreme roughness, radiance and degenerate triangles give finite images") {
        // GGX alpha 1e-4 and 1, lights of radiance 1e-6 and 1e6, grazing views of a plane, and
        // the mesh with zero-area and duplicate triangles: no NaN or Inf may reach the image;
        // the guards count any non-finite sample they drop.
        TANDEM_REQUIRE_DEVICE(ctx);
        for (float alpha : {1e-4f, 1.0f})
            for (float radiance : {1e-6f, 1e6f}) {
                const SceneDesc d = test::stress_scene(alpha, radiance, 32);
                const RenderResult r = test::render_desc(*ctx, d, 16);
                INFO("alpha " << alpha << ", radiance " << radiance << ": " << r.nan_guards
                              << " non-finite samples dropped");
                std::size_t bad = 0, lit = 0;
                for (float v : r.rgb) {
                    bad += !std::isfinite(v) || v < 0.0f;
                    lit += v > 0.0f;
                }
                CHECK(bad == 0);
                CHECK(lit > r.rgb.size() / 2);         // the scene is really lit and seen
                CHECK(r.nan_guards == 0u); // none were needed here (the guard counts any)
            }
    }
}
