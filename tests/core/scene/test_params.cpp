// The parameter registry: names, kinds, contiguous layout, current values and ranges.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

#include <filesystem>

#include "core/io/atomic_file.h"
#include "core/scene/bitmaps.h"
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
        // texels as loaded (linear RGB), held once: in the parameters, not also as device texels
        const std::vector<Bitmap> bitmaps = load_bitmaps(desc);
        std::size_t param_bitmaps = 0;
        for (std::size_t t = 0; t < desc.textures.size(); ++t) {
            CHECK(rs.textures[t].param == reg.texture(t));
            if (reg.texture(t) == NO_PARAM) continue;
            ++param_bitmaps;
            const std::vector<float>& rgb = bitmaps[t].rgb;
            CHECK(test::same_bytes(rgb, std::vector<float>(reg.values().begin() + reg.texture(t),
                                                           reg.values().begin() + reg.texture(t) + rgb.size())));
        }
        CHECK(param_bitmaps == 1);
        CHECK(reg.values()[floor.offset] == bitmaps[0].rgb[0]);
        std::size_t device_texels = 0;
        for (std::size_t t = 0; t < desc.textures.size(); ++t)
            if (desc.textures[t].kind == Texture::Kind::bitmap && reg.texture(t) == NO_PARAM)
                device_texels += std::size_t(bitmaps[t].width) * bitmaps[t].height;
        CHECK(rs.texels.size() == device_texels);
        const Parameter& light = reg.find("light-emitter.radiance");
        CHECK(reg.values()[light.offset] == 12.0f);
        CHECK(std::isinf(light.upper));
        CHECK(reg.find("plastic.specular_reflectance").size == 3);
    }

    TEST_CASE("the registry is built from the description alone, and the flattening reads its offsets") {
        const SceneDesc desc = load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/three-spheres.xml");
        const ParamRegistry reg(desc, load_bitmaps(desc));
        const RenderScene rs = build_render_scene(desc);
        // the flattening adds only what the description cannot say: the meshes' vertex positions
        REQUIRE(reg.parameters().size() <= rs.params.parameters().size());
        for (std::size_t i = 0; i < reg.parameters().size(); ++i) {
            CHECK(reg.parameters()[i].name == rs.params.parameters()[i].name);
            CHECK(reg.parameters()[i].offset == rs.params.parameters()[i].offset);
        }
        for (std::size_t i = reg.parameters().size(); i < rs.params.parameters().size(); ++i)
            CHECK(rs.params.parameters()[i].kind == Parameter::Kind::vertices);
        CHECK(test::same_bytes(reg.values(), std::vector<float>(rs.params.values().begin(),
                                                                rs.params.values().begin() +
                                                                    std::ptrdiff_t(reg.size()))));
        for (std::size_t i = 0; i < desc.bsdfs.size(); ++i) {
            CHECK(rs.materials[i].reflectance_param == reg.bsdf(i).reflectance);
            CHECK(rs.materials[i].specular_param == reg.bsdf(i).specular);
            CHECK(rs.materials[i].alpha_param == reg.bsdf(i).alpha);
        }
        for (const gpu::EmissiveTriangle& e : rs.emissive) CHECK(e.radiance_param != NO_PARAM);
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
        for (const Parameter& p : rs.params.parameters())
            if (!p.moves_geometry()) CHECK(p.name.rfind("base.", 0) == 0);
        const gpu::Material &a = rs.materials[0], &b = rs.materials[1];
        CHECK(b.flags == (a.flags | MATERIAL_FLAG_TWOSIDED));
        CHECK(a.reflectance_param == b.reflectance_param);
        CHECK(a.specular_param == b.specular_param);
        CHECK(a.alpha_param == b.alpha_param);
        CHECK(a.alpha_param == rs.params.find("base.alpha").offset);
    }
}

TEST_SUITE("params") {
    TEST_CASE("no parameter is an index of refraction: delta lobes weigh alike in both states") {
        // The two-state path weighs a delta lobe sampled under theta_n with the old state's own
        // weight (continuation_weight_old), exact only while the lobe's choice probability (the
        // dielectric's Fresnel term) is the same in both states: eta and k must not be
        // parameters. Every bundled scene, plus one with every bsdf type and explicit IORs: each
        // parameter is a reflectance, specular reflectance, alpha or radiance, and every float of
        // the parameter buffer is reached only through those offsets.
        const std::string path = (std::filesystem::temp_directory_path() / "tandem-iors.xml").string();
        write_file_atomic(path, R"(<scene version="3.0.0">
            <bsdf type="conductor" id="c"><rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3, 2.5, 2"/></bsdf>
            <bsdf type="roughconductor" id="rc"><string name="material" value="Au"/></bsdf>
            <bsdf type="dielectric" id="d"><float name="int_ior" value="1.7"/><float name="ext_ior" value="1.1"/></bsdf>
            <bsdf type="roughplastic" id="p"><float name="int_ior" value="1.6"/></bsdf>
            <shape type="rectangle"><ref id="c"/></shape>
            <shape type="rectangle"><ref id="rc"/></shape>
            <shape type="rectangle"><ref id="d"/></shape>
            <shape type="rectangle"><ref id="p"/></shape>
        </scene>)");
        std::vector<std::string> files = {path};
        for (const char* dir : {"/scenes", "/tests/scenes"})
            for (const auto& e : std::filesystem::directory_iterator(std::string(TANDEM_SOURCE_DIR) + dir))
                if (e.path().extension() == ".xml") files.push_back(e.path().string());
        REQUIRE(files.size() >= 9);
        for (const std::string& file : files) {
            INFO(file);
            const bool mesh = file.find("tests/scenes/cbox.xml") != std::string::npos; // every plugin
            const SceneDesc desc = mesh ? load_scene(file, {{"mesh", test::mesh_path("knot_small.obj")}})
                                        : load_scene(file);
            const RenderScene rs = build_render_scene(desc);
            const ParamRegistry& reg = rs.params;
            std::vector<int> reached(reg.size(), 0);
            auto reach = [&](unsigned offset, std::size_t size) {
                if (offset == NO_PARAM) return;
                REQUIRE(offset + size <= reg.size());
                for (std::size_t i = offset; i < offset + size; ++i) ++reached[i];
            };
            for (std::size_t i = 0; i < desc.bsdfs.size(); ++i) {
                const BsdfParams b = reg.bsdf(i);
                reach(b.reflectance, 3), reach(b.specular, 3), reach(b.alpha, 1);
                const gpu::Material& m = rs.materials[i];
                if (m.type == MATERIAL_CONDUCTOR || m.type == MATERIAL_DIELECTRIC) {
                    // a delta lobe: only specular_reflectance, a factor of its weight, may change
                    CHECK(m.reflectance_param == NO_PARAM);
                    CHECK(m.alpha_param == NO_PARAM);
                }
            }
            for (std::size_t t = 0; t < desc.textures.size(); ++t)
                if (reg.texture(t) != NO_PARAM) {
                    for (const Parameter& p : reg.parameters())
                        if (p.offset == reg.texture(t)) reach(reg.texture(t), p.size);
                }
            for (std::size_t e = 0; e < desc.emitters.size(); ++e) reach(reg.emitter(e), 3);
            // a medium's values: whole parameters (rgb, scalar or a grid's voxels)
            const auto reach_whole = [&](unsigned offset) {
                for (const Parameter& p : reg.parameters())
                    if (offset != NO_PARAM && p.offset == offset) reach(offset, p.size);
            };
            for (const gpu::Medium& m : rs.media)
                for (unsigned offset : {m.sigma_t_param, m.albedo_param, m.scale_param, m.g_param})
                    reach_whole(offset);
            for (const MeshShape& m : rs.mesh_shapes) reach_whole(m.param);
            for (const Parameter& p : reg.parameters()) {
                INFO(p.name);
                const auto ends = [&](const std::string& s) {
                    return p.name.size() > s.size() && p.name.compare(p.name.size() - s.size(), s.size(), s) == 0;
                };
                if (p.in_medium)
                    CHECK((ends(".sigma_t") || ends(".albedo") || ends(".scale") || ends(".g")));
                else if (p.moves_geometry())
                    CHECK(ends(".vertex_positions"));
                else
                    CHECK((ends(".reflectance") || ends(".specular_reflectance") || ends(".alpha") || ends(".radiance")));
                CHECK(std::count(reached.begin() + p.offset, reached.begin() + p.offset + p.size, 0) == 0);
            }
        }
    }
}
