// Shape gradients (kernels/boundary.cl, core/render/boundary.h): the primary boundary term against
// a closed form, the translation it implies, and determinism.
//
// The scene (tests/scenes/shape-emitter-black.xml, Mitsuba's TranslateRectangleEmitterOnBlack): a
// 2 x 2 square area light of radiance 1 on black in the plane z = 0, seen from z = 4 with a square
// film whose field of view spans the square [-a, a]^2 of that plane, a = 4 tan(fov / 2), and
// centred at x = 1.25, so that its right part lies outside the view. The mean image (the mean
// loss, over pixels and channels) is the fraction of the film it covers,
//     F = (a - (x - 1)) * 2 / (2 a)^2   (its left edge at x - 1 inside the view, all of its height),
// which no interior term changes (the light's radiance is the same everywhere on it). So
//     dF/dx = -2 / (2a)^2,
// and moving it toward the camera (z) scales its image about the film's centre: with D = 4 - z,
// the film fraction is (1 - l) h / 2 for l = (x - 1) / (D tan) and h = 1 / (D tan), so
//     dF/dz = -dF/dD = h (1 - 2 l) / (2 D).
// The sum of the per-vertex gradients is the derivative of that rigid shift; each corner's own y
// gradient tilts an edge (below). Each check compares
// the mean over K = 16 seeds with the closed form within 4 standard errors measured from them (a
// t distribution with 15 degrees of freedom puts 4 at a two-sided 0.1 %), and requires the
// standard error to stay below 2 % of the value, so that a missing factor (a pdf, the edge
// parameter's weights, the Jacobian's sign) cannot hide in the noise.
#include <doctest/doctest.h>

#include <cmath>
#include <memory>

#include "core/inverse/session.h"
#include "inverse_fixtures.h"
#include "support.h"

using namespace tandem;

namespace {

std::string test_scene(const char* name) {
    return std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/" + name;
}

/// The sum over vertices of the gradient of `name` (the derivative of a rigid shift).
std::array<double, 3> translation(const std::vector<float>& g, const Parameter& p) {
    std::array<double, 3> t{0, 0, 0};
    for (std::size_t i = 0; i < p.size; ++i) t[i % 3] += g[p.offset + i];
    return t;
}

} // namespace

TEST_CASE("shape: the primary boundary term matches the covered area's derivative") {
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene("shape-emitter-black.xml"),
                    {{"res", "32"}});
    const Parameter& p = session.parameter("light.vertex_positions");
    REQUIRE(p.kind == Parameter::Kind::vertices);
    REQUIRE(p.moves_geometry());
    const double tan_half = std::tan(34.0207 * M_PI / 360.0), a = 4.0 * tan_half;
    const double x = 1.25, D = 4.0;
    const double dfdx = -2.0 / (4.0 * a * a);
    const double l = (x - 1.0) / (D * tan_half), h = 1.0 / (D * tan_half);
    const double dfdz = h * (1.0 - 2.0 * l) / (2.0 * D);
    // Per vertex: raising a top corner by dy tilts the top edge, whose visible part x in
    // [x - 1, a] (length w) gains the area dy * integral of its weight there: (1 - s / 2) ds for
    // the left corner, s / 2 ds for the right one (s = x - (x - 1)), so w - w^2 / 4 and w^2 / 4;
    // a bottom corner loses as much. The left edge only slides along itself.
    const double w = a - (x - 1.0);
    const std::vector<float> corners = session.value(p);
    std::array<double, 4> dfdy{};
    for (int v = 0; v < 4; ++v) {
        const bool left = corners[3 * v] < x, top = corners[3 * v + 1] > 0.0f;
        dfdy[v] = (top ? 1.0 : -1.0) * (left ? w - w * w / 4.0 : w * w / 4.0) / (4.0 * a * a);
    }
    test::Stat sx, sy, sz, corner[4];
    for (std::uint32_t seed = 0; seed < 16; ++seed) {
        const Session::GradResult r = session.grad("mean", {}, {&p}, 4, 4, seed);
        const std::array<double, 3> t = translation(r.gradient, p);
        sx.add(t[0]);
        sy.add(t[1]);
        sz.add(t[2]);
        for (int v = 0; v < 4; ++v) corner[v].add(r.gradient[p.offset + 3 * v + 1]);
    }
    for (int v = 0; v < 4; ++v) {
        INFO("corner " << v << " dF/dy: " << corner[v].mean() << " +- " << corner[v].se()
                       << " (closed form " << dfdy[v] << ")");
        CHECK(std::abs(corner[v].mean() - dfdy[v]) <= 4.0 * corner[v].se());
        CHECK(corner[v].se() < 0.05 * std::abs(dfdy[v]));
    }
    INFO("x: " << sx.mean() << " +- " << sx.se() << " (closed form " << dfdx << ")");
    INFO("y: " << sy.mean() << " +- " << sy.se() << " (closed form 0)");
    INFO("z: " << sz.mean() << " +- " << sz.se() << " (closed form " << dfdz << ")");
    CHECK(std::abs(sx.mean() - dfdx) <= 4.0 * sx.se());
    CHECK(sx.se() < 0.02 * std::abs(dfdx));
    CHECK(std::abs(sz.mean() - dfdz) <= 4.0 * sz.se());
    CHECK(sz.se() < 0.02 * std::abs(dfdz));
    CHECK(std::abs(sy.mean()) <= 4.0 * sy.se());
}

TEST_CASE("shape: boundary gradients are bit-identical run to run, and zero for a still shape") {
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene("shape-emitter-black.xml"),
                    {{"res", "16"}});
    const Parameter& p = session.parameter("light.vertex_positions");
    const Parameter& radiance = session.parameter("light.emitter.radiance");
    const std::vector<float> a = session.grad("mean", {}, {&p}, 2, 2, 7).gradient;
    const std::vector<float> b = session.grad("mean", {}, {&p}, 2, 2, 7).gradient;
    CHECK(test::same_bytes(a, b));
    // differentiating the radiance alone takes no boundary term: the vertices' gradients stay 0
    const std::vector<float> c = session.grad("mean", {}, {&radiance}, 2, 2, 7).gradient;
    for (std::size_t i = 0; i < p.size; ++i) CHECK(c[p.offset + i] == 0.0f);
}

TEST_CASE("shape: assigned vertex positions move what is traced and where edges are sampled") {
    Context* ctx = test::device_context();
    Session moved(*ctx, KernelLibrary::from_environment(), test_scene("shape-emitter-black.xml"),
                  {{"res", "16"}});
    Session there(*ctx, KernelLibrary::from_environment(), test_scene("shape-emitter-black.xml"),
                  {{"res", "16"}, {"x", "1"}});
    const Parameter& p = moved.parameter("light.vertex_positions");
    std::vector<float> v = moved.value(p);
    // two steps, each exact (the corners are dyadic): the first rebuilds the tree, the second
    // refits it, and traces what a tree built there traces
    for (float dx : {-0.5f, 0.25f}) {
        for (std::size_t i = 0; i < v.size(); i += 3) v[i] += dx;
        moved.set_value(p, FloatSpan{v.data(), v.size()});
        moved.render(1, 0);
    }
    CHECK(moved.device_scene().bvh_updates().builds == 2);
    CHECK(moved.device_scene().bvh_updates().refits == 1);
    CHECK(test::same_bytes(moved.render(4, 3), there.render(4, 3)));
    const Parameter& q = there.parameter("light.vertex_positions");
    CHECK(test::same_bytes(moved.grad("mean", {}, {&p}, 2, 2, 5).gradient,
                           there.grad("mean", {}, {&q}, 2, 2, 5).gradient));
    // a non-finite position is refused with the shape's name: by an assignment, and where a
    // whole layout (a bad optimizer step's, say) reaches the passes, before anything is traced
    v[4] = std::nanf("");
    CHECK_THROWS_WITH_AS(moved.set_value(p, FloatSpan{v.data(), v.size()}),
                         doctest::Contains("light.vertex_positions"), Error);
    std::vector<float> all = moved.state().theta().download();
    all[p.offset + 4] = std::nanf("");
    moved.set_values(all);
    CHECK_THROWS_WITH_AS(moved.render(1, 0), doctest::Contains("light.vertex_positions: vertex 1"),
                         Error);
}

// A refit keeps the tree's topology (DeviceScene::sync_geometry): a small step refits it, but
// where the occluder is stretched across the wall (alternate vertices 2 units left and right: its
// triangles' boxes span the scene) the refit tree's SAH cost grows past the rebuild threshold and
// the tree is built anew.
TEST_CASE("shape: a small step refits the tree, one that stretches a shape across the scene "
          "rebuilds it") {
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene("shape-shadow.xml"), {});
    const Parameter& p = session.parameter("occluder.vertex_positions");
    const auto step = [&](std::vector<float> w) {
        session.set_value(p, FloatSpan{w.data(), w.size()});
        session.render(1, 0);
        return session.device_scene().bvh_updates();
    };
    std::vector<float> v = session.value(p);
    for (float& x : v) x += 0.001f;
    DeviceScene::BvhUpdates u = step(v); // the first change: no tree kept from construction
    CHECK((u.builds == 2 && u.refits == 0));
    for (float& x : v) x += 0.001f;
    u = step(v);
    CHECK((u.builds == 2 && u.refits == 1));
    for (std::size_t i = 0; i < v.size() / 3; ++i) v[3 * i] += i % 2 ? 2.0f : -2.0f;
    u = step(v);
    CHECK((u.builds == 3 && u.refits == 1));
}

namespace {

/// Mean of an image.
double image_mean(const std::vector<float>& img) {
    double s = 0.0;
    for (float v : img) s += v;
    return s / double(img.size());
}

/// The central difference (mean(I(v + h)) - mean(I(v - h))) / 2h of the scene `file` with the
/// define `name` at v +- h, both rendered with `seed` (the same camera rays and samples: their
/// difference is far less noisy than either image).
struct Difference {
    Difference(Context& ctx, const char* file, const std::string& name, double v, double h,
               const SceneDefines& extra = {}) : h(h) {
        SceneDefines plus = extra, minus = extra;
        plus.emplace_back(name, std::to_string(v + h));
        minus.emplace_back(name, std::to_string(v - h));
        up = std::make_unique<Session>(ctx, KernelLibrary::from_environment(), test_scene(file), plus);
        down = std::make_unique<Session>(ctx, KernelLibrary::from_environment(), test_scene(file), minus);
    }
    double operator()(int spp, std::uint32_t seed) {
        return (image_mean(up->render(spp, seed)) - image_mean(down->render(spp, seed))) / (2.0 * h);
    }
    double h;
    std::unique_ptr<Session> up, down;
};

} // namespace

// The interior term alone: a plane larger than the view, lit by a point light and a small area
// light, moves along its normal (tests/scenes/shape-plane.xml); no edge of it is in view and
// nothing comes between it and the lights, so the boundary terms vanish. The gradient's sum over
// vertices (the derivative of that shift) against central differences of the mean image with
// h = 0.01 (the mean is smooth in z: the difference's truncation, h^2 f'''/6, is below 1e-4 of it,
// measured with h = 0.02 and 0.005 agreeing), over K = 16 seeds each: |PRB - FD| within 4
// combined standard errors, each below 1.5 % of the value. A shift within the plane moves no hit
// (n . dP = 0) and leaves the image as it is: exactly zero.
TEST_CASE("shape: the interior term matches finite differences (a plane moving along its normal)") {
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene("shape-plane.xml"), {});
    const Parameter& p = session.parameter("plane.vertex_positions");
    Difference fd(*ctx, "shape-plane.xml", "z", 0.0, 0.01);
    test::Stat prb, diff;
    for (std::uint32_t seed = 0; seed < 16; ++seed) {
        const std::array<double, 3> t =
            translation(session.grad("mean", {}, {&p}, 4, 32, seed).gradient, p);
        CHECK(t[0] == 0.0);
        CHECK(t[1] == 0.0);
        prb.add(t[2]);
        diff.add(fd(64, 1000 + seed));
    }
    const double se = std::sqrt(prb.se() * prb.se() + diff.se() * diff.se());
    INFO("PRB " << prb.mean() << " +- " << prb.se() << ", FD " << diff.mean() << " +- "
                << diff.se());
    CHECK(std::abs(prb.mean() - diff.mean()) <= 4.0 * se);
    CHECK(prb.se() < 0.015 * std::abs(diff.mean()));
    CHECK(diff.se() < 0.015 * std::abs(diff.mean()));
}

namespace {

/// A finite-difference case: the derivative of the mean image with respect to a rigid shift of
/// the shapes `params` along `axis`, which the scene's define `define` (at `value`) applies.
struct ShiftCase {
    const char* file;
    std::string define;
    double value, h;
    std::vector<std::string> params;
    int axis;
    int spp_grad, spp_fd;
    SceneDefines extra = {};
};

/// PRB (interior and boundary terms: the sum of the per-vertex gradients along the axis) against
/// central differences of the mean image, K = 16 seeds each: within 4 combined standard errors,
/// which must stay below 5 % of the value (the goal: a test without that power could not
/// tell a missing term of that size). Returns (PRB, FD) means for the report.
std::pair<double, double> check_shift(const ShiftCase& c) {
    Context* ctx = test::device_context();
    SceneDefines defines = c.extra;
    defines.emplace_back(c.define, std::to_string(c.value));
    Session session(*ctx, KernelLibrary::from_environment(), test_scene(c.file), defines);
    std::vector<const Parameter*> params;
    for (const std::string& name : c.params) params.push_back(&session.parameter(name));
    Difference fd(*ctx, c.file, c.define, c.value, c.h, c.extra);
    test::Stat prb, diff;
    for (std::uint32_t seed = 0; seed < 16; ++seed) {
        const std::vector<float> g = session.grad("mean", {}, params, 4, c.spp_grad, seed).gradient;
        double sum = 0.0;
        for (const Parameter* p : params) sum += translation(g, *p)[std::size_t(c.axis)];
        prb.add(sum);
        diff.add(fd(c.spp_fd, 1000 + seed));
    }
    const double se = std::sqrt(prb.se() * prb.se() + diff.se() * diff.se());
    INFO(std::string(c.file) << ": PRB " << prb.mean() << " +- " << prb.se() << ", FD " << diff.mean()
                << " +- " << diff.se());
    CHECK(std::abs(prb.mean() - diff.mean()) <= 4.0 * se);
    CHECK(se < 0.05 * std::abs(diff.mean()));
    MESSAGE(std::string(c.file) << " " << c.define << ": PRB " << prb.mean() << " +- " << prb.se() << ", FD "
                   << diff.mean() << " +- " << diff.se());
    return {prb.mean(), diff.mean()};
}

} // namespace

// The finite-difference cases of shape gradients (after Mitsuba 3's discontinuity tests): each
// gradient has interior and boundary parts, primary (silhouettes in view) and secondary (shadows,
// reflections). h = 0.01: the mean image is smooth in the shift (its pixels integrate over the
// moving edges), so the central difference's truncation, O(h^2), is far below its noise.
// Measured (EPYC-AVX512, PoCL): occluder 0.00638 +- 0.00023 against 0.00633 +- 0.00016; receiver
// -0.0192 +- 0.0007 against -0.0186 +- 0.0003; right angle -0.0254 +- 0.0001 against -0.0267 +-
// 0.0006.
TEST_CASE("shape: an occluder between a small light and a wall, moving") {
    check_shift({"shape-shadow.xml", "ox", 0.3, 0.01, {"occluder.vertex_positions"}, 0, 256, 4096});
}

TEST_CASE("shape: a shadow's receiver moving under a sky") {
    check_shift({"shape-shadow.xml", "wz", 0.0, 0.01, {"wall.vertex_positions"}, 2, 64, 1024,
                 {{"sky", "1"}, {"radiance", "0"}}});
}

TEST_CASE("shape: two surfaces at a right angle moving together under a point light") {
    check_shift({"shape-selfshadow.xml", "t", 0.0, 0.01,
                 {"floor.vertex_positions", "wall.vertex_positions"}, 0, 32, 64});
}

// The plane under a spot light alone, its lit ellipse mostly in the falloff's transition
// (tests/scenes/shape-spot.xml), moving along its normal: each hit's angle from the spot's axis
// changes with its distance and cosine, so the interior term carries the falloff's derivative
// (kernels/path/nee.h: falloff_dx).
TEST_CASE("shape: a plane moving under a spot light") {
    check_shift({"shape-spot.xml", "z", 0.0, 0.01, {"plane.vertex_positions"}, 2, 32, 64});
}

// A diffuse card lit by a lamp's reflection in a fixed gold floor (GGX alpha 0.1;
// tests/scenes/shape-reflector.xml), moving along its normal: each hit slides along its camera
// ray, which turns the direction from the floor up to it, and the floor's BSDF turns with it
// (kernels/path/shape_adjoint.h: shape_vertex_incoming); the card's silhouette and the edges
// seen from it move too (the boundary terms).
TEST_CASE("shape: a card lit by a glossy floor, moving") {
    check_shift({"shape-reflector.xml", "x", 0.0, 0.01, {"card.vertex_positions"}, 0, 256, 4096});
}

// max_depth 0 renders black (as Mitsuba): every term of the gradient is zero, the secondary term's
// too (whose receivers' paths are one segment shorter than the camera's).
TEST_CASE("shape: max_depth 0 renders black and its gradient is zero") {
    Session session(*test::device_context(), KernelLibrary::from_environment(),
                    test_scene("shape-shadow.xml"), {{"max_depth", "0"}});
    const Parameter& p = session.parameter("occluder.vertex_positions");
    const std::vector<float> g = session.grad("mean", {}, {&p}, 1, 16, 0).gradient;
    for (std::size_t i = 0; i < p.size; ++i) CHECK(g[p.offset + i] == 0.0f);
}

TEST_CASE("shape: a scene with mirrors or glass warns of what its shape gradients leave out") {
    const RenderScene glass = build_render_scene(load_scene(test_scene("shape-glass.xml")));
    const Parameter* floor = &glass.params.find("floor.vertex_positions");
    const std::string gaps = shape_gradient_gaps(glass, {floor});
    CHECK(gaps.find("warning: shape gradients leave out") == 0);
    CHECK(gaps.find("(pane)") != std::string::npos); // the shape whose bsdf is a dielectric
    // nothing to say where no shape moves, or where nothing is a mirror or glass
    const Parameter* albedo = &glass.params.find("floor.bsdf.reflectance");
    CHECK(shape_gradient_gaps(glass, {albedo}) == "");
    const RenderScene shadow = build_render_scene(load_scene(test_scene("shape-shadow.xml")));
    CHECK(shape_gradient_gaps(shadow, {&shadow.params.find("occluder.vertex_positions")}) == "");
}

// A cube's shadow on a floor that the camera does not see, only the screen the floor lights
// (tests/scenes/shape-bounce.xml): the shadow's receiver reaches the film through one bounce
// (kernels/boundary.cl: route 1 of boundary_secondary_sample).
TEST_CASE("shape: a shadow seen only by its light's bounce, moving") {
    check_shift({"shape-bounce.xml", "ox", -1.5, 0.01, {"occluder.vertex_positions"}, 0, 256, 4096});
}

// The same cube, bright now, over a black floor: the screen sees its top, lit by the lamp, beside
// its side, lit by nothing; the crease between them (both faces turned toward the screen, no
// silhouette) is where the radiance the screen receives jumps, and it moves with the cube
// (kernels/boundary.cl: every edge is a candidate, not only silhouettes). The cube's top edge is
// in view too (the primary term).
TEST_CASE("shape: a lit face beside an unlit one, seen from a screen, moving") {
    check_shift({"shape-bounce.xml", "ox", -1.5, 0.01, {"occluder.vertex_positions"}, 0, 256, 4096,
                 {{"floor", "0, 0, 0"}, {"cube", "0.8, 0.8, 0.8"}}});
}

// The shadow seen through a screen as above, under max_depth unbounded and Russian roulette from
// the first bounce: the walk from the receiver toward the film (kernels/path/boundary_secondary.h:
// secondary_walk_route) goes on with survival probability min(albedo, 0.95) = 0.5 at the floor's
// bounce, and one pair of side paths serves every route. Without the walk's 1 / q the estimate
// reads -0.00296 +- 0.00010 against -0.00424 +- 0.00006.
TEST_CASE("shape: a shadow seen by its light's bounce under unbounded max_depth and roulette") {
    check_shift({"shape-bounce.xml", "ox", -1.5, 0.01, {"occluder.vertex_positions"}, 0, 256, 4096,
                 {{"max_depth", "-1"}, {"rr_depth", "1"}, {"floor", "0.5, 0.5, 0.5"}}});
}

// A cube's shadow on a panel that the screen in view cannot see, relayed to it by a wall
// (tests/scenes/shape-relay.xml, max_depth 4): the receiver reaches the film through two bounces
// (route 2 of the secondary term's walk); part of the shadow falls on the wall too (route 1). The
// screen and the wall are shaded with tilted normals, so the walk's bounce at the wall carries the
// adjoint's shading-normal factor and the connection at the screen its geometric cosines.
// Measured (Xeon-RKL): 0.000503 +- 0.000013 against 0.000515 +- 0.000009; without route 2
// 0.000807, without the bounce's shading-normal factor 0.00130, with the connection's cosines
// about the shading normal 0.000340. h = 0.05: the mean image is smooth in x (h = 0.01: 0.000477
// +- 0.000026).
TEST_CASE("shape: a shadow seen through two bounces, moving") {
    check_shift({"shape-relay.xml", "ox", -3.25, 0.05, {"occluder.vertex_positions"}, 0, 16384, 8192});
}

// A cube's shadow cast through a glass pane onto a floor, which the camera sees under the pane
// (tests/scenes/shape-glass.xml): the receiver is the pane, seen through a refraction. The walk's
// bounce there weighs importance, which crosses the interface with weight 1, not radiance's
// eta_ti^2 (1 / 2.25 entering): with radiance's weight the estimate reads 0.0355 +- 0.0005
// against 0.0886 +- 0.0018.
TEST_CASE("shape: a shadow cast through a glass pane, moving") {
    check_shift({"shape-glass.xml", "ox", 0.2, 0.05, {"occluder.vertex_positions"}, 0, 1024, 4096});
}

// A cube's shadow under a point light on a wall shaded with normals tilted 40 degrees away from
// the light (tests/scenes/shape-tilted.xml): the film's d(pixel)/dA at the receiver and the change
// of measure to the edge take the triangle's cosines, the BSDF the shading normal's. With every
// cosine about the shading normal the estimate reads 0.0072 against 0.0025. h = 0.05 (h = 0.02:
// 0.00243 +- 0.00007).
TEST_CASE("shape: a shadow on a wall shaded with tilted normals, moving") {
    check_shift({"shape-tilted.xml", "ox", 0.3, 0.05, {"occluder.vertex_positions"}, 0, 2048, 16384});
}

// A cube, a light on black, seen only in the reflection of a glossy floor (GGX alpha 0.025;
// tests/scenes/shape-glossy.xml): the whole derivative is the secondary term at a glossy receiver,
// whose directions the guide draws along the lobes (core/render/boundary_guide.h). h = 0.05: the
// mean image is smooth in x, and h = 0.02 agrees (0.00636 +- 0.00020 against 0.00640 +- 0.00015).
// Unguided, the standard error at 1024 samples was 60 times the guided one's (docs/method.md,
// "Glossy receivers: the guide").
TEST_CASE("shape: an object seen in a glossy floor, moving") {
    check_shift({"shape-glossy.xml", "x", 0.5, 0.05, {"object.vertex_positions"}, 0, 2048, 4096});
}

// The same at max_depth 3, where the secondary term samples creases too: nothing here bounces
// light a second time, so the derivative is the same as at max_depth 2, and the two estimates,
// on the same seeds, must agree (their paired difference within 4 of its standard errors). The
// cube's creases seen from the floor carry no jump (both faces emit alike), but the guide crowds
// directions near silhouettes, where a face seen nearly edge-on is thinner than the side rays'
// offset; such creases are left out (kernels/path/boundary_secondary.h: secondary_crease_clear).
// Without that, the difference reads about -0.0011 (a sixth of the derivative).
TEST_CASE("shape: an object in a glossy floor at max_depth 3 where creases are sampled") {
    Context* ctx = test::device_context();
    std::unique_ptr<Session> depth[2];
    for (int i = 0; i < 2; ++i)
        depth[i] = std::make_unique<Session>(*ctx, KernelLibrary::from_environment(),
                                             test_scene("shape-glossy.xml"),
                                             SceneDefines{{"max_depth", i == 0 ? "2" : "3"}});
    test::Stat three, diff;
    for (std::uint32_t seed = 0; seed < 16; ++seed) {
        double x[2];
        for (int i = 0; i < 2; ++i) {
            const Parameter& p = depth[i]->parameter("object.vertex_positions");
            x[i] = translation(depth[i]->grad("mean", {}, {&p}, 4, 1024, seed).gradient, p)[0];
        }
        three.add(x[1]);
        diff.add(x[1] - x[0]);
    }
    INFO("max_depth 3: " << three.mean() << " +- " << three.se() << "; 3 - 2: " << diff.mean()
                         << " +- " << diff.se());
    CHECK(std::abs(diff.mean()) <= 4.0 * diff.se());
    CHECK(diff.se() < 0.05 * std::abs(three.mean()));
    MESSAGE("glossy floor, max_depth 3 - 2: " << diff.mean() << " +- " << diff.se());
}

namespace {

/// The x of the translation of `param` with the primary term left out, its secondary term sampled
/// as `plain` and as `other`, for the same 16 seeds (the interior term at 1 spp is the same in
/// both), and their paired differences: mean within 4 standard errors of 0 (returned third).
std::array<test::Stat, 3> secondary_two_ways(const char* file, const SceneDefines& defines,
                                             const char* param, BoundarySamples plain,
                                             BoundarySamples other) {
    Context* ctx = test::device_context();
    Session session(*ctx, KernelLibrary::from_environment(), test_scene(file), defines);
    const Parameter& p = session.parameter(param);
    std::array<test::Stat, 3> stat;
    for (std::uint32_t seed = 0; seed < 16; ++seed) {
        double g[2];
        for (int i = 0; i < 2; ++i) {
            session.set_boundary_samples(i == 0 ? plain : other);
            g[i] = translation(session.grad("mean", {}, {&p}, 4, 1, seed).gradient, p)[0];
            stat[i].add(g[i]);
        }
        stat[2].add(g[1] - g[0]);
    }
    INFO(std::string(file) << ": one way " << stat[0].mean() << " +- " << stat[0].se()
                           << ", the other " << stat[1].mean() << " +- " << stat[1].se()
                           << ", their difference " << stat[2].mean() << " +- " << stat[2].se());
    CHECK(std::abs(stat[2].mean()) <= 4.0 * stat[2].se());
    return stat;
}

/// Unguided and guided (BoundarySamples::guide), `spp` secondary samples per pixel.
std::array<test::Stat, 3> secondary_guided_and_not(const char* file, const SceneDefines& defines,
                                                   const char* param, int spp) {
    return secondary_two_ways(file, defines, param, {0, spp, 0}, {0, spp, 1});
}

} // namespace

// The guide changes where the secondary term's directions go, not what they estimate: the
// gradient without its primary term, guided and not, agrees within 4 standard errors of the
// paired differences over 16 seeds,
// on the occluder (diffuse receivers, unguided by default; both standard errors below 5 % of the
// value) and on the cube light in the glossy floor. There the unguided estimate is noisy (about
// 0.045 at 256 samples) but it is the one that leans on light-directed samples, of which those
// toward the cube's own faces from its edges are void (a great circle of directions: weighed as
// the others, the unguided mean was -0.56 +- 0.06 against 0.007; docs/testing.md). This check
// catches gross errors only (its error bar is about 15 times the value); the guide's density is
// checked by the finite differences above.
TEST_CASE("shape: the secondary term's guide changes its variance, not its mean") {
    const std::array<test::Stat, 3> occluder =
        secondary_guided_and_not("shape-shadow.xml", {{"ox", "0.3"}}, "occluder.vertex_positions",
                                 256);
    CHECK(occluder[0].se() < 0.05 * std::abs(occluder[0].mean()));
    CHECK(occluder[1].se() < 0.05 * std::abs(occluder[0].mean()));
    secondary_guided_and_not("shape-glossy.xml", {}, "object.vertex_positions", 256);
}

// The light pairs (core/render/boundary.h: secondary_light_pairs) change where the secondary
// term's samples go, not what they estimate: under three small area lights (shape-lights.xml),
// without and with them, the paired differences over 16 seeds within 4 standard errors of 0; with
// them the standard error is lower (the pairs aim at the shadows' edges), and the difference's
// standard error below 5 % of the value, so that a pair density off by that much is caught.
TEST_CASE("shape: the secondary term's light pairs change its variance, not its mean") {
    const std::array<test::Stat, 3> s = secondary_two_ways(
        "shape-lights.xml", {}, "occluder.vertex_positions", {0, 256, -1, false},
        {0, 256, -1, true});
    MESSAGE("three lights: without pairs " << s[0].mean() << " +- " << s[0].se() << ", with "
                                           << s[1].mean() << " +- " << s[1].se());
    CHECK(s[1].se() < s[0].se());
    CHECK(s[2].se() < 0.05 * std::abs(s[0].mean()));
}

// A plane larger than the view, its albedo a bilinear bitmap, shifted within itself: no hit
// moves and no edge is in view, the texture slides under the pixels (the interior term through
// the hit's texture coordinates; Mitsuba 3's TranslateTexturedPlane).
TEST_CASE("shape: a textured plane sliding within itself") {
    check_shift({"shape-textured.xml", "x", 0.0, 0.01, {"plane.vertex_positions"}, 0, 512, 1024});
    check_shift({"shape-textured.xml", "y", 0.0, 0.01, {"plane.vertex_positions"}, 1, 64, 256});
    // nearest texels jump as they slide: a discontinuity no boundary term samples, refused
    Session nearest(*test::device_context(), KernelLibrary::from_environment(),
                    test_scene("shape-textured.xml"), {{"filter", "nearest"}});
    const Parameter& p = nearest.parameter("plane.vertex_positions");
    CHECK_THROWS_WITH_AS(nearest.grad("mean", {}, {&p}, 1, 1, 0),
                         doctest::Contains("bilinear bitmap, yet (plane)"), Error);
}

// Turning the plane about the x axis (tests/scenes/shape-plane.xml, `tilt`, in degrees) moves each
// vertex by (0, -z, y) per radian and turns the normal with it: the gradient's dot product with
// that motion against central differences in the angle (h = 1 degree), as the translation
// above. A translation leaves the normal as it is, so only this case sees its term.
namespace {

void check_tilt(const char* bsdf, double tilt, int spp_grad, int spp_fd) {
    Context* ctx = test::device_context();
    const SceneDefines defines{{"bsdf", bsdf}, {"tilt", std::to_string(tilt)}};
    Session session(*ctx, KernelLibrary::from_environment(), test_scene("shape-plane.xml"), defines);
    const Parameter& p = session.parameter("plane.vertex_positions");
    const std::vector<float> xyz = session.value(p);
    Difference fd(*ctx, "shape-plane.xml", "tilt", tilt, 1.0, {{"bsdf", bsdf}});
    const double per_degree = M_PI / 180.0;
    test::Stat prb, diff;
    for (std::uint32_t seed = 0; seed < 16; ++seed) {
        const std::vector<float> g = session.grad("mean", {}, {&p}, 4, spp_grad, seed).gradient;
        double dot = 0.0;
        for (std::size_t v = 0; v < p.size / 3; ++v)
            dot += g[p.offset + 3 * v + 1] * -xyz[3 * v + 2] + g[p.offset + 3 * v + 2] * xyz[3 * v + 1];
        prb.add(dot * per_degree);
        diff.add(fd(spp_fd, 1000 + seed));
    }
    const double se = std::sqrt(prb.se() * prb.se() + diff.se() * diff.se());
    INFO(std::string(bsdf) << ": PRB " << prb.mean() << " +- " << prb.se() << ", FD "
                           << diff.mean() << " +- " << diff.se());
    CHECK(std::abs(prb.mean() - diff.mean()) <= 4.0 * se);
    CHECK(se < 0.05 * std::abs(diff.mean()));
    MESSAGE(std::string(bsdf) << " tilt " << tilt << ": PRB " << prb.mean() << " +- " << prb.se()
                              << ", FD " << diff.mean() << " +- " << diff.se());
}

} // namespace

TEST_CASE("shape: the interior term matches finite differences (a plane turning)") {
    check_tilt("matte", 0.0, 32, 1024);
}

// The same plane in gold (roughconductor, GGX alpha 0.2) and in rough plastic (alpha 0.15), whose
// highlights of both lights are in view: moving along its normal and turning, each hit's BSDF
// value changes with the directions to the camera and the lights, and with the normal
// (shared/bsdf_dir_grad.h; kernels/path/shape_adjoint.h: ShapeDirs).
TEST_CASE("shape: a glossy plane moving along its normal and turning") {
    for (const char* bsdf : {"metal", "plastic"}) {
        check_shift({"shape-plane.xml", "z", 0.0, 0.01, {"plane.vertex_positions"}, 2, 32, 256,
                     {{"bsdf", bsdf}}});
        check_tilt(bsdf, -15.0, 128, 1024);
    }
    // a mirror would turn the path after it as it turns: refused
    Session mirror(*test::device_context(), KernelLibrary::from_environment(),
                   test_scene("shape-plane.xml"), {{"bsdf", "mirror"}});
    const Parameter& p = mirror.parameter("plane.vertex_positions");
    CHECK_THROWS_WITH_AS(mirror.grad("mean", {}, {&p}, 1, 1, 0),
                         doctest::Contains("bsdf is smooth (a mirror or glass: plane)"), Error);
}

namespace {

/// The derivative of the mean image of tests/scenes/smooth-bump.xml (`face`: "true" or "false")
/// with respect to raising its centre vertex (every copy of it: Assimp reads OBJ corners apart),
/// PRB against central differences (h = 0.01; the sessions moved by set_value, so the normals
/// derived from the vertices follow), K = 16 seeds each. Returns (PRB, FD) as Stats.
std::pair<test::Stat, test::Stat> bump_derivative(const std::string& face, double h, int res,
                                                  int spp_grad, int spp_fd) {
    Context* ctx = test::device_context();
    const SceneDefines defines{{"face", face}, {"res", std::to_string(res)}};
    auto open = [&] {
        return std::make_unique<Session>(*ctx, KernelLibrary::from_environment(),
                                         test_scene("smooth-bump.xml"), defines);
    };
    std::unique_ptr<Session> session = open(), up = open(), down = open();
    const Parameter& p = session->parameter("bump.vertex_positions");
    const std::vector<float> xyz = session->value(p);
    std::vector<std::size_t> centre; // the z of each copy of the raised vertex
    for (std::size_t i = 0; i + 2 < xyz.size(); i += 3)
        if (xyz[i] == 0.0f && xyz[i + 1] == 0.0f && xyz[i + 2] == 0.3f) centre.push_back(i + 2);
    REQUIRE(centre.size() == 6);
    auto moved = [&](Session& s, double dz) {
        std::vector<float> v = xyz;
        for (std::size_t i : centre) v[i] = static_cast<float>(0.3 + dz);
        s.set_value(s.parameter("bump.vertex_positions"), FloatSpan{v.data(), v.size()});
    };
    moved(*up, h);
    moved(*down, -h);
    test::Stat prb, diff;
    for (std::uint32_t seed = 0; seed < 16; ++seed) {
        const std::vector<float> g = session->grad("mean", {}, {&p}, 4, spp_grad, seed).gradient;
        double sum = 0.0;
        for (std::size_t i : centre) sum += g[p.offset + i];
        prb.add(sum);
        diff.add((image_mean(up->render(spp_fd, 1000 + seed)) -
                  image_mean(down->render(spp_fd, 1000 + seed))) / (2.0 * h));
    }
    return {prb, diff};
}

} // namespace

// Shading normals derived from the vertices (core/scene/vertex_normals.h) follow them: raising
// one vertex of a smooth height field turns the normals of its neighbours, and the interior term
// carries their derivatives (kernels/path/shape_adjoint.h: shape_vertex_push_smooth) besides the
// slide of the hits and of their barycentrics. No edge is in view and nothing casts a shadow, so
// there is no boundary term. The same height field with face normals checks the flat push. Each
// within 4 combined standard errors, which stay below 5 % of the value. The smooth case runs at
// 0.4 % standard error: leaving out the slide of the barycentrics (tests/mutants) moves it by 3 %.
// Measured (EPYC-AVX512, PoCL): smooth -0.000900 +- 0.000003 against -0.000901 +- 0.000001; flat
// -0.02891 +- 0.00008 against -0.02884 +- 0.00010.
TEST_CASE("shape: raising a vertex of a smooth height field matches finite differences") {
    for (const std::string face : {"false", "true"}) {
        const bool smooth = face == "false";
        const auto [prb, diff] =
            smooth ? bump_derivative(face, 0.01, 24, 16, 64) : bump_derivative(face, 0.01, 16, 8, 32);
        const double se = std::sqrt(prb.se() * prb.se() + diff.se() * diff.se());
        INFO("face_normals " << face << ": PRB " << prb.mean() << " +- " << prb.se() << ", FD "
                             << diff.mean() << " +- " << diff.se());
        CHECK(std::abs(prb.mean() - diff.mean()) <= 4.0 * se);
        CHECK(se < 0.05 * std::abs(diff.mean()));
        MESSAGE("smooth-bump face_normals " << face << ": PRB " << prb.mean() << " +- " << prb.se()
                                            << ", FD " << diff.mean() << " +- " << diff.se());
    }
}
