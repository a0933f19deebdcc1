// Mitsuba XML scene loading (core/scene/scene.h): values, variables, transforms, and one-line errors
// that name the file, the line and the tag or attribute.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>
#include <glm/vector_relational.hpp>

#include "core/scene/render_scene.h"
#include "core/scene/scene.h"
#include "shared/bvh_traverse.h"
#include "runtime/error.h"
#include "support.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

const std::string k_fixtures = std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/";

/// A fresh folder holding the inline scenes of this run, plus the (empty) files they reference:
/// the loader only checks that referenced files exist. Removed when the test program exits.
struct ScratchDir {
    fs::path dir = fs::temp_directory_path() / ("tandem-scene-test-" + std::to_string(getpid()));
    ScratchDir() {
        fs::create_directories(dir);
        for (const char* f : {"mesh.obj", "tex.png", "sky.exr"})
            std::ofstream(dir / f) << "";
    }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
};

const fs::path& scratch_dir() {
    static const ScratchDir scratch;
    return scratch.dir;
}

/// Writes `text` to the scratch folder as `name` and returns its path.
std::string write_scene(const std::string& name, const std::string& text) {
    const std::string path = (scratch_dir() / name).string();
    std::ofstream(path) << text;
    return path;
}

/// Wraps `body` in a scene tag: body line 1 is file line 2.
std::string in_scene(const std::string& body) {
    return "<scene version=\"3.0.0\">\n" + body + "\n</scene>\n";
}

glm::vec3 apply(const glm::mat4& m, const glm::vec3& p) {
    return glm::vec3(m * glm::vec4(p, 1.f));
}

bool near(const glm::vec3& a, const glm::vec3& b, float eps = 1e-5f) {
    return glm::all(glm::lessThanEqual(glm::abs(a - b), glm::vec3(eps)));
}

/// The message of the Error that loading `path` throws ("" if it does not throw).
std::string load_error(const std::string& path,
                       const std::vector<std::pair<std::string, std::string>>& defines = {}) {
    try {
        load_scene(path, defines);
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

} // namespace

TEST_SUITE("scene") {
    TEST_CASE("analytic shapes: which spheres and disks are traced exactly, and which side is front") {
        auto flatten = [](Shape shape, bool emits = false) {
            SceneDesc d;
            d.path = "shapes";
            d.camera().width = d.camera().height = 8;
            if (emits) {
                Emitter e;
                e.type = EmitterType::area;
                d.emitters.push_back(e);
                shape.emitter = 0;
            }
            d.shapes.push_back(shape);
            return build_render_scene(d);
        };
        const glm::mat4 id(1.0f);
        Shape sphere;
        sphere.type = ShapeType::sphere;
        sphere.center = glm::vec3(1.0f, 2.0f, 3.0f);
        sphere.radius = 0.5f;
        sphere.to_world = glm::translate(id, glm::vec3(0.0f, 0.0f, -1.0f)) * glm::scale(id, glm::vec3(2.0f));
        RenderScene rs = flatten(sphere);
        REQUIRE(rs.mesh.spheres.size() == 1u);
        CHECK(rs.mesh.triangles.empty());
        CHECK(rs.mesh.spheres[0].center == glm::vec3(2.0f, 4.0f, 5.0f));
        CHECK(rs.mesh.spheres[0].radius == 1.0f);
        CHECK(rs.mesh.spheres[0].orientation == 1.0f);
        CHECK(rs.infos.size() == 1u);
        CHECK(rs.uvs.size() == 1u);
        sphere.flip_normals = true;
        CHECK(flatten(sphere).mesh.spheres.at(0).orientation == -1.0f);
        // rotated: analytic, its texture coordinates in its own axes (to_local undoes the turn)
        Shape turned = sphere;
        turned.to_world = glm::rotate(id, 0.3f, glm::vec3(0, 0, 1)) * glm::scale(id, glm::vec3(2.0f));
        const RenderScene rt = flatten(turned);
        REQUIRE(rt.mesh.spheres.size() == 1u);
        CHECK(rt.mesh.spheres[0].radius == doctest::Approx(1.0));
        const glm::vec4 q = rt.mesh.spheres[0].to_local;
        float x = std::cos(0.3f), y = std::sin(0.3f), z = 0.0f; // the turned +x axis
        gpu::bvh_quat_rotate(q.x, q.y, q.z, q.w, &x, &y, &z);
        CHECK(x == doctest::Approx(1.0).epsilon(1e-6));
        CHECK(y == doctest::Approx(0.0).scale(1.0).epsilon(1e-6));
        CHECK(z == doctest::Approx(0.0).scale(1.0).epsilon(1e-6));
        // tessellated: mirrored, scaled unevenly, emitting; and on request
        for (const glm::mat4& m : {glm::scale(id, glm::vec3(1.0f, 1.0f, -1.0f)),
                                   glm::scale(id, glm::vec3(1.0f, 2.0f, 1.0f))}) {
            Shape s = sphere;
            s.to_world = m;
            const RenderScene t = flatten(s);
            CHECK(t.mesh.spheres.empty());
            CHECK(t.mesh.triangles.size() == 3968u); // 64 x 32 quads, one triangle each at the poles
        }
        CHECK(flatten(sphere, /*emits=*/true).mesh.spheres.empty());
        CHECK(build_render_scene([&] {
                  SceneDesc d;
                  d.path = "shapes";
                  d.shapes.push_back(sphere);
                  return d;
              }(), /*analytic_shapes=*/false).mesh.spheres.empty());

        Shape disk;
        disk.type = ShapeType::disk;
        disk.to_world = glm::translate(id, glm::vec3(1.0f, 0.0f, 0.0f)) *
                        glm::rotate(id, -1.5707964f, glm::vec3(1, 0, 0)) * glm::scale(id, glm::vec3(3.0f));
        rs = flatten(disk);
        REQUIRE(rs.mesh.disks.size() == 1u);
        const Disk& d = rs.mesh.disks[0];
        CHECK(d.center == glm::vec3(1.0f, 0.0f, 0.0f));
        CHECK(glm::length(d.x_axis) == doctest::Approx(3.0));
        // the front faces to_world's image of +z, here +y (a floor), as Mitsuba's normal
        const glm::vec3 front = d.orientation * glm::normalize(glm::cross(d.x_axis, d.y_axis));
        CHECK(front.y == doctest::Approx(1.0));
        // mirrored: Mitsuba's normal (the inverse transpose) keeps facing to_world's +z side
        Shape mirrored = disk;
        mirrored.to_world = glm::scale(id, glm::vec3(-1.0f, 1.0f, 1.0f));
        const RenderScene rm = flatten(mirrored);
        const Disk& dm = rm.mesh.disks.at(0);
        CHECK((dm.orientation * glm::normalize(glm::cross(dm.x_axis, dm.y_axis))).z == doctest::Approx(1.0));
        mirrored.flip_normals = true;
        const RenderScene rf = flatten(mirrored);
        const Disk& df = rf.mesh.disks.at(0);
        CHECK((df.orientation * glm::normalize(glm::cross(df.x_axis, df.y_axis))).z == doctest::Approx(-1.0));
        // tessellated: scaled unevenly in its plane, emitting
        Shape ellipse = disk;
        ellipse.to_world = glm::scale(id, glm::vec3(2.0f, 1.0f, 1.0f));
        CHECK(flatten(ellipse).mesh.disks.empty());
        CHECK(flatten(ellipse).mesh.triangles.size() == 64u);
        CHECK(flatten(disk, /*emits=*/true).mesh.disks.empty());
    }

    TEST_CASE("a Cornell-box-like scene loads to the numbers in the file") {
        const std::string mesh = test::mesh_path("knot_small.obj");
        const SceneDesc s = load_scene(k_fixtures + "cbox.xml", {{"mesh", mesh}});
        CHECK(s.integrator.max_depth == 8);
        CHECK(s.integrator.rr_depth == 3);

        const Camera& c = s.camera();
        CHECK(c.fov == 45.f);
        CHECK(c.fov_axis == FovAxis::smaller);
        CHECK(c.width == 256); // $res default
        CHECK(c.height == 192);
        CHECK(c.spp == 16); // $spp default
        CHECK(c.near_clip == doctest::Approx(0.1));
        CHECK(c.far_clip == 100.f);
        // lookat origin (1,2,3) target (4,6,3) up +z, by hand: dir = (0.6, 0.8, 0),
        // left = normalize(up x dir) = (-0.8, 0.6, 0), new_up = dir x left = (0, 0, 1).
        CHECK(near(glm::vec3(c.to_world[0]), {-0.8f, 0.6f, 0.f}));
        CHECK(near(glm::vec3(c.to_world[1]), {0.f, 0.f, 1.f}));
        CHECK(near(glm::vec3(c.to_world[2]), {0.6f, 0.8f, 0.f}));
        CHECK(near(apply(c.to_world, {0, 0, 0}), {1.f, 2.f, 3.f}));
        CHECK(near(apply(c.to_world, {0, 0, 5}), {4.f, 6.f, 3.f})); // 5 units ahead: the target

        REQUIRE(s.bsdfs.size() == 6); // 5 at scene level + the disk's nested conductor
        CHECK(s.bsdfs[0].id == "white");
        CHECK(s.bsdfs[0].type == BsdfType::diffuse);
        CHECK(s.bsdfs[0].twosided);
        CHECK(near(s.bsdfs[0].reflectance.value, {0.885809f, 0.698859f, 0.666422f}));
        CHECK(!s.bsdfs[1].twosided);
        CHECK(near(s.bsdfs[1].reflectance.value, {0.570068f, 0.0430135f, 0.0443706f}));
        const Bsdf& gold = s.bsdfs[2];
        CHECK(gold.type == BsdfType::roughconductor);
        CHECK(gold.alpha == doctest::Approx(0.2));
        CHECK(near(gold.eta, {0.1431189557f, 0.3749570432f, 1.4424785571f}));
        CHECK(near(gold.k, {3.9831604247f, 2.3857207478f, 1.6032152899f}));
        const Bsdf& plastic = s.bsdfs[3];
        CHECK(plastic.type == BsdfType::roughplastic);
        CHECK(near(plastic.reflectance.value, glm::vec3(0.1f)));
        CHECK(plastic.int_ior == doctest::Approx(1.49)); // Mitsuba's polypropylene default
        CHECK(plastic.nonlinear);
        CHECK(s.bsdfs[4].type == BsdfType::dielectric);
        CHECK(s.bsdfs[4].int_ior == doctest::Approx(1.333)); // "water"
        CHECK(s.bsdfs[4].ext_ior == 1.f);
        CHECK(s.bsdfs[5].type == BsdfType::conductor);
        CHECK(s.bsdfs[5].eta == glm::vec3(0.f)); // material "none": a perfect mirror
        CHECK(s.bsdfs[5].k == glm::vec3(1.f));

        REQUIRE(s.shapes.size() == 6);
        const ShapeType types[] = {ShapeType::rectangle, ShapeType::rectangle, ShapeType::cube,
                                   ShapeType::sphere,    ShapeType::disk,      ShapeType::obj};
        const int bsdfs[] = {0, -1, 1, 2, 5, 4};
        for (int i = 0; i < 6; ++i) {
            CAPTURE(i);
            CHECK(s.shapes[i].type == types[i]);
            CHECK(s.shapes[i].bsdf == bsdfs[i]);
        }
        CHECK(s.shapes[0].id == "floor");
        CHECK(near(s.shapes[3].center, {0.5f, 0.3f, -0.2f}));
        CHECK(s.shapes[3].radius == doctest::Approx(0.3));
        CHECK(s.shapes[4].flip_normals);
        CHECK(s.shapes[5].filename == fs::path(mesh).lexically_normal().string());

        REQUIRE(s.emitters.size() == 3);
        REQUIRE(s.shapes[1].emitter == 0);
        const Emitter& area = s.emitters[0];
        CHECK(area.type == EmitterType::area);
        CHECK(near(area.radiance, {18.387f, 13.9873f, 6.75357f}));
        // The light: scale 0.25, rotate +90 about x (z -> -y, facing down), lift to y = 1.99.
        CHECK(near(apply(s.shapes[1].to_world, {1, 0, 0}), {0.25f, 1.99f, 0.f}));
        CHECK(near(glm::vec3(s.shapes[1].to_world * glm::vec4(0, 0, 1, 0)), {0, -0.25f, 0}));
        CHECK(s.emitters[1].type == EmitterType::point);
        CHECK(near(s.emitters[1].intensity, glm::vec3(5.f)));
        CHECK(near(apply(s.emitters[1].to_world, {0, 0, 0}), {0, 1.5f, 0}));
        CHECK(s.emitters[2].type == EmitterType::constant);
        CHECK(near(s.emitters[2].radiance, glm::vec3(0.25f)));
        for (const Shape& sh : s.shapes)
            if (&sh != &s.shapes[1]) CHECK(sh.emitter == -1);
    }

    TEST_CASE("$variables take <default> values, and -D overrides them") {
        const std::string path = write_scene("vars.xml", in_scene(R"(
<default name="spp" value="8"/>
<default name="w" value="64"/>
<default name="wh" value="$w"/>
<sensor type="perspective">
  <float name="fov" value="1$w"/>
  <film type="hdrfilm"><integer name="width" value="$w"/><integer name="height" value="$wh"/></film>
  <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
</sensor>)"));
        const SceneDesc a = load_scene(path);
        CHECK(a.camera().spp == 8);
        CHECK(a.camera().width == 64);
        CHECK(a.camera().height == 64);
        CHECK(a.camera().fov == 164.f); // "1$w": substitution inside a longer value

        const SceneDesc b = load_scene(path, {{"spp", "2"}, {"w", "10"}});
        CHECK(b.camera().spp == 2);
        CHECK(b.camera().width == 10);
        CHECK(b.camera().height == 10); // the default "$w" sees the override
        CHECK(b.camera().fov == 110.f);
    }

    TEST_CASE("a define must name a variable the scene declares or uses") {
        const std::string path = write_scene("defines.xml", in_scene(R"(
<default name="spp" value="8"/>
<sensor type="perspective">
  <film type="hdrfilm"><integer name="width" value="$w"/><integer name="height" value="16"/></film>
  <sampler type="independent"><integer name="sample_count" value="$spp"/></sampler>
</sensor>)"));
        // $w has no <default>: the scene needs it from a define, and takes it
        CHECK(load_scene(path, {{"w", "10"}, {"spp", "2"}}).camera().width == 10);
        CHECK(load_error(path, {{"w", "10"}, {"foo", "1"}}) ==
              path + ": define 'foo' names no variable of the scene (it has: spp, w)");
        const std::string bare = write_scene("no-vars.xml", in_scene(""));
        CHECK(load_error(bare, {{"res", "8"}}) ==
              bare + ": define 'res' names no variable of the scene (it has none)");
    }

    TEST_CASE("twosided wraps one bsdf, nested or referenced, under its own id") {
        const SceneDesc s = load_scene(write_scene("twosided.xml", in_scene(R"(
<bsdf type="roughconductor" id="metal"><float name="alpha" value="0.3"/></bsdf>
<bsdf type="twosided" id="both">
  <bsdf type="roughplastic"><float name="alpha" value="0.05"/></bsdf>
</bsdf>
<bsdf type="twosided" id="metal2"><ref id="metal"/></bsdf>
<shape type="rectangle"><ref id="both"/></shape>
<shape type="rectangle"><ref id="metal2"/></shape>)")));
        REQUIRE(s.bsdfs.size() == 3);
        CHECK(!s.bsdfs[0].twosided);
        CHECK(s.bsdfs[1].id == "both");
        CHECK(s.bsdfs[1].type == BsdfType::roughplastic);
        CHECK(s.bsdfs[1].twosided);
        CHECK(s.bsdfs[1].alpha == doctest::Approx(0.05));
        CHECK(s.bsdfs[1].line == 4); // the outer tag (the raw string starts with a newline)
        CHECK(s.bsdfs[2].id == "metal2");
        CHECK(s.bsdfs[2].type == BsdfType::roughconductor);
        CHECK(s.bsdfs[2].twosided);
        CHECK(s.bsdfs[2].alpha == doctest::Approx(0.3));
        CHECK(s.shapes[0].bsdf == 1);
        CHECK(s.shapes[1].bsdf == 2);
    }

    TEST_CASE("textures nest in a bsdf or are referenced by name") {
        const SceneDesc s = load_scene(write_scene("textures.xml", in_scene(R"(
<texture type="checkerboard" id="checks">
  <rgb name="color0" value="1, 0, 0"/>
  <transform name="to_uv"><scale x="4" y="2"/><translate x="0.5" y="0.25"/></transform>
</texture>
<bsdf type="diffuse" id="a">
  <texture type="bitmap" name="reflectance">
    <string name="filename" value="tex.png"/>
    <boolean name="raw" value="true"/>
    <string name="filter_type" value="nearest"/>
  </texture>
</bsdf>
<bsdf type="roughplastic" id="b"><ref name="diffuse_reflectance" id="checks"/></bsdf>
<bsdf type="diffuse" id="c"/>)")));
        REQUIRE(s.textures.size() == 2);
        const Texture& checks = s.textures[0];
        CHECK(checks.kind == Texture::Kind::checkerboard);
        CHECK(checks.color0 == glm::vec3(1, 0, 0));
        CHECK(checks.color1 == glm::vec3(0.2f)); // Mitsuba default
        // uv (1, 1) -> scaled (4, 2) -> translated (4.5, 2.25)
        CHECK(near(checks.to_uv * glm::vec3(1, 1, 1), {4.5f, 2.25f, 1.f}));
        const Texture& bitmap = s.textures[1];
        CHECK(bitmap.kind == Texture::Kind::bitmap);
        CHECK(bitmap.filename == (scratch_dir() / "tex.png").string());
        CHECK(!bitmap.srgb);
        CHECK(bitmap.filter_type == "nearest");
        CHECK(bitmap.line == 8);
        CHECK(s.bsdfs[0].reflectance.texture == 1);
        CHECK(s.bsdfs[1].reflectance.texture == 0);
        CHECK(s.bsdfs[2].reflectance.texture == -1);
        CHECK(s.bsdfs[2].reflectance.value == glm::vec3(0.5f)); // Mitsuba default
    }

    TEST_CASE("transform elements compose in file order, each after the previous") {
        const SceneDesc s = load_scene(write_scene("transforms.xml", in_scene(R"(
<shape type="cube"><transform name="to_world"><translate x="1"/><scale value="2"/></transform></shape>
<shape type="cube"><transform name="to_world"><scale value="2"/><translate x="1"/></transform></shape>
<shape type="cube"><transform name="to_world"><rotate y="1" angle="90"/></transform></shape>
<shape type="cube"><transform name="to_world">
  <matrix value="0 -1 0 5  1 0 0 6  0 0 1 7  0 0 0 1"/>
</transform></shape>
<shape type="cube"><transform name="to_world">
  <scale value="1, 2, 3"/><translate value="1 1 1"/><rotate axis="0 0 1" angle="180"/>
</transform></shape>
<shape type="cube"><transform name="to_world">
  <matrix value="0 -1 0  1 0 0  0 0 1"/><rotate value="0, 0, 2" angle="-90"/>
</transform></shape>
<shape type="cube"><transform name="to_world"><lookat origin="1 2 3" target="1 2 5"/></transform>
</shape>)")));
        REQUIRE(s.shapes.size() == 7);
        // translate then scale: (1,1,1) -> (2,1,1) -> (4,2,2); scale then translate: (3,2,2).
        CHECK(near(apply(s.shapes[0].to_world, {1, 1, 1}), {4, 2, 2}));
        CHECK(near(apply(s.shapes[1].to_world, {1, 1, 1}), {3, 2, 2}));
        // Right-handed rotation about +y by 90 degrees: +x -> -z.
        CHECK(near(apply(s.shapes[2].to_world, {1, 0, 0}), {0, 0, -1}));
        // Row-major matrix: x -> y, y -> -x, then translation (5, 6, 7).
        CHECK(near(apply(s.shapes[3].to_world, {1, 0, 0}), {5, 7, 7}));
        CHECK(near(apply(s.shapes[3].to_world, {0, 1, 0}), {4, 6, 7}));
        // (1,1,1) -> (1,2,3) -> (2,3,4) -> (-2,-3,4)
        CHECK(near(apply(s.shapes[4].to_world, {1, 1, 1}), {-2, -3, 4}));
        // A 3x3 matrix (+90 about z) undone by rotate value= (-90 about z): the identity.
        CHECK(near(apply(s.shapes[5].to_world, {1, 2, 3}), {1, 2, 3}));
        // lookat without up: still a rigid frame looking at the target.
        const glm::mat4& m = s.shapes[6].to_world;
        CHECK(near(apply(m, {0, 0, 2}), {1, 2, 5}));
        CHECK(glm::determinant(m) == doctest::Approx(1.0));
        CHECK(glm::dot(glm::vec3(m[0]), glm::vec3(m[1])) == doctest::Approx(0.0));
        CHECK(glm::length(glm::vec3(m[0])) == doctest::Approx(1.0));
    }

    TEST_CASE("emitters: spot defaults, envmap file, point position") {
        const SceneDesc s = load_scene(write_scene("emitters.xml", in_scene(R"(
<emitter type="spot" id="spot">
  <float name="cutoff_angle" value="40"/>
  <rgb name="intensity" value="1 2 3"/>
</emitter>
<emitter type="envmap">
  <string name="filename" value="./sky.exr"/><float name="scale" value="0.5"/>
</emitter>
<emitter type="point"><transform name="to_world"><translate x="3"/></transform></emitter>)")));
        REQUIRE(s.emitters.size() == 3);
        CHECK(s.emitters[0].id == "spot");
        CHECK(s.emitters[0].beam_width == doctest::Approx(30.0)); // 3/4 of the cutoff
        CHECK(s.emitters[0].intensity == glm::vec3(1, 2, 3));
        CHECK(s.emitters[1].filename == (scratch_dir() / "sky.exr").string());
        CHECK(s.emitters[1].scale == 0.5f);
        CHECK(near(apply(s.emitters[2].to_world, {0, 0, 0}), {3, 0, 0}));
    }

    TEST_CASE("gallery-lights: -D ledge_radiance sets the 64 ledge emitters and no other light") {
        const std::string gallery = std::string(TANDEM_SOURCE_DIR) + "/scenes/gallery-lights.xml";
        const SceneDesc base = load_scene(gallery, {{"res", "8"}});
        const SceneDesc bright =
            load_scene(gallery, {{"res", "8"}, {"ledge_radiance", "12000, 10200, 7200"}});
        REQUIRE(base.shapes.size() == bright.shapes.size());
        REQUIRE(base.emitters.size() == bright.emitters.size());
        std::vector<bool> is_ledge(base.emitters.size(), false);
        for (const Shape& s : base.shapes)
            if (s.emitter >= 0 && s.id.rfind("ledge-light-", 0) == 0)
                is_ledge[size_t(s.emitter)] = true;
        int ledge = 0, others = 0;
        for (size_t i = 0; i < base.emitters.size(); ++i) {
            const Emitter &a = base.emitters[i], &b = bright.emitters[i];
            if (is_ledge[i]) {
                ++ledge;
                CHECK(a.radiance == glm::vec3(60, 51, 36)); // the generator's default
                CHECK(b.radiance == glm::vec3(12000, 10200, 7200));
            } else {
                ++others;
                CHECK(a.type == b.type);
                CHECK(a.radiance == b.radiance);
                CHECK(a.intensity == b.intensity);
            }
        }
        CHECK(ledge == 64);
        CHECK(others == 5); // three spots, the side-room light and the fill
    }

    TEST_CASE("a scene without sensor or integrator gets Mitsuba's defaults") {
        const SceneDesc s = load_scene(write_scene("empty.xml", in_scene("")));
        CHECK(s.camera().width == 768);
        CHECK(s.camera().height == 576);
        CHECK(s.camera().spp == 4);
        CHECK(s.camera().fov == doctest::Approx(39.3077));
        CHECK(s.integrator.max_depth == -1);
        CHECK(s.shapes.empty());
    }

    TEST_CASE("every error names the file, the line and the tag or attribute, on one line") {
        struct Case {
            const char* body; // inside <scene>; its first line is line 2
            int line;
            const char* needle;
        };
        const Case cases[] = {
            {"<shape type=\"cube\">\n</shap>", 3, "malformed XML"},
            {"<foo/>", 2, "unknown tag <foo>"},
            {"<shape type=\"cube\">\n  <transform name=\"to_world\"><skew/></transform></shape>", 3,
             "unknown tag <skew>"},
            {"<bsdf type=\"plastic\"/>", 2, "unsupported bsdf type 'plastic'"},
            {"<shape type=\"mesh\"/>", 2, "unsupported shape type 'mesh'"},
            {"<emitter type=\"directional\"/>", 2, "unsupported emitter type 'directional'"},
            {"<texture type=\"noise\"/>", 2, "unsupported texture type 'noise'"},
            {"<integrator type=\"direct\"/>", 2, "unsupported integrator type 'direct'"},
            {"<sensor type=\"orthographic\"/>", 2, "unsupported sensor type 'orthographic'"},
            {"<sensor type=\"perspective\">\n<film type=\"hdrfilm\">\n<rfilter type=\"gaussian\"/>"
             "</film></sensor>",
             4, "unsupported rfilter type 'gaussian'"},
            {"<bsdf type=\"diffuse\">\n\n  <float name=\"roughness\" value=\"1\"/></bsdf>", 4,
             "unsupported property 'roughness'"},
            {"<sensor type=\"perspective\">\n  <string name=\"fov\" value=\"45\"/></sensor>", 3,
             "property 'fov' must be <float>"},
            {"<sensor type=\"perspective\">\n  <float name=\"fov\" value=\"4x5\"/></sensor>", 3,
             "attribute 'value' must be a number, got '4x5'"},
            {"<integrator type=\"path\">\n<integer name=\"max_depth\" value=\"1.5\"/></integrator>",
             3, "must be an integer, got '1.5'"},
            {"<shape type=\"cube\">\n<boolean name=\"flip_normals\" value=\"yes\"/></shape>", 3,
             "must be true or false, got 'yes'"},
            {"<bsdf type=\"diffuse\">\n<rgb name=\"reflectance\" value=\"1, 2\"/></bsdf>", 3,
             "must be 1 or 3 numbers"},
            {"<bsdf type=\"diffuse\">\n<spectrum name=\"reflectance\" value=\"400:0.1, 500:0.2\"/>"
             "</bsdf>",
             3, "only grey spectra"},
            {"<shape type=\"cube\">\n<transform name=\"to_world\">\n<translate value=\"1 2\"/>"
             "</transform></shape>",
             4, "<translate>: attribute 'value' must be 3 numbers"},
            {"<shape type=\"cube\">\n<transform name=\"to_world\"><rotate x=\"1\"/></transform>"
             "</shape>",
             3, "<rotate>: missing attribute 'angle'"},
            {"<bsdf type=\"diffuse\">\n<float value=\"1\"/></bsdf>", 3,
             "<float>: missing attribute 'name'"},
            {"\n<shape id=\"x\"/>", 3, "<shape id=\"x\">: missing attribute 'type'"},
            {"<shape type=\"cube\" colour=\"red\"/>", 2, "unexpected attribute 'colour'"},
            {"<bsdf type=\"diffuse\" id=\"a\"/>\n<bsdf type=\"diffuse\" id=\"a\"/>", 3,
             "duplicate id 'a' (first used on line 2)"},
            {"<shape type=\"cube\">\n<ref id=\"nope\"/></shape>", 3, "unknown id 'nope'"},
            {"<texture type=\"checkerboard\" id=\"t\"/>\n<shape type=\"cube\"><ref id=\"t\"/>"
             "</shape>",
             3, "'t' is a <texture>, expected a <bsdf>"},
            {"<shape type=\"cube\">\n<ref id=\"later\"/></shape>\n<bsdf type=\"diffuse\" "
             "id=\"later\"/>",
             3, "unknown id 'later'"},
            {"<sensor type=\"perspective\">\n<float name=\"fov\" value=\"$fov\"/></sensor>", 3,
             "attribute 'value' uses undefined $fov"},
            {"<shape type=\"obj\">\n<string name=\"filename\" value=\"nope.obj\"/></shape>", 3,
             "filename 'nope.obj' not found"},
            {"<shape type=\"ply\"/>", 2, "missing property 'filename'"},
            {"<emitter type=\"envmap\">\n<string name=\"filename\" value=\"nope.exr\"/></emitter>",
             3, "filename 'nope.exr' not found"},
            {"<texture type=\"bitmap\">\n<string name=\"filename\" value=\"nope.png\"/></texture>",
             3, "filename 'nope.png' not found"},
            {"<emitter type=\"area\"/>", 2, "must be nested in a <shape>"},
            {"<shape type=\"cube\">\n<emitter type=\"point\"/></shape>", 3,
             "only area emitters can be nested"},
            {"<bsdf type=\"roughconductor\">\n<string name=\"distribution\" value=\"beckmann\"/>"
             "</bsdf>",
             3, "distribution 'beckmann' is not supported"},
            {"<emitter type=\"envmap\">\n<float name=\"scale\" value=\"-1\"/></emitter>", 2,
             "scale must be finite and >= 0"},
            {"<emitter type=\"envmap\">\n<float name=\"scale\" value=\"inf\"/></emitter>", 2,
             "scale must be finite and >= 0"},
            {"<bsdf type=\"roughplastic\">\n<float name=\"alpha\" value=\"0\"/></bsdf>", 2,
             "alpha must be in (0, 1]"},
            {"<bsdf type=\"roughconductor\">\n<float name=\"alpha\" value=\"-0.1\"/></bsdf>", 2,
             "alpha must be in (0, 1]"},
            {"<bsdf type=\"conductor\">\n<string name=\"material\" value=\"Unobtainium\"/></bsdf>",
             3, "unknown conductor material 'Unobtainium'"},
            {"<bsdf type=\"dielectric\">\n<string name=\"int_ior\" value=\"glas\"/></bsdf>", 3,
             "unknown int_ior material 'glas'"},
            {"<bsdf type=\"twosided\">\n<bsdf type=\"diffuse\"/><bsdf type=\"diffuse\"/></bsdf>", 2,
             "needs exactly one nested bsdf, has 2"},
            {"<shape type=\"cube\">\n<bsdf type=\"diffuse\"/>\n<bsdf type=\"diffuse\"/></shape>", 4,
             "more than one bsdf"},
            {"<bsdf type=\"diffuse\">\n<float name=\"a\" value=\"1\"/>\n<float name=\"a\" "
             "value=\"2\"/></bsdf>",
             4, "property 'a' given twice"},
            {"<shape type=\"cube\">\n<default name=\"x\" value=\"1\"/></shape>", 3,
             "<default> is only allowed directly inside <scene>"},
            {"<sensor type=\"perspective\"><transform name=\"to_world\">\n"
             "<lookat origin=\"0 0 0\" target=\"0 1 0\" up=\"0 1 0\"/></transform></sensor>",
             3, "'up' is parallel"},
            {"<sensor type=\"perspective\">\n<string name=\"fov_axis\" value=\"z\"/></sensor>", 3,
             "fov_axis must be x, y, diagonal, smaller or larger"},
            {"<sensor type=\"batch\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"7\"/>"
             "</film>\n<sensor type=\"perspective\"/>\n<sensor type=\"perspective\"/></sensor>",
             2, "the film's width 7 does not split evenly between its 2 sensors"},
            {"<sensor type=\"batch\"><sensor type=\"perspective\">\n<film type=\"hdrfilm\"/>"
             "</sensor></sensor>",
             3, "a nested sensor has no <film> of its own"},
            {"<sensor type=\"batch\">\n<film type=\"hdrfilm\"/></sensor>", 2,
             "<sensor type=\"batch\">: no nested <sensor>"},
            {"<film type=\"hdrfilm\"/>", 2, "<scene>: unexpected <film type=\"hdrfilm\">"},
            {"<bsdf type=\"diffuse\">\n<texture type=\"checkerboard\" name=\"albedo\"/></bsdf>", 3,
             "unexpected <texture type=\"checkerboard\"> with name=\"albedo\""},
            {"<shape type=\"cube\">\nhello</shape>", 2, "unexpected text"},
        };
        int index = 0;
        for (const Case& c : cases) {
            const std::string file = "error" + std::to_string(index++) + ".xml";
            const std::string path = write_scene(file, in_scene(c.body));
            const std::string msg = load_error(path);
            const std::string body = c.body;
            CAPTURE(body);
            CAPTURE(msg);
            CHECK(msg.rfind(path + ":" + std::to_string(c.line) + ": ", 0) == 0);
            CHECK(msg.find(c.needle) != std::string::npos);
            CHECK(msg.find('\n') == std::string::npos);
        }
    }

    TEST_CASE("scene-level errors: root, version, missing file") {
        const std::string v = write_scene("v06.xml", "<scene version=\"0.6.0\">\n</scene>\n");
        CHECK(load_error(v).rfind(v + ":1: <scene>: unsupported version '0.6.0'", 0) == 0);
        const std::string nov = write_scene("nov.xml", "\n<scene>\n</scene>\n");
        CHECK(load_error(nov).rfind(nov + ":2: <scene>: missing attribute 'version'", 0) == 0);
        const std::string root = write_scene("root.xml", "<shape type=\"cube\"/>\n");
        CHECK(load_error(root).rfind(root + ":1: the root tag must be <scene>", 0) == 0);
        CHECK(load_error("/nonexistent/x.xml") ==
              "/nonexistent/x.xml: scene file not found or unreadable");
        // The fixture names a missing mesh unless -D mesh=... points at one.
        const std::string cbox = k_fixtures + "cbox.xml";
        const std::string msg = load_error(cbox);
        CHECK(msg.find(cbox + ":") == 0);
        CHECK(msg.find("filename 'missing.obj' not found") != std::string::npos);
    }
}
