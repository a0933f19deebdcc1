// The PRB adjoint's path record (kernels/path/record.h): adjoint_primal records the outcome of
// each NEE shadow ray, one bit per vertex, and the hits of the first bounces that the policy
// asks for (Tuning::hit_record_bounces); adjoint_pass reads them instead of tracing the rays again. The
// replay asks the same questions of the same rays, so the gradients must be the same bits as a
// build that traces every ray twice (SHADOW_RECORD=0, no hits recorded). The scenes below occlude
// many of their light samples (boxes, spheres over a floor), so a bit or a hit read at the wrong
// depth or sample changes the gradients. Measured (kernels copied into TANDEM_KERNEL_DIR and
// edited): with the replay reading shadow bit depth + 1, or its recorded hits with u and v
// swapped, every scene's gradients differ. That the replay reads the record at all is tested by
// altering it between the kernels; with the replay tracing every bounce again, that test fails.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <vector>

#include "core/inverse/gradient_step.h"
#include "core/render/features.h"
#include "core/render/passes.h"
#include "support.h"

using namespace tandem;

TEST_SUITE("gradient") {
    TEST_CASE("the replay reads its primal's record: the same gradients and guards as tracing "
              "every ray again") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        auto check = [&](const std::string& file) {
            INFO(file);
            const RenderScene scene =
                build_render_scene(load_scene(file, {{"res", "16"}, {"max_depth", "5"}}));
            BuildFlags features = render_features(scene, *ctx);
            features.set("WAVEFRONT", 0); // the megakernels: the wavefront has its own record
            // delta of every sign, and zero in a block of pixels (whose paths both passes skip)
            std::vector<float> d(3 * 16 * 16);
            for (std::size_t i = 0; i < d.size(); ++i)
                d[i] = (i / 3) % 16 < 5 ? 0.0f : 0.01f * float(int(i % 7) - 3);
            // (SHADOW_RECORD, the hits recorded): nothing recorded, then the shadow bits alone,
            // with the first two bounces' hits (later ones traced), and with every bounce's
            const std::vector<std::pair<int, unsigned>> runs = {{0, 0}, {1, 0}, {1, 2}, {1, 32}};
            std::vector<std::vector<float>> grads;
            std::vector<std::uint64_t> guards;
            for (const auto& [shadow, hits] : runs) {
                features.set("SHADOW_RECORD", shadow);
                const test::ScopedTuning tuning(*ctx, [&](Tuning& t) { t.hit_record_bounces = hits; });
                DeviceScene device(*ctx, lib, scene, features);
                const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
                Buffer<float> delta(*ctx, "delta", d);
                GradientBuffers grad(*ctx, scene.params.size());
                backward(device, theta, 7, 6, delta, grad); // two launches of samples: 4 + 2
                grads.push_back(grad.value.download());
                guards.push_back(device.read_guards());
            }
            for (std::size_t r = 1; r < runs.size(); ++r) {
                INFO("SHADOW_RECORD=" << runs[r].first << ", hits of " << runs[r].second
                                      << " bounces recorded");
                CHECK(test::same_bytes(grads[0], grads[r]));
                CHECK(guards[0] == guards[r]);
            }
            std::size_t nonzero = 0;
            for (float g : grads[0])
                nonzero += g != 0.0f;
            CHECK(nonzero > 0);
        };
        const std::string scenes = std::string(TANDEM_SOURCE_DIR) + "/scenes/";
        const std::string tests = std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/";
        // (scenes the other gradient tests build too, so that only the SHADOW_RECORD=0 programs
        // are new to the kernel cache)
        check(scenes + "cbox-wall.xml");     // an area light over two boxes, a textured wall
        check(scenes + "three-spheres.xml"); // spheres over a floor, rough plastic and conductor
        check(tests + "grad-delta.xml");     // point and spot lights, smooth materials
    }

    TEST_CASE("TANDEM_SHADOW_RECORD selects the build flag, TANDEM_HIT_RECORD the recorded "
              "bounces, and a bad value of either is a one-line error") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene = build_render_scene(
            load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox.xml", {{"res", "8"}}));
        // the variables, read into a Tuning
        auto read = [&](const char* name, const char* value) {
            const test::ScopedEnv env(name, value);
            return tuning_from_environment();
        };
        CHECK(read("TANDEM_SHADOW_RECORD", nullptr).shadow_record);
        CHECK(read("TANDEM_SHADOW_RECORD", "1").shadow_record);
        CHECK(!read("TANDEM_SHADOW_RECORD", "0").shadow_record);
        CHECK(read("TANDEM_HIT_RECORD", nullptr).hit_record_bounces == 32);
        CHECK(read("TANDEM_HIT_RECORD", "3").hit_record_bounces == 3);
        // the Tuning's, into the flag and the device scene's policy
        Tuning no_shadows;
        no_shadows.shadow_record = false;
        CHECK(render_features(scene, ctx->device(), Tuning{}).get("SHADOW_RECORD") == 1);
        CHECK(render_features(scene, ctx->device(), no_shadows).get("SHADOW_RECORD") == 0);
        BuildFlags features = render_features(scene, *ctx);
        features.set("WAVEFRONT", 0);
        {
            const test::ScopedTuning tuning(*ctx, [](Tuning& t) { t.hit_record_bounces = 5; });
            DeviceScene device(*ctx, lib, scene, features);
            CHECK(device.policy().hit_record_bounces == 5);
            const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
            Buffer<float> delta(*ctx, "delta", std::vector<float>(3 * 8 * 8, 0.01f));
            GradientBuffers grad(*ctx, scene.params.size());
            CHECK_NOTHROW(backward(device, theta, 7, 1, delta, grad));
        }
        const std::vector<std::pair<const char*, std::vector<const char*>>> bad = {
            {"TANDEM_SHADOW_RECORD", {"x", "-1", "", "2"}},
            {"TANDEM_HIT_RECORD", {"x", "-1", "", "33", "1e3", "99999999999"}}};
        for (const auto& [name, values] : bad)
            for (const char* value : values) {
                INFO(std::string(name) << "='" << std::string(value) << "'");
                try {
                    read(name, value);
                    FAIL("no error");
                } catch (const Error& e) {
                    const std::string what = e.what();
                    CHECK(what.find(name) != std::string::npos);
                    CHECK(what.find('\n') == std::string::npos);
                }
            }
    }

    TEST_CASE("the adjoint's launches: every bounce recorded up to max_depth, within 512 MiB") {
        auto launches = [](std::size_t pixels, unsigned max_depth, bool wavefront,
                           unsigned hits = k_max_hit_record_bounces) {
            return adjoint_launches(pixels, max_depth, wavefront, hits);
        };
        // 256^2, max_depth 8: four samples per launch, every bounce
        AdjointLaunches l = launches(256 * 256, 8, false);
        CHECK(l.samples == 4);
        CHECK(l.hit_bounces == 8);
        // unbounded paths: 32 bounces; the wavefront keeps its own record; fewer when asked
        CHECK(launches(256 * 256, 0xFFFFFFFFu, false).hit_bounces == 32);
        CHECK(launches(256 * 256, 8, true).hit_bounces == 0);
        CHECK(launches(256 * 256, 8, false, 3).hit_bounces == 3);
        CHECK(launches(256 * 256, 2, false, 3).hit_bounces == 2);
        // 1024^2, max_depth 8: 144 bytes per sample (16 + 8 x 16), 3 samples per launch
        l = launches(1024 * 1024, 8, false);
        CHECK(l.samples == 3);
        CHECK(l.hit_bounces == 8);
        // 1024^2, 32 bounces: one sample per launch and 31 bounces (32 words of 16 bytes a pixel)
        l = launches(1024 * 1024, 32, false);
        CHECK(l.samples == 1);
        CHECK(l.hit_bounces == 31);
        // 4096^2: one sample, and the one bounce that the rest of 512 MiB holds
        l = launches(4096 * 4096, 8, false);
        CHECK(l.samples == 1);
        CHECK(l.hit_bounces == 1);
        // whatever the size, radiance and hits fit in 512 MiB where the radiance alone does
        for (std::size_t pixels : {1u << 10, 1u << 16, 1u << 20, 3u << 20, 1u << 24, 1u << 25})
            for (unsigned depth : {1u, 5u, 8u, 32u, 0xFFFFFFFFu}) {
                l = launches(pixels, depth, false);
                INFO(pixels << " pixels, max_depth " << depth);
                CHECK(l.samples >= 1);
                CHECK(std::size_t(l.samples) * pixels * 16 * (1 + l.hit_bounces) <=
                      std::max<std::size_t>(std::size_t(512) << 20, pixels * 16));
            }
    }

    TEST_CASE("adjoint_pass reads the record adjoint_primal left: a changed record changes the "
              "gradients") {
        // The test above cannot tell a replay that reads its record from one that traces every
        // ray again. Here the record is altered between the two kernels: flipping the shadow
        // bits, or swapping u and v of the recorded hits, must change the gradients.
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const RenderScene scene =
            build_render_scene(load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox-wall.xml",
                                          {{"res", "16"}, {"max_depth", "5"}}));
        BuildFlags features = render_features(scene, *ctx);
        features.set("WAVEFRONT", 0);
        DeviceScene device(*ctx, lib, scene, features);
        const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
        const std::size_t pixels = device.pixels();
        Buffer<float> delta(*ctx, "delta", std::vector<float>(3 * pixels, 0.01f));
        gpu::RenderParams rp = device.launch_params(7);
        rp.sample_begin = 0;
        rp.sample_count = 2;
        const unsigned bounces = 5;
        Buffer<gpu::float4> record(*ctx, "record", 2 * pixels);
        Buffer<gpu::Hit> hits(*ctx, "hits", bounces * 2 * pixels);
        device.launch(0, device.kernel("adjoint.cl", "adjoint_primal"), "test", pixels, rp, theta,
                      delta, device.no_reservoirs(), 0u, 0u, record, hits, bounces);
        const std::vector<gpu::float4> kept_record = record.download();
        const std::vector<gpu::Hit> kept_hits = hits.download();
        // the adjoint pass over the given record, its fixed-point sums decoded
        auto gradient = [&](const std::vector<gpu::float4>& r, const std::vector<gpu::Hit>& h) {
            record.upload(r);
            hits.upload(h);
            GradientBuffers grad(*ctx, scene.params.size());
            device.launch(0, device.kernel("adjoint.cl", "adjoint_pass"), "test", pixels, rp, theta,
                          delta, device.no_reservoirs(), 0u, 0u, 0.5f, grad.exponent, record, hits,
                          bounces, grad.active, grad.fixed, device.guards());
            const auto count = static_cast<unsigned>(grad.value.size());
            device.kernel("adjoint.cl", "decode_gradients")
                .launch(*ctx, "test", count, grad.fixed, grad.exponent, grad.value, count,
                        device.guards());
            return grad.value.download();
        };
        const std::vector<float> base = gradient(kept_record, kept_hits);
        std::size_t nonzero = 0;
        for (float g : base)
            nonzero += g != 0.0f;
        REQUIRE(nonzero > 0);
        CHECK(test::same_bytes(base, gradient(kept_record, kept_hits))); // run to run
        std::vector<gpu::float4> flipped = kept_record;
        std::uint32_t shadow_bits = 0;
        for (gpu::float4& v : flipped) {
            std::uint32_t w;
            std::memcpy(&w, &v.w, 4);
            shadow_bits |= w;
            w = ~w;
            std::memcpy(&v.w, &w, 4);
        }
        CHECK(shadow_bits != 0u); // some shadow ray reached its light
        CHECK(!test::same_bytes(base, gradient(flipped, kept_hits)));
        std::vector<gpu::Hit> swapped = kept_hits;
        for (gpu::Hit& hit : swapped)
            std::swap(hit.u, hit.v);
        CHECK(!test::same_bytes(base, gradient(kept_record, swapped)));
    }
}
