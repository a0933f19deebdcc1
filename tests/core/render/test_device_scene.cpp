// The device scene: the scene's kernel arguments are written once (kernels/shared/scene_args.h),
// and the compiled kernels' signatures agree with the list the host binds; feature validation;
// the parameter state's generic save and restore.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <glm/geometric.hpp>

#include "core/inverse/param_state.h"
#include "core/render/device_scene.h"
#include "runtime/error.h"
#include "probes/probes.h"
#include "support.h"

using namespace tandem;

namespace {

/// The OpenCL implementation's view of kernel `name`'s first arguments, as (type, name).
std::vector<std::pair<std::string, std::string>> kernel_arguments(const Program& program,
                                                                  const std::string& name) {
    const cl::Kernel k = program.kernel(name);
    std::vector<std::pair<std::string, std::string>> out;
    const cl_uint n = k.getInfo<CL_KERNEL_NUM_ARGS>();
    for (cl_uint i = 0; i < n; ++i) {
        std::string type = k.getArgInfo<CL_KERNEL_ARG_TYPE_NAME>(i),
                    arg = k.getArgInfo<CL_KERNEL_ARG_NAME>(i);
        // some implementations end strings with NUL, or prefix structs with "struct "
        type = type.c_str();
        arg = arg.c_str();
        if (type.rfind("struct ", 0) == 0) type = type.substr(7);
        out.emplace_back(type, arg);
    }
    return out;
}

/// Where `host` (the binding) and the head of `kernel` (the signature) disagree, as messages.
std::vector<std::string>
mismatches(const std::vector<std::pair<std::string, std::string>>& host,
           const std::vector<std::pair<std::string, std::string>>& kernel) {
    std::vector<std::string> out;
    if (kernel.size() < host.size() + 1) out.push_back("the kernel has too few arguments");
    for (std::size_t i = 0; i < host.size() && i < kernel.size(); ++i)
        if (host[i] != kernel[i])
            out.push_back("argument " + std::to_string(i) + ": host " + host[i].first + " " +
                          host[i].second + ", kernel " + kernel[i].first + " " + kernel[i].second);
    return out;
}

RenderScene small_scene(const char* file) {
    return build_render_scene(
        load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/" + file, {{"res", "8"}}));
}

} // namespace

TEST_SUITE("device scene") {
    TEST_CASE(
        "every path kernel takes the scene's arguments in the order the host binds them, then rp") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = small_scene("cbox.xml");
        const std::string options =
            render_features(scene, *ctx).options() + " -cl-kernel-arg-info";
        const std::vector<std::pair<std::string, std::string>> host = DeviceScene::argument_list();
        REQUIRE(host.size() == 22);
        CHECK(host.front() == std::make_pair(std::string("float4*"), std::string("nodes")));
        CHECK(host.back() == std::make_pair(std::string("DeviceCamera"), std::string("cam")));
        // Argument info is kept only by a build from source: no binary cache for these.
        const test::ScopedTuning no_cache(*ctx, [](Tuning& t) { t.cache_dir.clear(); });
        const KernelLibrary lib = probe_library(); // the replay check is a path kernel too
        std::vector<std::string> checked;
        for (const std::string file :
             {"render.cl", "adjoint.cl", "wavefront.cl", "probes/replay_check.cl"}) {
            const Program program =
                Program::build_source(*ctx, file, lib.preprocess(file), options);
            // every kernel of the program that takes the scene (its first argument is `nodes`)
            for (const std::string& name : program.kernel_names()) {
                const auto args = kernel_arguments(program, name);
                if (args.empty() || args[0].second != "nodes") continue;
                INFO(file << ": " << name);
                checked.push_back(name);
                const std::vector<std::string> bad = mismatches(host, args);
                for (const std::string& m : bad)
                    INFO(m);
                CHECK(bad.empty());
                REQUIRE(args.size() > host.size());
                CHECK(args[host.size()] ==
                      std::make_pair(std::string("RenderParams"), std::string("rp")));
                // the comparison can fail: a binding with two arguments swapped does
                std::vector<std::pair<std::string, std::string>> swapped = host;
                std::swap(swapped[1], swapped[3]);
                CHECK(mismatches(swapped, args).size() == 2);
            }
        }
        std::sort(checked.begin(), checked.end());
        CHECK(checked ==
              std::vector<std::string>{"adjoint_pass", "adjoint_primal", "render_pass", "render_two_state",
                                       "replay_residual", "wf_generate", "wf_intersect",
                                       "wf_replay_shadow", "wf_shade", "wf_shade_replay",
                                       "wf_shade_two_state", "wf_shadow"});
    }

    TEST_CASE("a feature set that cannot render the scene is an error naming the flag") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = small_scene("three-spheres.xml");
        BuildFlags f = render_features(scene, *ctx);
        f.set("HAS_TEXTURES", 0);
        CHECK_THROWS_WITH_AS(DeviceScene(*ctx, KernelLibrary::from_environment(), scene, f),
                             doctest::Contains("HAS_TEXTURES=1"), Error);
        f = render_features(scene, *ctx);
        f.set("HAS_ENVMAP", 1); // an envmap where the scene has none changes the environment
        CHECK_THROWS_WITH_AS(DeviceScene(*ctx, KernelLibrary::from_environment(), scene, f),
                             doctest::Contains("HAS_ENVMAP=0"), Error);
        f = render_features(scene, *ctx);
        f.set("BSDF_DIELECTRIC", 1); // more than the scene needs is fine
        CHECK_NOTHROW(DeviceScene(*ctx, KernelLibrary::from_environment(), scene, f));
    }
}

TEST_SUITE("device scene") {
    TEST_CASE("shading's triangle and emitter normals are the unit normals of their vertices") {
        // checked in double precision, apart from the float functions the host computed them with
        auto unit_normal_of = [](const gpu::float4& a, const gpu::float4& b, const gpu::float4& c,
                                 float nx, float ny, float nz) {
            const glm::dvec3 p0(a.x, a.y, a.z), p1(b.x, b.y, b.z), p2(c.x, c.y, c.z);
            const glm::dvec3 n(nx, ny, nz), cross = glm::cross(p1 - p0, p2 - p0);
            return std::abs(glm::length(n) - 1.0) < 1e-6 &&
                   glm::dot(n, glm::normalize(cross)) > 1.0 - 1e-6;
        };
        const TriangleMesh mesh = test::mesh_with_analytic_shapes();
        REQUIRE(mesh.triangle_count() > 0);
        REQUIRE(mesh.primitive_count() > mesh.triangle_count());
        const std::vector<gpu::ShadingPrimitive> prims = shading_primitives(mesh);
        REQUIRE(prims.size() == mesh.primitive_count());
        for (std::size_t i = 0; i < prims.size(); ++i) {
            const gpu::ShadingPrimitive& p = prims[i];
            CHECK(gpu::as_uint(p.v0.w) == i);
            const gpu::float4& n = p.n_front;
            if (i < mesh.triangle_count())
                CHECK(unit_normal_of(p.v0, p.v1, p.v2, n.x, n.y, n.z));
            else // analytic: the normal depends on the point
                CHECK((n.x == 0.0f && n.y == 0.0f && n.z == 0.0f && n.w == 0.0f));
        }
        const RenderScene rs =
            build_render_scene(load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox.xml"));
        REQUIRE(!rs.emissive.empty());
        for (const gpu::EmissiveTriangle& e : rs.emissive)
            CHECK(unit_normal_of(e.p0, e.p1, e.p2, e.nx, e.ny, e.nz));
    }

    TEST_CASE("the guard counters are summed on the device, across chunks, and reset") {
        TANDEM_REQUIRE_DEVICE(ctx);
        // 70 x 70 = 4900 pixels: two chunks of the reduction, the second partial
        const RenderScene scene =
            build_render_scene(load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox.xml", {{"res", "70"}}));
        DeviceScene device(*ctx, KernelLibrary::from_environment(), scene);
        CHECK(device.read_guards() == 0u);
        std::vector<unsigned> counts(device.pixels());
        std::uint64_t expected = 0;
        for (std::size_t i = 0; i < counts.size(); ++i) {
            counts[i] = unsigned(i % 7 == 0 ? 10000000u + i : i % 3); // past 2^32 per chunk
            expected += counts[i];
        }
        device.guards().upload(counts);
        CHECK(expected > (std::uint64_t(1) << 32));
        CHECK(device.read_guards() == expected);
        device.reset_guards();
        CHECK(device.read_guards() == 0u);
    }
}

TEST_SUITE("parameter state") {
    TEST_CASE(
        "save and load restore every buffer, named ones included, without knowing what they hold") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = small_scene("cbox.xml");
        ParamState a(*ctx, scene.params);
        CHECK(test::same_bytes(a.theta().download(), scene.params.values()));
        struct Pair {
            float x;
            unsigned y;
        };
        a.add_buffer("test.pairs", 5, Pair{1.5f, 7u});
        a.add_buffer("test.floats", 3, 2.0f);
        CHECK_THROWS_AS(a.add_buffer("test.floats", 3, 2.0f), Error);
        CHECK_THROWS_AS(a.add_buffer("theta", 3, 2.0f), Error);
        std::vector<float> theta = scene.params.values();
        theta[0] = 0.125f;
        a.theta().upload(theta);
        a.add_buffer("adam.v", a.size(), 0.0f).upload(std::vector<float>(a.size(), 3.0f));
        a.buffer<float>("test.floats").upload({4.0f, 5.0f, 6.0f});
        a.count_step();
        a.count_step();
        SectionWriter writer;
        a.save(writer);
        const std::string saved = writer.bytes({'T', 'E', 'S', 'T', 'C', 'K', 'P', 'T'});
        const SectionReader sections("test.ckpt", saved);

        ParamState b(*ctx, scene.params);
        b.add_buffer("test.pairs", 5, Pair{0.0f, 0u});
        b.add_buffer("test.floats", 3, 0.0f);
        b.add_buffer("adam.v", b.size(), 0.0f); // an optimizer's moment (core/inverse/optimizer.h)
        b.load(sections);
        CHECK(b.steps() == 2u);
        CHECK(test::same_bytes(b.theta().download(), theta));
        CHECK(b.buffer<float>("adam.v").download() == std::vector<float>(a.size(), 3.0f));
        CHECK(b.buffer<float>("test.floats").download() == std::vector<float>{4.0f, 5.0f, 6.0f});
        CHECK(b.buffer<Pair>("test.pairs").download()[4].y == 7u);
        CHECK_THROWS_AS(b.buffer<float>("test.pairs"), Error); // another element type

        // a state without the named buffers, or with another size, is refused by name
        ParamState c(*ctx, scene.params);
        CHECK_THROWS_WITH_AS(c.load(sections), doctest::Contains("test.ckpt"), Error);
        ParamState d(*ctx, scene.params);
        d.add_buffer("test.pairs", 4, Pair{0.0f, 0u});
        d.add_buffer("test.floats", 3, 0.0f);
        d.add_buffer("adam.v", d.size(), 0.0f);
        CHECK_THROWS_WITH_AS(d.load(sections), doctest::Contains("'state:test.pairs'"), Error);
        CHECK(d.buffer<float>("test.floats").download() == std::vector<float>(3, 0.0f)); // untouched
        // one registered with any_size takes the saved size, and its reference stays valid
        ParamState e(*ctx, scene.params);
        Buffer<Pair>& pairs = e.add_buffer("test.pairs", 2, Pair{0.0f, 0u}, true);
        e.add_buffer("test.floats", 3, 0.0f);
        e.add_buffer("adam.v", e.size(), 0.0f);
        e.load(sections);
        REQUIRE(pairs.size() == 5u);
        CHECK(pairs.download()[4].x == 1.5f);
        CHECK(&e.buffer<Pair>("test.pairs") == &pairs);
        // a truncated file is damaged, whichever section it cuts
        CHECK_THROWS_WITH_AS(SectionReader("test.ckpt", saved.substr(0, saved.size() - 3)),
                             doctest::Contains("truncated"), DamagedFile);
    }
}
