// The parameter registry: names, kinds, contiguous layout, current values and ranges.
#include <doctest/doctest.h>

#include <cmath>

#include <filesystem>

#include "core/io/atomic_file.h"
#include "core/scene/params.h"
#include "core/scene/render_scene.h"
#include "runtime/error.h"
#include "support.h"

using namespace tandem;

TEST_SUITE("params") {
    TEST_CASE("three-spheres: every parameter kind, laid out contiguously with its values") {
        const SceneDesc desc = load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/three-spheres.xml");
        const RenderScene rs = build_render_scene(desc);
        const ParamRegistry& reg = rs.params;
        std::size_t next = 0;
        for (const Parameter& p : reg.parameters()) {
            INFO(p.name);
            CHECK(p.offset == next); // one flat array, in registration order, no gaps
            next += p.size;
        }
        CHECK(next == reg.values().size());
        const Parameter& alpha = reg.find("gold.alpha");
        CHECK(alpha.kind == Parameter::Kind::scalar);
        CHECK(reg.values()[alpha.offset] == 0.2f);
        CHECK(alpha.lower == 1e-3f);
        CHECK(alpha.upper == 1.0f);
        const Parameter& matte = reg.find("matte.reflectance");
        CHECK(matte.size == 3);
        CHECK(reg.values()[matte.offset + 1] == 0.25f);
        const Parameter& floor = reg.find("floor.reflectance");
        CHECK(floor.kind == Parameter::Kind::texture);
        CHECK(floor.size == std::size_t(floor.width) * floor.height * 3);
        CHECK(floor.width == 256);
        // texels as the renderer holds them (linear RGB), first texel
        CHECK(reg.values()[floor.offset] == rs.texels[0].x);
        const Parameter& light = reg.find("light-emitter.radiance");
        CHECK(reg.values()[light.offset] == 12.0f);
        CHECK(std::isinf(light.upper));
        CHECK(reg.find("plastic.specular_reflectance").size == 3);
    }

    TEST_CASE("an unknown parameter is an error that names it and lists the known ones") {
        const SceneDesc desc = load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox.xml");
        const RenderScene rs = build_render_scene(desc);
        const ParamRegistry& reg = rs.params;
        CHECK_THROWS_WITH_AS(reg.find("wall.roughness"),
                             doctest::Contains("unknown parameter 'wall.roughness'"), Error);
        CHECK_THROWS_WITH_AS(reg.find("nope"), doctest::Contains("white.reflectance"), Error);
        // the light's emitter has no id: it is named after its shape, as in Mitsuba
        CHECK(reg.values()[reg.find("light.emitter.radiance").offset] == 18.387f);
    }
}

TEST_SUITE("params") {
    TEST_CASE("a twosided bsdf wrapping a ref shares the referenced bsdf's parameters") {
        const std::string path = (std::filesystem::temp_directory_path() / "tandem-twosided-ref.xml").string();
        write_file_atomic(path, R"(<scene version="3.0.0">
            <bsdf type="roughplastic" id="base"><float name="alpha" value="0.3"/></bsdf>
            <bsdf type="twosided" id="both"><ref id="base"/></bsdf>
            <shape type="rectangle"><ref id="base"/></shape>
            <shape type="rectangle"><ref id="both"/></shape>
        </scene>)");
        const RenderScene rs = build_render_scene(load_scene(path));
        for (const Parameter& p : rs.params.parameters()) CHECK(p.name.rfind("base.", 0) == 0);
        const gpu::Material &a = rs.materials[0], &b = rs.materials[1];
        CHECK(b.flags == (a.flags | MATERIAL_FLAG_TWOSIDED));
        CHECK(a.reflectance_param == b.reflectance_param);
        CHECK(a.specular_param == b.specular_param);
        CHECK(a.alpha_param == b.alpha_param);
        CHECK(a.alpha_param == rs.params.find("base.alpha").offset);
    }
}
