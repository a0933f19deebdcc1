// Participating media against closed forms (kernels/path/media.h): the furnace, transmittance and
// single scattering through a slab, in a homogeneous medium and in a grid; the majorant grid's
// bound; the scene format's media and its errors; and what refuses media (ReSTIR).
//
// Tolerances: rendered-minus-expected over M pixels, mean within 5 standard errors (measured from
// the pixels' own spread; a false alarm once in ~1.7 million runs for Gaussian errors), plus a
// stated bound on what the closed form leaves out where it leaves something out.
#include <doctest/doctest.h>

#include <cmath>

#include <glm/geometric.hpp>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <unistd.h>

#include <glm/gtc/type_ptr.hpp>
#include <openvdb/openvdb.h>

#include "core/io/volume_io.h"
#include "core/render/features.h"
#include "core/render/passes.h"
#include "core/render/schedule.h"
#include "core/inverse/gradient_step.h"
#include "render_fixtures.h"
#include "runtime/error.h"
#include "shared/medium.h"
#include "support.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

std::string write_file(const std::string& name, const std::string& text) {
    const std::string p = test::scratch_path(name);
    std::ofstream(p) << text;
    return p;
}

/// A scene: camera at the origin looking along +z with a `fov` degree field of view, res^2
/// pixels, then `body`.
std::string scene_text(const std::string& integrator, float fov, int res, const std::string& body) {
    return "<scene version=\"3.0.0\">\n" + integrator +
           "\n<sensor type=\"perspective\"><float name=\"fov\" value=\"" + std::to_string(fov) +
           "\"/><transform name=\"to_world\"><lookat origin=\"0,0,0\" target=\"0,0,1\" "
           "up=\"0,1,0\"/></transform><film type=\"hdrfilm\"><integer name=\"width\" value=\"" +
           std::to_string(res) + "\"/><integer name=\"height\" value=\"" + std::to_string(res) +
           "\"/></film></sensor>\n" + body + "\n</scene>\n";
}

RenderResult render_text(const std::string& name, const std::string& text, int spp,
                         unsigned seed = 1) {
    Context& ctx = *test::device_context();
    const RenderScene scene = build_render_scene(load_scene(write_file(name, text)));
    DeviceScene device(ctx, KernelLibrary::from_environment(), scene);
    CHECK(device.features().get("HAS_MEDIA") == 1);
    RenderOptions opt;
    opt.spp = spp;
    opt.seed = seed;
    return render_image(device, parameter_buffer(ctx, scene.params), opt);
}

/// A .vol grid of n^3 voxels, every voxel `rgb` (3 channels) or rgb.x (1).
std::string constant_grid(const std::string& name, int n, glm::vec3 rgb, int channels) {
    VolumeGrid g;
    g.width = g.height = g.depth = n;
    g.channels = channels;
    for (std::size_t i = 0; i < g.voxels(); ++i)
        for (int c = 0; c < channels; ++c) g.values.push_back(rgb[c]);
    const std::string path = test::scratch_path(name);
    write_volume(path, g);
    return path;
}

/// The medium of the slab tests, named "slab": homogeneous, or a grid of constant values over
/// the slab's box (x, y in [-100, 100], z in [1, 1 + d]).
std::string slab_medium(bool grid, glm::vec3 sigma_t, glm::vec3 albedo, float d) {
    const auto rgb = [](glm::vec3 v) {
        return std::to_string(v.x) + ", " + std::to_string(v.y) + ", " + std::to_string(v.z);
    };
    if (!grid)
        return "<medium type=\"homogeneous\" id=\"slab\"><rgb name=\"sigma_t\" value=\"" +
               rgb(sigma_t) + "\"/><rgb name=\"albedo\" value=\"" + rgb(albedo) + "\"/></medium>";
    const std::string file = constant_grid("slab.vol", 16, sigma_t, 3);
    return "<medium type=\"heterogeneous\" id=\"slab\"><volume name=\"sigma_t\" "
           "type=\"gridvolume\"><string name=\"filename\" value=\"" + file +
           "\"/><transform name=\"to_world\"><scale x=\"200\" y=\"200\" z=\"" + std::to_string(d) +
           "\"/><translate x=\"-100\" y=\"-100\" z=\"1\"/></transform></volume><rgb "
           "name=\"albedo\" value=\"" + rgb(albedo) + "\"/></medium>";
}

/// The slab's boundary: a cube of null bsdf over x, y in [-100, 100], z in [1, 1 + d].
std::string slab_shape(float d) {
    return "<shape type=\"cube\"><bsdf type=\"null\"/><ref name=\"interior\" id=\"slab\"/>"
           "<transform name=\"to_world\"><scale x=\"100\" y=\"100\" z=\"" + std::to_string(d / 2) +
           "\"/><translate z=\"" + std::to_string(1 + d / 2) + "\"/></transform></shape>";
}

/// E_2(x) = int_0^1 exp(-x / mu) dmu (composite Simpson in mu, 4000 intervals).
double e2(double x) {
    const int n = 4000;
    double sum = 0;
    for (int i = 0; i <= n; ++i) {
        const double mu = double(i) / n;
        const double f = mu > 0 ? std::exp(-x / mu) : 0.0;
        sum += f * (i == 0 || i == n ? 1 : (i % 2 ? 4 : 2));
    }
    return sum / (3.0 * n);
}

/// Radiance along the normal through an infinite slab of thickness d (extinction st, scattering
/// ss, isotropic phase) under a unit sky, up to single scattering: exp(-st d) +
/// ss int_0^d exp(-st z) (E_2(st (d - z)) + E_2(st z)) / 2 dz (Simpson, 400 intervals).
double slab_single_scattering(double st, double ss, double d) {
    const int n = 400;
    double sum = 0;
    for (int i = 0; i <= n; ++i) {
        const double z = d * i / n;
        const double f = std::exp(-st * z) * 0.5 * (e2(st * (d - z)) + e2(st * z));
        sum += f * (i == 0 || i == n ? 1 : (i % 2 ? 4 : 2));
    }
    return std::exp(-st * d) + ss * sum * d / (3.0 * n);
}

/// Checks channel c of r against `expected(x, y)` per pixel.
template <class F> void check_pixels(const RenderResult& r, int c, F expected, double bound,
                                     const char* what) {
    test::DiffStats s;
    for (int y = 0; y < r.height; ++y)
        for (int x = 0; x < r.width; ++x)
            s.add(r.rgb[3 * (std::size_t(y) * r.width + x) + c] - expected(x, y));
    INFO(std::string(what) << " channel " << c << ": mean difference " << s.mean() << ", standard error "
              << s.std_error() << ", bound " << bound);
    CHECK(std::fabs(s.mean()) <= 5.0 * s.std_error() + bound + 1e-6);
}

} // namespace

TEST_SUITE("media") {

TEST_CASE("media: a furnace (albedo 1, any g, chromatic extinction) under a unit sky renders 1") {
    // A ball of non-absorbing medium behind a null boundary, unbounded depth: every pixel's
    // expectation is 1 in every channel, whatever scatters.
    for (const char* phase : {"<phase type=\"isotropic\"/>",
                              "<phase type=\"hg\"><float name=\"g\" value=\"0.7\"/></phase>",
                              "<phase type=\"hg\"><float name=\"g\" value=\"-0.9\"/></phase>"}) {
        CAPTURE(phase);
        const std::string body =
            "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"1\"/></emitter>"
            "<medium type=\"homogeneous\" id=\"fog\"><rgb name=\"sigma_t\" value=\"1, 3, 6\"/>"
            "<float name=\"albedo\" value=\"1\"/>" + std::string(phase) + "</medium>"
            "<shape type=\"sphere\"><point name=\"center\" x=\"0\" y=\"0\" z=\"4\"/>"
            "<bsdf type=\"null\"/><ref name=\"interior\" id=\"fog\"/></shape>";
        const RenderResult r =
            render_text("furnace.xml", scene_text("<integrator type=\"volpath\"/>", 35, 24, body), 64);
        CHECK(r.nan_guards == 0);
        for (int c = 0; c < 3; ++c) check_pixels(r, c, [](int, int) { return 1.0; }, 0.0, "furnace");
    }
}

TEST_CASE("media: the two-state path sees the furnace in both states (another g, a denser old state)") {
    // The furnace of the test above under CV-PS: the old state scatters less forward (g 0.5
    // against the new state's 0.7) through a medium 1.2 times as dense. Each state's image is 1
    // per pixel in expectation; an old state that took the new state's phase for the new state's
    // directions, or a majorant that bounded the new state alone, would not be (the former is
    // 20 standard errors off). (Far apart states make H heavy-tailed: each scattering multiplies
    // the old throughput by p_old / p_new, and over the dozens of collisions of a dense medium
    // the product's mean 1 comes from rare large values: with g -0.7 against 0.7 and twice the
    // density, 16384 spp still fall 2-5 % short. The control weight alpha then shrinks; over an
    // optimizer step the states differ by far less.)
    const std::string body =
        "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"1\"/></emitter>"
        "<medium type=\"homogeneous\" id=\"fog\"><rgb name=\"sigma_t\" value=\"1, 1.5, 2\"/>"
        "<float name=\"albedo\" value=\"1\"/><phase type=\"hg\"><float name=\"g\" "
        "value=\"0.7\"/></phase></medium><shape type=\"sphere\"><point name=\"center\" x=\"0\" "
        "y=\"0\" z=\"4\"/><bsdf type=\"null\"/><ref name=\"interior\" id=\"fog\"/></shape>";
    Context& ctx = *test::device_context();
    const RenderScene scene = build_render_scene(load_scene(
        write_file("furnace2.xml", scene_text("<integrator type=\"volpath\"/>", 35, 24, body))));
    DeviceScene device(ctx, KernelLibrary::from_environment(), scene);
    std::vector<float> old = scene.params.values();
    old[scene.params.find("fog.g").offset] = 0.5f;
    old[scene.params.find("fog.scale").offset] = 1.2f;
    const Buffer<float> now = parameter_buffer(ctx, scene.params), before(ctx, "old", old);
    Buffer<float> f(ctx, "f", 3 * 24 * 24), h(ctx, "h", 3 * 24 * 24);
    render_two_state(device, now, before, 5, 1024, f, h);
    CHECK(device.read_guards() == 0);
    for (const auto& [image, what] : {std::pair<const Buffer<float>*, const char*>{&f, "F"}, {&h, "H"}}) {
        const std::vector<float> v = image->download();
        for (int c = 0; c < 3; ++c) {
            test::DiffStats s;
            for (std::size_t i = 0; i < 24 * 24; ++i) s.add(v[3 * i + c] - 1.0);
            INFO(std::string(what) << " channel " << c << ": mean difference " << s.mean() << ", standard error " << s.std_error());
            CHECK(std::fabs(s.mean()) <= 5.0 * s.std_error() + 1e-6);
        }
    }
}

TEST_CASE("media: transmittance through a slab is exp(-sigma_t d / cos), homogeneous and grid") {
    // Pure absorption (albedo 0), chromatic: spectral tracking draws distances from the largest
    // channel and weighs the others by their null collisions. An area light of radiance 1 behind
    // the slab; each pixel's expectation is the mean of exp(-sigma_t d / cos theta) over its area
    // (8 x 8 points per pixel: the remaining error is below 1e-6 at this field of view).
    const float d = 0.75f;
    const glm::vec3 sigma_t(0.5f, 1.0f, 2.0f);
    const std::string light =
        "<shape type=\"rectangle\"><transform name=\"to_world\"><rotate x=\"1\" angle=\"180\"/>"
        "<scale value=\"50\"/><translate z=\"3\"/></transform><emitter type=\"area\"><rgb "
        "name=\"radiance\" value=\"1\"/></emitter></shape>";
    for (bool grid : {false, true}) {
        CAPTURE(grid);
        const std::string text =
            scene_text("<integrator type=\"volpath\"/>", 20, 16,
                       slab_medium(grid, sigma_t, glm::vec3(0.0f), d) + slab_shape(d) + light);
        const RenderResult r = render_text("slab-t.xml", text, 64);
        CHECK(r.nan_guards == 0);
        const gpu::DeviceCamera cam = build_render_scene(load_scene(test::scratch_path("slab-t.xml"))).camera();
        for (int c = 0; c < 3; ++c)
            check_pixels(r, c, [&](int x, int y) {
                double sum = 0;
                for (int j = 0; j < 8; ++j)
                    for (int i = 0; i < 8; ++i) {
                        const double sx = 1 - 2 * (x + (i + 0.5) / 8) / cam.width;
                        const double sy = 1 - 2 * (y + (j + 0.5) / 8) / cam.height;
                        const double vx = cam.dir_x.x * sx + cam.dir_y.x * sy;
                        const double vy = cam.dir_x.y * sx + cam.dir_y.y * sy;
                        const double cos_t = 1.0 / std::sqrt(1.0 + vx * vx + vy * vy);
                        sum += std::exp(-double(sigma_t[c]) * d / cos_t);
                    }
                return sum / 64.0;
            }, 1e-6, grid ? "grid slab" : "homogeneous slab");
    }
}

TEST_CASE("media: transmittance through a random grid is exp(-integral of sigma_t), rays across its cells") {
    // Pure absorption in a 12 x 10 x 9 grid of random chromatic densities (a 2 x 2 x 2 majorant
    // grid whose cells differ), seen obliquely against an area light: the free flights walk the
    // majorant cells (DDA) and must see the trilinear density, cell by cell. Expected per pixel:
    // the mean over 4 x 4 rays of exp(-int sigma_t dt), the integral by the midpoint rule on 4000
    // steps through the grid (on the host, with the kernels' own grid_eval): its error is far
    // below the noise, bound 1e-4.
    VolumeGrid g;
    g.width = 12;
    g.height = 10;
    g.depth = 9;
    g.channels = 3;
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (std::size_t i = 0; i < g.voxels() * 3; ++i) g.values.push_back(u(rng) * u(rng) * 3.0f);
    write_volume(test::scratch_path("random.vol"), g);
    const std::string text = scene_text(
        "<integrator type=\"volpath\"/>", 30, 12,
        "<medium type=\"heterogeneous\" id=\"m\"><volume name=\"sigma_t\" type=\"gridvolume\">"
        "<string name=\"filename\" value=\"random.vol\"/><transform name=\"to_world\">"
        "<translate value=\"-0.5, -0.5, -0.5\"/><rotate y=\"1\" angle=\"30\"/><rotate x=\"1\" "
        "angle=\"20\"/><scale value=\"1.2\"/><translate z=\"3\"/></transform></volume>"
        "<float name=\"albedo\" value=\"0\"/></medium>"
        "<shape type=\"sphere\"><point name=\"center\" x=\"0\" y=\"0\" z=\"3\"/><float "
        "name=\"radius\" value=\"1.2\"/><bsdf type=\"null\"/><ref name=\"interior\" id=\"m\"/></shape>"
        "<shape type=\"rectangle\"><transform name=\"to_world\"><rotate x=\"1\" angle=\"180\"/>"
        "<scale value=\"20\"/><translate z=\"8\"/></transform><emitter type=\"area\"><rgb "
        "name=\"radiance\" value=\"1\"/></emitter></shape>");
    const RenderResult r = render_text("random.xml", text, 64);
    CHECK(r.nan_guards == 0);
    const RenderScene rs = build_render_scene(load_scene(test::scratch_path("random.xml")));
    const gpu::DeviceCamera cam = rs.camera();
    const gpu::DeviceGrid grid = rs.grids[rs.media[0].sigma_t_grid];
    const float* data = rs.params.values().data(); // the grid is a parameter
    // optical depth along the ray from the origin with unit direction d, inside the grid's cube
    const auto depth = [&](glm::dvec3 d, int c) {
        const double t_max = 8.0;
        const int n = 4000;
        double sum = 0;
        for (int i = 0; i < n; ++i) {
            const double t = (i + 0.5) * t_max / n;
            const gpu::float3 x = gpu::make_float3(float(d.x * t), float(d.y * t), float(d.z * t));
            const gpu::float3 l = gpu::grid_local(&grid, x);
            if (l.x < 0 || l.x > 1 || l.y < 0 || l.y > 1 || l.z < 0 || l.z > 1) continue;
            sum += gpu::grid_eval(data, &grid, l, unsigned(c));
        }
        return sum * t_max / n;
    };
    for (int c = 0; c < 3; ++c)
        check_pixels(r, c, [&](int x, int y) {
            double sum = 0;
            for (int j = 0; j < 4; ++j)
                for (int i = 0; i < 4; ++i) {
                    const double sx = 1 - 2 * (x + (i + 0.5) / 4) / cam.width;
                    const double sy = 1 - 2 * (y + (j + 0.5) / 4) / cam.height;
                    const glm::dvec3 v(cam.dir_z.x + cam.dir_x.x * sx + cam.dir_y.x * sy,
                                       cam.dir_z.y + cam.dir_x.y * sx + cam.dir_y.y * sy,
                                       cam.dir_z.z + cam.dir_x.z * sx + cam.dir_y.z * sy);
                    sum += std::exp(-depth(glm::normalize(v), c));
                }
            return sum / 16.0;
        }, 1e-4, "random grid");
}

TEST_CASE("media: single scattering in a slab under a sky matches its closed form") {
    // max_depth 2: the camera ray's transmission and one scattering vertex (NEE through the
    // medium to the sky, MIS with the phase sample). The closed form is for rays along the normal
    // of an infinite slab; the pixels are within 0.36 degrees of it (fov 0.5), which changes the
    // path lengths by less than 2e-5 relative, and the slab is 200 wide (what leaves it sideways
    // crosses at least 100 of medium: exp(-50) and less). Bound 1e-4 on both.
    const float d = 1.0f;
    const glm::vec3 sigma_t(0.5f, 1.0f, 2.0f), albedo(0.9f, 0.5f, 0.8f);
    const std::string sky = "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"1\"/></emitter>";
    for (bool grid : {false, true}) {
        CAPTURE(grid);
        const std::string text =
            scene_text("<integrator type=\"volpath\"><integer name=\"max_depth\" value=\"2\"/></integrator>",
                       0.5f, 32, slab_medium(grid, sigma_t, albedo, d) + slab_shape(d) + sky);
        // 8192 spp on 32^2 pixels: a standard error of about 2.5e-4, so that a bias of 0.2 %
        // (what random numbers correlated with the light sample made) is beyond 5 of them
        const RenderResult r = render_text("slab-s.xml", text, 8192);
        CHECK(r.nan_guards == 0);
        for (int c = 0; c < 3; ++c) {
            const double expected = slab_single_scattering(sigma_t[c], sigma_t[c] * albedo[c], d);
            check_pixels(r, c, [&](int, int) { return expected; }, 1e-4,
                         grid ? "grid slab" : "homogeneous slab");
        }
    }
}

TEST_CASE("media: renders are bit-identical for a seed, and extreme media give no NaN") {
    const std::string body =
        "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"1\"/></emitter>"
        "<medium type=\"homogeneous\" id=\"m\"><rgb name=\"sigma_t\" value=\"$st\"/>"
        "<float name=\"albedo\" value=\"$a\"/><phase type=\"hg\"><float name=\"g\" value=\"$g\"/>"
        "</phase></medium><shape type=\"sphere\"><point name=\"center\" x=\"0\" y=\"0\" z=\"4\"/>"
        "<bsdf type=\"null\"/><ref name=\"interior\" id=\"m\"/></shape>"
        "<shape type=\"rectangle\"><transform name=\"to_world\"><translate z=\"6\"/></transform>"
        "<bsdf type=\"diffuse\"/></shape>";
    const std::string head = "<default name=\"st\" value=\"1\"/><default name=\"a\" value=\"0.5\"/>"
                             "<default name=\"g\" value=\"0.5\"/>";
    const std::string path = write_file("extreme.xml", scene_text("<integrator type=\"volpath\"/>", 40, 12, head + body));
    Context& ctx = *test::device_context();
    for (const char* st : {"1e-6", "1e4", "1"})
        for (const char* a : {"0", "1"})
            for (const char* g : {"0.9", "-0.9"}) {
                CAPTURE(st);
                CAPTURE(a);
                CAPTURE(g);
                const RenderScene scene = build_render_scene(load_scene(path, {{"st", st}, {"a", a}, {"g", g}}));
                DeviceScene device(ctx, KernelLibrary::from_environment(), scene);
                RenderOptions opt;
                opt.spp = 8;
                const RenderResult r = render_image(device, parameter_buffer(ctx, scene.params), opt);
                CHECK(r.nan_guards == 0);
                bool finite = true;
                for (float v : r.rgb) finite = finite && std::isfinite(v) && v >= 0.0f;
                CHECK(finite);
                if (std::string(st) == "1" && std::string(a) == "1") {
                    const RenderResult again = render_image(device, parameter_buffer(ctx, scene.params), opt);
                    CHECK(test::same_bytes(r.rgb, again.rgb));
                }
            }
}

TEST_CASE("media: a walk that gives up (too many collisions or null crossings) is dropped and counted") {
    // A chromatic medium sigma_t (1e6, 1, 1), albedo 1: after its first null collision the red
    // weight is 0, and spectral tracking then scatters with probability ~1e-6 per collision, so a
    // free flight through the ball draws more than MEDIA_MAX_DRAWS. And 70 null planes in a row,
    // more than MEDIA_MAX_CROSSINGS. Either way the sample is dropped (never a NaN pixel) and
    // counted in the guards, as a non-finite one.
    const std::string sky = "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"1\"/></emitter>";
    const RenderResult dense = render_text(
        "give-up-draws.xml",
        scene_text("<integrator type=\"volpath\"/>", 20, 6,
                   sky + "<medium type=\"homogeneous\" id=\"m\"><rgb name=\"sigma_t\" "
                         "value=\"1e6, 1, 1\"/><float name=\"albedo\" value=\"1\"/></medium>"
                         "<shape type=\"sphere\"><point name=\"center\" x=\"0\" y=\"0\" z=\"4\"/>"
                         "<bsdf type=\"null\"/><ref name=\"interior\" id=\"m\"/></shape>"),
        2);
    std::string planes;
    for (int i = 0; i < 70; ++i)
        planes += "<shape type=\"rectangle\"><transform name=\"to_world\"><scale value=\"5\"/>"
                  "<translate z=\"" + std::to_string(2 + 0.05 * i) + "\"/></transform>"
                  "<bsdf type=\"null\"/></shape>";
    const RenderResult crossings = render_text(
        "give-up-crossings.xml", scene_text("<integrator type=\"volpath\"/>", 20, 6, sky + planes), 2);
    for (const RenderResult* r : {&dense, &crossings}) {
        CHECK(r->nan_guards > 0);
        bool finite = true;
        for (float v : r->rgb) finite = finite && std::isfinite(v) && v >= 0.0f;
        CHECK(finite);
    }
    CHECK(crossings.nan_guards == 6u * 6u * 2u); // every path crosses them all
}

TEST_CASE("media: the majorant grid bounds the trilinear interpolant in every cell") {
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> value(0.0f, 4.0f), unit(0.0f, 1.0f);
    const unsigned nx = 11, ny = 7, nz = 9, channels = 3, cx = 3, cy = 2, cz = 4;
    std::vector<float> values(std::size_t(nx) * ny * nz * channels);
    for (float& v : values) v = value(rng) * value(rng) * value(rng); // spiky
    const std::vector<float> bounds = build_majorant_grid(values, nx, ny, nz, channels, cx, cy, cz);
    gpu::DeviceGrid g{};
    g.nx = nx;
    g.ny = ny;
    g.nz = nz;
    g.channels = channels;
    int violations = 0;
    for (int i = 0; i < 200000; ++i) {
        const gpu::float3 l = gpu::make_float3(unit(rng), unit(rng), unit(rng));
        const unsigned x = std::min(cx - 1, unsigned(l.x * cx)), y = std::min(cy - 1, unsigned(l.y * cy)),
                       z = std::min(cz - 1, unsigned(l.z * cz));
        const float bound = bounds[(std::size_t(z) * cy + y) * cx + x];
        for (unsigned c = 0; c < channels; ++c)
            if (gpu::grid_eval(values.data(), &g, l, c) > bound * (1.0f + 1e-6f)) ++violations;
    }
    CHECK(violations == 0);
    // and it is not vacuous: no cell's bound exceeds the grid's maximum
    CHECK(*std::max_element(bounds.begin(), bounds.end()) <= *std::max_element(values.begin(), values.end()));
}

TEST_CASE("media: ReSTIR refuses scenes with media, and the scheduler fuses the two-state render") {
    const std::string text = scene_text(
        "<integrator type=\"prbvolpath\"/>", 30, 8,
        "<emitter type=\"constant\"><rgb name=\"radiance\" value=\"1\"/></emitter>"
        "<medium type=\"homogeneous\" id=\"m\"/><shape type=\"sphere\"><point name=\"center\" "
        "x=\"0\" y=\"0\" z=\"4\"/><bsdf type=\"null\"/><ref name=\"interior\" id=\"m\"/></shape>");
    Context& ctx = *test::device_context();
    const RenderScene scene = build_render_scene(load_scene(write_file("refuse.xml", text)));
    DeviceScene device(ctx, KernelLibrary::from_environment(), scene);
    CHECK_THROWS_WITH_AS(require_surfaces(device, "light-sample reuse (ReSTIR)"),
                         doctest::Contains("does not cover participating media"), Error);
    // plain replay, CV-PSS and CV-PS are built
    for (CvMode mode : {CvMode::none, CvMode::pss, CvMode::ps})
        GradientStep(device, KernelLibrary::from_environment(), 0,
                     std::vector<float>(8 * 8 * 3, 0.0f), mode);
    std::string reason;
    const Parameter& sigma = scene.params.find("m.sigma_t");
    CHECK(plan_cv(CvMode::ps, {&sigma}, &reason) == CvMode::ps);
}

TEST_CASE("media: the scene format, and its errors name the file and line") {
    const std::string grid = constant_grid("ok.vol", 4, glm::vec3(1.0f), 1);
    const auto load = [&](const std::string& body) {
        return load_scene(write_file("fmt.xml", "<scene version=\"3.0.0\">\n" + body + "\n</scene>\n"));
    };
    const auto error = [&](const std::string& body) -> std::string {
        try {
            build_render_scene(load(body + "<shape type=\"rectangle\"/>"));
        } catch (const Error& e) {
            return e.what();
        }
        return "";
    };
    const std::string ball = "<shape type=\"sphere\"><bsdf type=\"null\"/>";
    // a top-level medium by reference, an inline one, the sensor's, Mitsuba's defaults
    const SceneDesc d = load(
        "<medium type=\"homogeneous\" id=\"fog\"><float name=\"scale\" value=\"2\"/>"
        "<phase type=\"hg\"/></medium>\n"
        "<sensor type=\"perspective\"><ref id=\"fog\"/></sensor>\n" + ball +
        "<ref name=\"interior\" id=\"fog\"/><medium type=\"heterogeneous\" name=\"exterior\">"
        "<volume name=\"sigma_t\" type=\"gridvolume\"><string name=\"filename\" value=\"" + grid +
        "\"/></volume></medium></shape>");
    REQUIRE(d.media.size() == 2);
    CHECK(d.media[0].albedo.value == glm::vec3(0.75f)); // Mitsuba's default albedo
    CHECK(d.media[0].g == doctest::Approx(0.8f));         // and hg's default g
    CHECK(d.sensors[0].medium == 0);
    CHECK(d.shapes[0].interior == 0);
    CHECK(d.shapes[0].exterior == 1);
    const RenderScene rs = build_render_scene(d);
    CHECK(rs.media[0].sigma_t.w == 2.0f); // the scale (the kernel applies it: medium_load)
    CHECK(rs.media[1].kind == MEDIUM_GRID);
    CHECK(rs.cameras[0].medium == 0u);
    CHECK(rs.infos[0].interior == 0u);
    // a null bsdf has no parameters; each medium has sigma_t, albedo, scale (and g for hg), named
    // by id, else by index; a grid's voxels are one parameter
    std::string names;
    for (const Parameter& p : rs.params.parameters())
        names += p.name + "/" + parameter_kind_name(p.kind) + "/" + std::to_string(p.size) + " ";
    CHECK(names == "fog.sigma_t/rgb/3 fog.albedo/rgb/3 fog.scale/scalar/1 fog.g/scalar/1 "
                   "medium1.sigma_t/volume/64 medium1.albedo/rgb/3 medium1.scale/scalar/1 ");
    CHECK(rs.params.find("medium1.sigma_t").depth == 4);
    CHECK(rs.grids[rs.media[1].sigma_t_grid].offset == rs.params.find("medium1.sigma_t").offset);

    CHECK(error("<medium type=\"fog\" id=\"m\"/>").find("fmt.xml:2: <medium type=\"fog\">: unsupported medium type") != std::string::npos);
    CHECK(error("<medium type=\"homogeneous\"/>").find("fmt.xml:2: <medium>: a medium at scene level needs an id") != std::string::npos);
    CHECK(error(ball + "<ref name=\"interior\" id=\"none\"/></shape>").find("fmt.xml:2: <ref id=\"none\">: unknown id") != std::string::npos);
    CHECK(error(ball + "<medium type=\"homogeneous\" name=\"inside\"/></shape>").find("named \"interior\" or \"exterior\", not \"inside\"") != std::string::npos);
    CHECK(error("<medium type=\"homogeneous\" id=\"m\"><phase type=\"hg\"><float name=\"g\" value=\"1\"/></phase></medium>").find("g must be in (-1, 1)") != std::string::npos);
    CHECK(error("<medium type=\"homogeneous\" id=\"m\"><float name=\"sigma_t\" value=\"-1\"/></medium>").find("sigma_t must be finite and >= 0") != std::string::npos);
    CHECK(error("<medium type=\"homogeneous\" id=\"m\"><float name=\"albedo\" value=\"1.5\"/></medium>").find("albedo must be in [0, 1]") != std::string::npos);
    CHECK(error("<medium type=\"homogeneous\" id=\"m\"><volume name=\"sigma_t\" type=\"gridvolume\"><string name=\"filename\" value=\"" + grid + "\"/></volume></medium>").find("a homogeneous medium takes constant values only") != std::string::npos);
    std::ofstream(test::scratch_path("smoke.vdb")) << "x";
    const std::string not_vdb = error("<medium type=\"heterogeneous\" id=\"m\"><volume name=\"sigma_t\" type=\"gridvolume\"><string name=\"filename\" value=\"smoke.vdb\"/></volume></medium>");
    CHECK(not_vdb.find("fmt.xml:2: medium 'm': sigma_t: ") != std::string::npos);
    CHECK(not_vdb.find("smoke.vdb: OpenVDB cannot read it") != std::string::npos);
    // grids: not a .vol file, a negative density, an albedo above 1 (named by file and voxel)
    std::ofstream(test::scratch_path("junk.vol")) << "not a volume";
    const std::string junk = error("<medium type=\"heterogeneous\" id=\"m\"><volume name=\"sigma_t\" type=\"gridvolume\"><string name=\"filename\" value=\"junk.vol\"/></volume></medium>");
    CHECK(junk.find("fmt.xml:2: medium 'm': sigma_t: ") != std::string::npos);
    CHECK(junk.find("junk.vol") != std::string::npos);
    VolumeGrid bad;
    bad.width = bad.height = bad.depth = 2;
    bad.values.assign(8, 1.0f);
    bad.values[5] = -0.5f;
    write_volume(test::scratch_path("negative.vol"), bad);
    CHECK(error("<medium type=\"heterogeneous\" id=\"m\"><volume name=\"sigma_t\" type=\"gridvolume\"><string name=\"filename\" value=\"negative.vol\"/></volume></medium>").find("voxel (1, 0, 1) is -0.5") != std::string::npos);
    bad.values[5] = 1.5f;
    write_volume(test::scratch_path("bright.vol"), bad);
    CHECK(error("<medium type=\"heterogeneous\" id=\"m\"><volume name=\"albedo\" type=\"gridvolume\"><string name=\"filename\" value=\"bright.vol\"/></volume></medium>").find("albedo: ") != std::string::npos);
    CHECK(error("<integrator type=\"bdpt\"/>").find("unsupported integrator type 'bdpt'") != std::string::npos);
}

TEST_CASE("media: an OpenVDB grid reads as the dense block of its active voxels, placed by its transform") {
    // a float grid "density" with active voxels in index [2, 5] x [-1, 1] x [3, 3] (one voxel
    // deep: widened to two), voxel size 0.25, translated; and a vec3s grid that is not chosen
    openvdb::initialize();
    openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.0f);
    density->setName("density");
    density->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
    density->transform().postTranslate(openvdb::Vec3d(1.0, -2.0, 0.5));
    auto access = density->getAccessor();
    for (int x = 2; x <= 5; ++x)
        for (int y = -1; y <= 1; ++y) access.setValue(openvdb::Coord(x, y, 3), float(x + 10 * y + 100));
    openvdb::Vec3SGrid::Ptr colour = openvdb::Vec3SGrid::create();
    colour->setName("colour");
    colour->getAccessor().setValue(openvdb::Coord(0, 0, 0), openvdb::Vec3s(1, 2, 3));
    const std::string path = test::scratch_path("density.vdb");
    openvdb::io::File(path).write({colour, density});

    const VolumeGrid g = read_volume(path);
    CHECK(g.width == 4);
    CHECK(g.height == 3);
    CHECK(g.depth == 2);
    CHECK(g.channels == 1);
    CHECK(g.at(0, 0, 0) == -10.0f + 102.0f); // index (2, -1, 3)
    CHECK(g.at(3, 2, 0) == 5.0f + 10.0f + 100.0f);
    CHECK(g.at(3, 2, 1) == 0.0f); // the widened layer: the background
    REQUIRE(g.placed);
    // voxel (i, j, k)'s centre, at ((i, j, k) + 1/2) / n in the unit cube, lands where OpenVDB
    // puts index lo + (i, j, k)
    const glm::mat4 to_world = glm::make_mat4(g.to_world.data());
    for (const glm::ivec3 v : {glm::ivec3(0, 0, 0), glm::ivec3(3, 2, 1), glm::ivec3(1, 2, 0)}) {
        const glm::vec4 unit((v.x + 0.5f) / g.width, (v.y + 0.5f) / g.height, (v.z + 0.5f) / g.depth, 1.0f);
        const glm::vec4 world = to_world * unit;
        const openvdb::Vec3d expected = density->indexToWorld(openvdb::Coord(2 + v.x, -1 + v.y, 3 + v.z));
        for (int a = 0; a < 3; ++a) CHECK(world[a] == doctest::Approx(expected[a]).epsilon(1e-6));
    }
    // the device grid is placed by the file's transform, then the volume's to_world
    const std::string text = scene_text("<integrator type=\"volpath\"/>", 30, 4,
        "<medium type=\"heterogeneous\" id=\"m\"><volume name=\"sigma_t\" type=\"gridvolume\">"
        "<string name=\"filename\" value=\"density.vdb\"/><transform name=\"to_world\">"
        "<translate z=\"4\"/></transform></volume></medium><shape type=\"sphere\">"
        "<bsdf type=\"null\"/><ref name=\"interior\" id=\"m\"/></shape>");
    const RenderScene rs = build_render_scene(load_scene(write_file("vdb.xml", text)));
    const gpu::DeviceGrid dg = rs.grids[rs.media[0].sigma_t_grid];
    const openvdb::Vec3d centre = density->indexToWorld(openvdb::Coord(2, -1, 3)) + openvdb::Vec3d(0, 0, 4);
    const gpu::float3 l = gpu::grid_local(&dg, gpu::make_float3(float(centre.x()), float(centre.y()), float(centre.z())));
    CHECK(l.x == doctest::Approx(0.5f / 4));
    CHECK(l.y == doctest::Approx(0.5f / 3));
    CHECK(l.z == doctest::Approx(0.5f / 2));
    // a file without a float or vec3s grid, and one whose density is not finite
    openvdb::Int32Grid::Ptr ints = openvdb::Int32Grid::create();
    ints->getAccessor().setValue(openvdb::Coord(0, 0, 0), 1);
    openvdb::io::File(test::scratch_path("ints.vdb")).write({ints});
    CHECK_THROWS_WITH_AS(read_volume(test::scratch_path("ints.vdb")),
                         doctest::Contains("no float or vec3s grid"), Error);
    access.setValue(openvdb::Coord(4, 0, 3), std::numeric_limits<float>::quiet_NaN());
    openvdb::io::File(test::scratch_path("nan.vdb")).write({density});
    CHECK_THROWS_WITH_AS(read_volume(test::scratch_path("nan.vdb")),
                         doctest::Contains("a non-finite value at voxel (2, 1, 0)"), Error);
}

} // TEST_SUITE
