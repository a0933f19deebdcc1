// Texture evaluation on the host (the shared code the kernel runs), and a textured plane rendered
// on the device against the texture itself.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "core/render/passes.h"
#include "shared/envmap.h"
#include "shared/rng.h"
#include "shared/textures.h"
#include "render_fixtures.h"
#include "support.h"

using namespace tandem;

namespace {

gpu::TextureInfo identity_uv() {
    gpu::TextureInfo t{};
    t.param = NO_PARAM;
    t.uv_row0 = gpu::make_float4(1, 0, 0, 0);
    t.uv_row1 = gpu::make_float4(0, 1, 0, 0);
    return t;
}

/// A diffuse bsdf textured by a checkerboard (colours 0.8, 0.2, 0.1 and 0.1, 0.3, 0.7 through
/// `to_uv`) under a constant environment L, named `path`: the analytic-shape tests' scene before
/// its camera and its one shape (bsdf 0).
SceneDesc checker_under_env(const char* path, const glm::mat3& to_uv, float L) {
    SceneDesc d;
    d.path = path;
    Texture tex;
    tex.kind = Texture::Kind::checkerboard;
    tex.color0 = glm::vec3(0.8f, 0.2f, 0.1f);
    tex.color1 = glm::vec3(0.1f, 0.3f, 0.7f);
    tex.to_uv = to_uv;
    d.textures.push_back(tex);
    Bsdf b;
    b.reflectance.texture = 0;
    d.bsdfs.push_back(b);
    Emitter env;
    env.type = EmitterType::constant;
    env.radiance = glm::vec3(L);
    d.emitters.push_back(env);
    return d;
}

/// The rendered res x res image `r` of a checker_under_env scene d against its reference:
/// `cell(fx, fy)` is what the camera ray through film point (fx, fy) sees (0 or 1: the
/// checkerboard's colours, 2: the environment). Pixels whose 16 stratified rays all see one cell
/// are compared with that colour x L (or L); `counted` gets how many of each.
template <class Cell>
test::DiffStats compare_pure_pixels(const RenderResult& r, int res, const SceneDesc& d, float L,
                                    Cell cell, int counted[3]) {
    const Texture& tex = d.textures.at(0);
    test::DiffStats diff;
    counted[0] = counted[1] = counted[2] = 0;
    for (int y = 0; y < res; ++y)
        for (int x = 0; x < res; ++x) {
            const int first = cell((x + 0.125) / res, (y + 0.125) / res);
            bool pure = true;
            for (int k = 0; k < 16 && pure; ++k)
                pure = cell((x + (k % 4 + 0.5) / 4.0) / res, (y + (k / 4 + 0.5) / 4.0) / res) == first;
            if (!pure) continue;
            counted[first] += 1;
            const glm::vec3 expect = first == 2 ? glm::vec3(L) : L * (first == 0 ? tex.color0 : tex.color1);
            for (int k = 0; k < 3; ++k)
                diff.add(r.rgb[3 * (std::size_t(y) * res + x) + k] - expect[k]);
        }
    return diff;
}

} // namespace

TEST_SUITE("textures") {
    TEST_CASE("checkerboard: Mitsuba's 2x2 cells, repeating, through to_uv") {
        gpu::TextureInfo t = identity_uv();
        t.kind = TEXTURE_CHECKERBOARD;
        t.color0 = gpu::make_float4(1, 0, 0, 0);
        t.color1 = gpu::make_float4(0, 0, 1, 0);
        auto red = [&](float u, float v) { return gpu::texture_eval(&t, nullptr, nullptr, u, v).x == 1.0f; };
        CHECK(red(0.25f, 0.25f));
        CHECK(!red(0.75f, 0.25f));
        CHECK(!red(0.25f, 0.75f));
        CHECK(red(0.75f, 0.75f));
        CHECK(red(1.25f, -0.75f)); // repeats
        t.uv_row0 = gpu::make_float4(2, 0, 0, 0); // to_uv scales u by 2
        CHECK(!red(0.375f, 0.25f));
    }

    TEST_CASE("bitmap: texel centres exact, bilinear between them, nearest, wrapping") {
        // 2x2 texels: (0,0)=0, (1,0)=1, (0,1)=2, (1,1)=3 in every channel
        const std::vector<gpu::float4> texels = {gpu::make_float4(0, 0, 0, 0), gpu::make_float4(1, 1, 1, 0),
                                                 gpu::make_float4(2, 2, 2, 0), gpu::make_float4(3, 3, 3, 0)};
        gpu::TextureInfo t = identity_uv();
        t.kind = TEXTURE_BITMAP;
        t.width = t.height = 2;
        auto at = [&](float u, float v) { return gpu::texture_eval(&t, texels.data(), nullptr, u, v).x; };
        CHECK(at(0.25f, 0.25f) == 0.0f); // texel centres
        CHECK(at(0.75f, 0.25f) == 1.0f);
        CHECK(at(0.25f, 0.75f) == 2.0f);
        CHECK(at(0.75f, 0.75f) == 3.0f);
        CHECK(at(0.5f, 0.5f) == doctest::Approx(1.5f)); // the average of all four
        CHECK(at(0.5f, 0.25f) == doctest::Approx(0.5f));
        CHECK(at(0.0f, 0.25f) == doctest::Approx(0.5f)); // wraps: halfway between texel 1 and 0
        t.filter = TEXTURE_FILTER_NEAREST;
        CHECK(at(0.49f, 0.99f) == 2.0f);
        CHECK(at(1.01f, 0.01f) == 0.0f);
    }

    TEST_CASE(
        "a bitmap that is a parameter reads rgb triplets, its footprint is the lookup's weights") {
        const std::vector<gpu::float4> texels = {gpu::make_float4(0, 0.5f, 0, 0), gpu::make_float4(1, 0, 0, 0),
                                                 gpu::make_float4(2, 0, 0.25f, 0), gpu::make_float4(3, 0, 0, 0)};
        std::vector<float> params = {9.0f}; // one unrelated value first: param is an offset
        for (const gpu::float4& c : texels) params.insert(params.end(), {c.x, c.y, c.z});
        gpu::TextureInfo t = identity_uv();
        t.kind = TEXTURE_BITMAP;
        t.width = t.height = 2;
        gpu::TextureInfo tp = t;
        tp.param = 1;
        for (int filter : {TEXTURE_FILTER_BILINEAR, TEXTURE_FILTER_NEAREST}) {
            t.filter = tp.filter = static_cast<unsigned>(filter);
            for (float u : {0.1f, 0.3f, 0.5f, 0.9f, 1.7f})
                for (float v : {-0.2f, 0.25f, 0.6f}) {
                    const gpu::float3 a = gpu::texture_eval(&t, texels.data(), nullptr, u, v);
                    const gpu::float3 b = gpu::texture_eval(&tp, nullptr, params.data(), u, v);
                    CHECK((a.x == b.x && a.y == b.y && a.z == b.z));
                    unsigned index[4];
                    float weight[4];
                    const unsigned n = gpu::texture_footprint(&t, u, v, index, weight);
                    CHECK(n == (filter == TEXTURE_FILTER_NEAREST ? 1u : 4u));
                    double sum = 0.0, value = 0.0;
                    for (unsigned k = 0; k < n; ++k) {
                        sum += weight[k];
                        value += weight[k] * texels[index[k]].x;
                    }
                    CHECK(sum == doctest::Approx(1.0).epsilon(1e-6));
                    CHECK(value == doctest::Approx(a.x).epsilon(1e-6));
                }
        }
    }
}

TEST_SUITE("device") {
    TEST_CASE("a checkerboard on an analytic sphere: Mitsuba's sphere uv and silhouette") {
        // A convex diffuse sphere alone under a constant environment L reflects albedo x L at
        // every point, whatever its normal, and the rays that miss it see L. The reference image
        // is supersampled here in double precision (16 rays per pixel through the device camera
        // record), with Mitsuba's sphere uv: u = phi / 2pi from +x toward +y, v = theta / pi from
        // +z, in the sphere's own axes (turned by to_world). Pixels whose 16 rays all see one cell,
        // or all miss, are compared.
        TANDEM_REQUIRE_DEVICE(ctx);
        const int res = 48;
        const float L = 1.5f;
        // 16 cells in phi, 8 in theta
        SceneDesc d = checker_under_env("checker-sphere", glm::mat3(8.0f, 0, 0, 0, 4.0f, 0, 0, 0, 1), L);
        d.camera().to_world = look_at({3.0f, 2.0f, 1.5f}, {0, 0, 0}, {0, 0, 1});
        d.camera().fov = 45.0f;
        d.camera().width = d.camera().height = res;
        Shape s;
        s.type = ShapeType::sphere;
        s.center = glm::vec3(0.2f, -0.1f, 0.0f);
        s.radius = 0.5f;
        const glm::mat4 turn = glm::rotate(glm::mat4(1.0f), 0.6f, glm::normalize(glm::vec3(1.0f, 2.0f, 0.5f)));
        s.to_world = glm::translate(glm::mat4(1.0f), glm::vec3(-0.2f, 0.1f, 0.0f)) * turn *
                     glm::scale(glm::mat4(1.0f), glm::vec3(2.0f)); // r 1
        s.bsdf = 0;
        d.shapes.push_back(s);
        const RenderScene flat = build_render_scene(d);
        REQUIRE(flat.mesh.spheres.size() == 1u);
        REQUIRE(flat.mesh.triangles.empty());
        const RenderResult r = test::render_flat_both_forms(*ctx, flat, 64);
        const glm::dvec3 centre = glm::dvec3(glm::vec3(s.to_world * glm::vec4(s.center, 1.0f)));
        const glm::dmat3 to_local = glm::transpose(glm::dmat3(glm::mat3(turn)));
        const gpu::DeviceCamera& cam = flat.camera();
        const glm::dvec3 o(cam.origin.x, cam.origin.y, cam.origin.z);
        const glm::dvec3 dx(cam.dir_x.x, cam.dir_x.y, cam.dir_x.z), dy(cam.dir_y.x, cam.dir_y.y, cam.dir_y.z),
            dz(cam.dir_z.x, cam.dir_z.y, cam.dir_z.z);
        // the cell a camera ray sees: 0 or 1 on the sphere, 2 for the environment
        auto cell = [&](double fx, double fy) {
            const glm::dvec3 dir = glm::normalize(dz + dx * (1.0 - 2.0 * fx) + dy * (1.0 - 2.0 * fy));
            const glm::dvec3 f = o - centre;
            const double bh = glm::dot(f, dir), c = glm::dot(f, f) - 1.0, disc = bh * bh - c;
            if (disc < 0.0) return 2;
            const glm::dvec3 n = to_local * (f + (-bh - std::sqrt(disc)) * dir); // the radius is 1
            double phi = std::atan2(n.y, n.x);
            if (phi < 0.0) phi += 2.0 * 3.14159265358979323846;
            const double u = phi / (2.0 * 3.14159265358979323846);
            const double v = std::acos(std::clamp(n.z, -1.0, 1.0)) / 3.14159265358979323846;
            return (std::fmod(8.0 * u, 1.0) > 0.5) == (std::fmod(4.0 * v, 1.0) > 0.5) ? 0 : 1;
        };
        int counted[3];
        const test::DiffStats diff = compare_pure_pixels(r, res, d, L, cell, counted);
        INFO("pixels compared: " << counted[0] << " and " << counted[1] << " in the two cells, "
             << counted[2] << " background; mean difference " << diff.mean() << ", standard error "
             << diff.std_error() << ", rms " << diff.rms());
        CHECK(counted[0] > 100);
        CHECK(counted[1] > 100);
        CHECK(std::fabs(diff.mean()) <= 5.0 * diff.std_error() + 1e-5);
        // a swapped colour, a mirrored u or v, or a wrong silhouette would be off by ~1
        CHECK(diff.rms() < 0.1);
    }

    TEST_CASE("a checkerboard on an analytic disk: Mitsuba's polar uv, rotated and scaled") {
        // The disk, turned 30 degrees about its normal and scaled by 0.9, under the top-down
        // camera (film (fx, fy) sees world (-1 + 2 fx, 1 - 2 fy, 0)) and a constant environment L:
        // albedo x L on it, L around it. The reference takes Mitsuba's disk uv (r, phi / 2pi) of
        // the local point, 16 rays per pixel; pixels whose rays all see one cell or all miss are
        // compared.
        TANDEM_REQUIRE_DEVICE(ctx);
        const int res = 48;
        const float L = 1.5f, turn = 0.5235988f, scale = 0.9f;
        // 8 rings, 12 sectors offset by 0.37 of one, so that no mirror of the angle maps the
        // pattern onto itself
        SceneDesc d = checker_under_env("checker-disk", glm::mat3(4.0f, 0, 0, 0, 6.0f, 0, 0, 0.37f, 1), L);
        d.camera() = test::top_down_camera(res);
        Shape s;
        s.type = ShapeType::disk;
        s.to_world = glm::rotate(glm::mat4(1.0f), turn, glm::vec3(0, 0, 1)) *
                     glm::scale(glm::mat4(1.0f), glm::vec3(scale));
        s.bsdf = 0;
        d.shapes.push_back(s);
        const RenderScene flat = build_render_scene(d);
        REQUIRE(flat.mesh.disks.size() == 1u);
        REQUIRE(flat.mesh.triangles.empty());
        const RenderResult r = test::render_flat_both_forms(*ctx, flat, 64);
        const double pi = 3.14159265358979323846;
        auto cell = [&](double fx, double fy) { // 0 or 1 on the disk, 2 off it
            const double X = -1.0 + 2.0 * fx, Y = 1.0 - 2.0 * fy;
            const double lx = (std::cos(turn) * X + std::sin(turn) * Y) / scale;
            const double ly = (-std::sin(turn) * X + std::cos(turn) * Y) / scale;
            const double radius = std::sqrt(lx * lx + ly * ly);
            if (radius > 1.0) return 2;
            double phi = std::atan2(ly, lx);
            if (phi < 0.0) phi += 2.0 * pi;
            const double u = radius, v = phi / (2.0 * pi);
            return (std::fmod(4.0 * u, 1.0) > 0.5) == (std::fmod(6.0 * v + 0.37, 1.0) > 0.5) ? 0 : 1;
        };
        int counted[3];
        const test::DiffStats diff = compare_pure_pixels(r, res, d, L, cell, counted);
        INFO("pixels compared: " << counted[0] << " and " << counted[1] << " in the two cells, "
             << counted[2] << " background; mean difference " << diff.mean() << ", standard error "
             << diff.std_error() << ", rms " << diff.rms());
        CHECK(counted[0] > 200);
        CHECK(counted[1] > 200);
        CHECK(counted[2] > 100);
        CHECK(std::fabs(diff.mean()) <= 5.0 * diff.std_error() + 1e-5);
        CHECK(diff.rms() < 0.1);
    }

    TEST_CASE("a checkerboard plane under a constant environment shows env x texture") {
        TANDEM_REQUIRE_DEVICE(ctx);
        // Camera 3 above the plane [-1,1]^2 looking down, framing it exactly: film (fx, fy) sees
        // world (-1 + 2 fx, 1 - 2 fy), so uv = (fx, 1 - fy). to_uv scales by 4: 8x8 cells.
        const int res = 64;
        SceneDesc d;
        d.path = "checker-plane";
        d.camera() = test::top_down_camera(res);
        Texture tex;
        tex.kind = Texture::Kind::checkerboard;
        tex.color0 = glm::vec3(0.8f, 0.2f, 0.1f);
        tex.color1 = glm::vec3(0.1f, 0.3f, 0.7f);
        tex.to_uv = glm::mat3(4.0f, 0, 0, 0, 4.0f, 0, 0, 0, 1);
        d.textures.push_back(tex);
        Bsdf b;
        b.reflectance.texture = 0;
        d.bsdfs.push_back(b);
        Emitter env;
        env.type = EmitterType::constant;
        env.radiance = glm::vec3(1.5f);
        d.emitters.push_back(env);
        Shape s;
        s.type = ShapeType::rectangle;
        s.bsdf = 0;
        d.shapes.push_back(s);
        const RenderResult r = test::render_desc(*ctx, d, 16);
        // Pixels whose footprint lies inside one cell (8 pixels per cell; skip the cell borders).
        test::DiffStats diff;
        for (int y = 0; y < res; ++y)
            for (int x = 0; x < res; ++x) {
                if (x % 8 == 0 || x % 8 == 7 || y % 8 == 0 || y % 8 == 7) continue;
                const float u = (x + 0.5f) / res, v = 1.0f - (y + 0.5f) / res;
                const bool c0 = (std::fmod(4 * u, 1.0f) > 0.5f) == (std::fmod(4 * v, 1.0f) > 0.5f);
                const glm::vec3 expect = 1.5f * (c0 ? tex.color0 : tex.color1);
                for (int k = 0; k < 3; ++k)
                    diff.add(r.rgb[3 * (std::size_t(y) * res + x) + k] - expect[k]);
            }
        INFO("mean difference " << diff.mean() << ", standard error " << diff.std_error() << " over "
                                << diff.n);
        CHECK(std::fabs(diff.mean()) <= 5.0 * diff.std_error() + 1e-5);
        // and the error per pixel is small: a swapped colour or a flipped v would be off by ~1
        CHECK(diff.rms() < 0.1);
    }
}
