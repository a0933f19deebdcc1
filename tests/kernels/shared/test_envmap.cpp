// Environment maps (kernels/shared/envmap.h, tables from build_envmap): the bilinear lookup
// against an independent tent-filter sum, the sampling density against closed forms (integral 1,
// proportional to luminance at the texels), a histogram of its samples against it, and the same
// code on the device.
//
// Tolerances: lookups are float trigonometry of float directions, good to ~1e-6 in (u, v); 2e-5
// relative to the value covers the texel slopes used here (<= 8 per unit u). The histogram test
// uses Pearson's statistic against the Wilson-Hilferty 99.9 % quantile (a false alarm once in a
// thousand seeds; the seed is fixed), and shows its power on a wrong density.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "core/scene/render_scene.h"
#include "runtime/error.h"
#include "runtime/launch.h"
#include "shared/envmap.h"
#include "shared/rng.h"
#include "support.h"

using namespace tandem;

namespace {

constexpr double k_pi = 3.14159265358979323846;

/// World direction of map coordinates (u, v) under an identity to_world (Mitsuba's convention).
gpu::float3 direction(double u, double v) {
    const double theta = v * k_pi, phi = 2.0 * k_pi * u;
    return gpu::make_float3(float(std::sin(theta) * std::sin(phi)), float(std::cos(theta)),
                            float(-std::sin(theta) * std::cos(phi)));
}

/// Map coordinates (u in [0, 1), v in [0, 1]) of a local direction, in double.
void coordinates(gpu::float3 l, double* u, double* v) {
    *u = std::atan2(double(l.x), -double(l.z)) / (2.0 * k_pi);
    *u -= std::floor(*u);
    *v = std::acos(std::fmin(std::fmax(double(l.y), -1.0), 1.0)) / k_pi;
}

/// Channel k of the map at (u, v), written independently of envmap.h: the sum over texels of
/// value x tent weights, the tent centred on u = (x + 1/2) / w (periodic) and v = y / (h - 1).
double tent_lookup(const std::vector<float>& rgb, int w, int h, double u, double v, int k) {
    double sum = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double du = std::fabs(u - (x + 0.5) / w);
            du = std::fmin(du, 1.0 - du); // periodic distance
            const double wu = std::fmax(0.0, 1.0 - du * w);
            const double wv = std::fmax(0.0, 1.0 - std::fabs(v - double(y) / (h - 1)) * (h - 1));
            sum += wu * wv * rgb[3 * (std::size_t(y) * w + x) + k];
        }
    return sum;
}

/// A 4x3 map: red = x + 4 y, green = a bump at (2, 1), blue = 1 everywhere.
std::vector<float> small_map() {
    std::vector<float> rgb;
    for (int y = 0; y < 3; ++y)
        for (int x = 0; x < 4; ++x)
            rgb.insert(rgb.end(), {float(x + 4 * y), (x == 2 && y == 1) ? 5.0f : 0.0f, 1.0f});
    return rgb;
}

/// A 16x8 map with a bright 'sun' texel over a gradient, the sampling test's.
std::vector<float> sun_map(int w, int h) {
    std::vector<float> rgb(std::size_t(w) * h * 3);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int k = 0; k < 3; ++k)
                rgb[3 * (std::size_t(y) * w + x) + k] =
                    (x == 11 && y == 2) ? 50.0f : 0.2f + 0.1f * x;
    return rgb;
}

/// The rotation the sun map is tested under: a look-at frame, so no map axis is a world axis.
glm::mat4 sun_to_world() { return look_at({0, 0, 0}, {1, 0.3f, 0.2f}, {0, 1, 0}); }

/// A scene holding sun_map(w, h) as its environment, under sun_to_world().
RenderScene sun_scene(int w, int h) {
    RenderScene rs;
    build_envmap(sun_map(w, h), w, h, sun_to_world(), rs);
    return rs;
}

/// Wilson-Hilferty approximation of the 99.9 % quantile of chi-square with k degrees of freedom.
double chi2_quantile_999(double k) {
    const double z = 3.09;
    return k * std::pow(1 - 2 / (9 * k) + z * std::sqrt(2 / (9 * k)), 3);
}

} // namespace

TEST_SUITE("envmap") {
    TEST_CASE("envmap lookup: bilinear between texel centres, wrapping in u, clamped in v") {
        const int w = 4, h = 3;
        const std::vector<float> rgb = small_map();
        RenderScene rs;
        build_envmap(rgb, w, h, glm::mat4(1.0f), rs);
        const gpu::EnvMap& env = rs.envmap;
        auto eval = [&](double u, double v) {
            return gpu::envmap_eval(&env, rs.env_texels.data(), direction(u, v));
        };
        auto close = [](double a, double b) {
            return std::fabs(a - b) <= 2e-5 * (1.0 + std::fabs(b));
        };
        // texel centres: the texel itself (rows 0 and 2 are the poles, so only row 1 is a point)
        for (int x = 0; x < w; ++x) {
            const gpu::float3 c = eval((x + 0.5) / w, 0.5);
            CHECK(close(c.x, x + 4.0));
            CHECK(close(c.y, x == 2 ? 5.0 : 0.0));
        }
        CHECK(close(eval(0.0, 0.5).x, 0.5 * (7.0 + 4.0))); // u = 0 blends columns 3 and 0
        CHECK(close(eval(0.99, 0.5).x, 7.0 + (0.99 * 4 - 3.5) * (4.0 - 7.0))); // and wraps
        CHECK(close(eval(0.375, 0.25).x, 0.5 * (1.0 + 5.0)));  // column 1, between rows 0 and 1
        CHECK(close(eval(0.625, 0.75).x, 0.5 * (6.0 + 10.0))); // column 2, between rows 1 and 2
        CHECK(close(eval(0.625, 1.0).x, 10.0));                // the south pole is row 2
        // everywhere: the tent-filter sum, and exactly 1 where the map is 1
        int exact = 0;
        for (int i = 0; i < 2000; ++i) {
            const double u = gpu::rng_uniform(5, i, 0, 0), v = gpu::rng_uniform(5, i, 0, 1);
            gpu::float3 l = direction(u, v);
            double uu, vv;
            coordinates(l, &uu, &vv); // the coordinates the float direction really has
            const gpu::float3 c = gpu::envmap_eval(&env, rs.env_texels.data(), l);
            INFO("u " << uu << ", v " << vv);
            CHECK(close(c.x, tent_lookup(rgb, w, h, uu, vv, 0)));
            CHECK(close(c.y, tent_lookup(rgb, w, h, uu, vv, 1)));
            exact += c.z == 1.0f;
        }
        CHECK(exact == 2000);
        // a rotation: world direction R l looks up what l looks up without it
        RenderScene rotated;
        const glm::mat4 to_world = glm::rotate(glm::mat4(1.0f), 0.7f, glm::vec3(0.3f, 1.0f, -0.2f));
        build_envmap(rgb, w, h, to_world, rotated);
        for (int i = 0; i < 100; ++i) {
            const gpu::float3 l =
                direction(gpu::rng_uniform(6, i, 0, 0), gpu::rng_uniform(6, i, 0, 1));
            const glm::vec3 d = glm::mat3(to_world) * glm::vec3(l.x, l.y, l.z);
            const gpu::float3 a = gpu::envmap_eval(&rotated.envmap, rotated.env_texels.data(),
                                                   gpu::make_float3(d.x, d.y, d.z));
            const gpu::float3 b = gpu::envmap_eval(&env, rs.env_texels.data(), l);
            CHECK(std::fabs(a.x - b.x) < 1e-4f * (1.0f + b.x));
        }
    }

    TEST_CASE("envmap tables: Mitsuba's padding to 2 x 3, and maps with nothing to sample") {
        RenderScene one;
        build_envmap({0.25f, 0.5f, 2.0f}, 1, 1, glm::mat4(1.0f), one); // a constant map
        CHECK(one.envmap.width == 2u);
        CHECK(one.envmap.height == 3u);
        for (int i = 0; i < 200; ++i) {
            const gpu::float3 c = gpu::envmap_eval(
                &one.envmap, one.env_texels.data(),
                direction(gpu::rng_uniform(7, i, 0, 0), gpu::rng_uniform(7, i, 0, 1)));
            CHECK((c.x == 0.25f && c.y == 0.5f && c.z == 2.0f));
        }
        RenderScene rs;
        CHECK_THROWS_WITH_AS(
            build_envmap(std::vector<float>(4 * 3 * 3, 0.0f), 4, 3, glm::mat4(1.0f), rs),
            "the environment map is black", Error); // exactly: not the message below
        std::vector<float> poles(4 * 3 * 3, 0.0f);
        poles[0] = 1.0f; // light in row 0 only: a single direction, sin(theta) = 0
        CHECK_THROWS_WITH_AS(build_envmap(poles, 4, 3, glm::mat4(1.0f), rs),
                             doctest::Contains("first and last rows"), Error);
    }

    TEST_CASE("envmap density: integrates to 1, and is proportional to luminance at the texels") {
        const int w = 16, h = 8;
        const std::vector<float> rgb = sun_map(w, h);
        const RenderScene rs = sun_scene(w, h);
        const glm::mat4 to_world = sun_to_world();
        const gpu::EnvMap& env = rs.envmap;
        // Midpoint rule over the sphere in (phi, z = cos theta), uniform in solid angle. The
        // density is continuous and piecewise smooth: the rule's error is well under 1e-4 (the
        // integral came out within 1e-6 of 1; leaving out sin(theta) or a normaliser moves it by
        // far more).
        const int nphi = 2048, nz = 1024;
        double integral = 0;
        for (int j = 0; j < nz; ++j) {
            const double z = -1.0 + 2.0 * (j + 0.5) / nz, s = std::sqrt(1.0 - z * z);
            for (int i = 0; i < nphi; ++i) {
                const double phi = 2.0 * k_pi * (i + 0.5) / nphi;
                const gpu::float3 d =
                    gpu::make_float3(float(s * std::cos(phi)), float(z), float(s * std::sin(phi)));
                integral += gpu::envmap_pdf(&env, rs.env_texels.data(), d);
            }
        }
        integral *= 4.0 * k_pi / (double(nphi) * nz);
        INFO("integral " << integral);
        CHECK(std::fabs(integral - 1.0) < 1e-4);
        // At texel (x, y) of an inner row the density in (u, v) is its luminance times
        // sin(theta) over the normaliser, so the solid-angle density is luminance / (2 pi^2 total).
        for (int y = 1; y < h - 1; ++y)
            for (int x = 0; x < w; ++x) {
                const gpu::float3 l = direction((x + 0.5) / w, double(y) / (h - 1));
                const glm::vec3 d = glm::mat3(to_world) * glm::vec3(l.x, l.y, l.z);
                const double pdf =
                    gpu::envmap_pdf(&env, rs.env_texels.data(), gpu::make_float3(d.x, d.y, d.z));
                const float* c = &rgb[3 * (std::size_t(y) * w + x)];
                const double lum = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
                INFO("texel " << x << ", " << y);
                CHECK(pdf * 2.0 * k_pi * k_pi * env.total == doctest::Approx(lum).epsilon(1e-4));
            }
    }

    TEST_CASE("envmap sampling: samples follow the density within cells, and report it") {
        // Bins: each cell between four texels split 2 x 2 in (u - 1/2w, v). A bilinear density's
        // mean over a rectangle is its value at the centre, so a bin's probability is its area
        // times the (u, v) density there. A wrong in-cell warp (e.g. uniform in each cell) fails.
        const int w = 16, h = 8, n = 400000;
        const RenderScene rs = sun_scene(w, h);
        const glm::mat4 to_world = sun_to_world();
        const gpu::EnvMap& env = rs.envmap;
        const int bx = 2 * w, by = 2 * (h - 1);
        std::vector<double> count(std::size_t(bx) * by, 0.0);
        double worst = 0; // relative mismatch of the reported density, away from the poles
        for (int i = 0; i < n; ++i) {
            float pdf;
            gpu::float3 radiance;
            const gpu::float3 d = gpu::envmap_sample_eval(
                &env, rs.env_texels.data(), rs.env_cdf.data(), gpu::rng_uniform(2, i, 0, 0),
                gpu::rng_uniform(2, i, 0, 1), &radiance, &pdf);
            const gpu::float3 l = gpu::envmap_to_local(&env, d);
            double u, v;
            coordinates(l, &u, &v);
            if (std::sin(v * k_pi) > 0.03) {
                const double again = gpu::envmap_pdf(&env, rs.env_texels.data(), d);
                worst = std::fmax(worst, std::fabs(pdf - again) / again);
            }
            double s = u - 0.5 / w;
            s -= std::floor(s);
            const int ix = std::min(int(s * bx), bx - 1), iy = std::min(int(v * by), by - 1);
            count[std::size_t(iy) * bx + ix] += 1.0;
        }
        INFO("largest relative difference of a sample's density from envmap_pdf " << worst);
        CHECK(worst < 1e-3);
        auto chi2_test = [&](bool bilinear, double* chi2, double* quantile) {
            *chi2 = 0;
            int dof = -1;
            for (int iy = 0; iy < by; ++iy)
                for (int ix = 0; ix < bx; ++ix) {
                    double p;
                    if (bilinear) {
                        const double u = (ix + 0.5) / bx + 0.5 / w, v = (iy + 0.5) / by;
                        const gpu::float3 l = direction(u, v);
                        const glm::vec3 d = glm::mat3(to_world) * glm::vec3(l.x, l.y, l.z);
                        const double pdf = gpu::envmap_pdf(&env, rs.env_texels.data(),
                                                           gpu::make_float3(d.x, d.y, d.z));
                        p = pdf * 2.0 * k_pi * k_pi * std::sin(v * k_pi) / (double(bx) * by);
                    } else { // a quarter of the cell's probability, from the CDFs
                        const float* rows = rs.env_cdf.data();
                        const float* cols = rows + h + (iy / 2) * (w + 1);
                        p = 0.25 * (rows[iy / 2 + 1] - rows[iy / 2]) *
                            (cols[ix / 2 + 1] - cols[ix / 2]);
                    }
                    const double expected = p * n;
                    if (expected < 5) continue;
                    const double c = count[std::size_t(iy) * bx + ix];
                    *chi2 += (c - expected) * (c - expected) / expected;
                    ++dof;
                }
            *quantile = chi2_quantile_999(dof);
            return dof;
        };
        double chi2, quantile;
        const int dof = chi2_test(true, &chi2, &quantile);
        INFO("bilinear: chi2 " << chi2 << " with " << dof << " dof, 99.9% quantile " << quantile);
        CHECK(dof > 300);
        CHECK(chi2 < quantile);
        double chi2_flat, quantile_flat;
        chi2_test(false, &chi2_flat, &quantile_flat);
        INFO("uniform within cells: chi2 " << chi2_flat << ", quantile " << quantile_flat);
        CHECK(chi2_flat > 10 * quantile_flat); // the test has the power to see the in-cell warp
        // the four cells around the sun texel get most samples
        double sun = 0;
        for (int iy = 2; iy < 6; ++iy)
            for (int ix = 2 * 10; ix < 2 * 12; ++ix)
                sun += count[std::size_t(iy) * bx + ix];
        CHECK(sun > 0.3 * n);
    }

    TEST_CASE("envmap sampling: a sample's own radiance and density are its direction's lookup") {
        // envmap_sample_eval filters the drawn cell's four texels at the drawn fractions; the
        // lookup finds the same texels and fractions again from the direction through atan2 and
        // acos, and the tent sum in double is independent of both. The sun texel (value 50 next
        // to 1.3) makes the slopes steep: a wrong cell or a swapped fraction is off by far more.
        const int w = 16, h = 8, n = 20000;
        const std::vector<float> rgb = sun_map(w, h);
        const RenderScene rs = sun_scene(w, h);
        const gpu::EnvMap& env = rs.envmap;
        double worst_lookup = 0, worst_tent = 0, worst_pdf = 0;
        int poles = 0;
        for (int i = 0; i < n; ++i) {
            const float u1 = gpu::rng_uniform(5, i, 0, 0), u2 = gpu::rng_uniform(5, i, 0, 1);
            gpu::float3 radiance;
            float pdf;
            const gpu::float3 d = gpu::envmap_sample_eval(&env, rs.env_texels.data(),
                                                          rs.env_cdf.data(), u1, u2, &radiance, &pdf);
            float pdf_lookup;
            const gpu::float3 c = gpu::envmap_eval_pdf(&env, rs.env_texels.data(), d, &pdf_lookup);
            double u, v;
            coordinates(gpu::envmap_to_local(&env, d), &u, &v);
            const float got[3] = {radiance.x, radiance.y, radiance.z}, lookup[3] = {c.x, c.y, c.z};
            for (int k = 0; k < 3; ++k) {
                const double tent = tent_lookup(rgb, w, h, u, v, k);
                worst_lookup = std::fmax(worst_lookup, std::fabs(got[k] - lookup[k]) / lookup[k]);
                worst_tent = std::fmax(worst_tent, std::fabs(got[k] - tent) / tent);
            }
            if (std::sin(v * k_pi) > 0.03)
                worst_pdf = std::fmax(worst_pdf, std::fabs(pdf - pdf_lookup) / pdf_lookup);
            else
                ++poles;
        }
        INFO("relative differences: radiance from the lookup " << worst_lookup << ", from the tent "
             << worst_tent << ", density from the lookup " << worst_pdf << " (" << poles
             << " samples near a pole)");
        CHECK(worst_lookup < 1e-4);
        CHECK(worst_tent < 1e-4);
        CHECK(worst_pdf < 1e-3);
    }
}

TEST_SUITE("device") {
    TEST_CASE("envmap on the device: lookups, densities and samples as on the host") {
        // The same shared code on both sides; only the trigonometric built-ins may differ (a few
        // ulps), so values agree to 1e-4 relative and directions to 1e-5.
        TANDEM_REQUIRE_DEVICE(ctx);
        const int w = 16, h = 8, n = 512;
        const RenderScene rs = sun_scene(w, h);
        const std::string source =
            KernelLibrary::from_environment().preprocess("shared/envmap.h") + R"(
__kernel void envmap_probe(EnvMap env, __global const float4* texels, __global const float* cdf,
                           __global const float4* dirs, __global float4* out, uint n) {
    const uint i = get_global_id(0);
    if (i >= n) return;
    const float3 d = xyz(dirs[i]);
    const float3 c = envmap_eval(&env, texels, d);
    out[4u * i] = (float4)(c, envmap_pdf(&env, texels, d));
    float pdf;
    float3 radiance;
    const float t = dirs[i].w * 7.31f, u2 = t - floor(t);
    const float3 s = envmap_sample_eval(&env, texels, cdf, dirs[i].w, u2, &radiance, &pdf);
    out[4u * i + 1u] = (float4)(s, pdf);
    out[4u * i + 2u] = (float4)(envmap_eval(&env, texels, s), envmap_pdf(&env, texels, s));
    out[4u * i + 3u] = (float4)(radiance, 0.0f);
}
)";
        const Program program = Program::build_source(*ctx, "envmap probe", source, "");
        std::vector<gpu::float4> dirs(n);
        for (int i = 0; i < n; ++i) {
            const gpu::float3 d =
                direction(gpu::rng_uniform(8, i, 0, 0), gpu::rng_uniform(8, i, 0, 1));
            dirs[i] = gpu::make_float4(d.x, d.y, d.z, gpu::rng_uniform(8, i, 0, 2));
        }
        Buffer<gpu::float4> texels(*ctx, "texels", rs.env_texels);
        Buffer<float> cdf(*ctx, "cdf", rs.env_cdf);
        Buffer<gpu::float4> in(*ctx, "dirs", dirs);
        Buffer<gpu::float4> out(*ctx, "out", std::size_t(4) * n);
        Kernel(program, "envmap_probe")
            .launch(*ctx, "envmap probe", n, rs.envmap, texels, cdf, in, out, unsigned(n));
        const std::vector<gpu::float4> got = out.download();
        auto close = [](float a, float b, float tol) {
            return std::fabs(a - b) <= tol * (1.0f + std::fabs(b));
        };
        int bad = 0;
        for (int i = 0; i < n; ++i) {
            const gpu::float3 d = gpu::make_float3(dirs[i].x, dirs[i].y, dirs[i].z);
            const gpu::float3 c = gpu::envmap_eval(&rs.envmap, rs.env_texels.data(), d);
            const float pdf = gpu::envmap_pdf(&rs.envmap, rs.env_texels.data(), d);
            float spdf;
            const float t = dirs[i].w * 7.31f, u2 = t - std::floor(t);
            gpu::float3 sr;
            const gpu::float3 s = gpu::envmap_sample_eval(&rs.envmap, rs.env_texels.data(),
                                                          rs.env_cdf.data(), dirs[i].w, u2, &sr,
                                                          &spdf);
            const gpu::float4 a = got[4 * i], b = got[4 * i + 1], e = got[4 * i + 2],
                              r = got[4 * i + 3];
            // the lookups at the device's own sample, on the host
            const gpu::float3 s_dev = gpu::make_float3(b.x, b.y, b.z);
            const gpu::float3 sc = gpu::envmap_eval(&rs.envmap, rs.env_texels.data(), s_dev);
            const float sp = gpu::envmap_pdf(&rs.envmap, rs.env_texels.data(), s_dev);
            const bool ok = close(a.x, c.x, 1e-4f) && close(a.y, c.y, 1e-4f) &&
                            close(a.z, c.z, 1e-4f) && close(a.w, pdf, 1e-4f) &&
                            close(b.x, s.x, 1e-5f) && close(b.y, s.y, 1e-5f) &&
                            close(b.z, s.z, 1e-5f) && close(b.w, spdf, 1e-4f) &&
                            close(e.x, sc.x, 1e-4f) && close(e.w, sp, 1e-4f) &&
                            close(r.x, sr.x, 1e-4f) && close(r.y, sr.y, 1e-4f) &&
                            close(r.z, sr.z, 1e-4f);
            if (!ok) {
                INFO("sample " << i << ": device eval " << a.x << " pdf " << a.w << ", host " << c.x
                               << " " << pdf << "; device sample pdf " << b.w << ", host " << spdf);
                CHECK(ok);
                ++bad;
            }
        }
        CHECK(bad == 0);
    }
}
