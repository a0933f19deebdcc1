// The PRB adjoint's path record (kernels/path/record.h): adjoint_primal records the outcome of
// each NEE shadow ray, one bit per vertex, and the hits of the first bounces that
// $TANDEM_HIT_RECORD asks for; adjoint_pass reads them instead of tracing the rays again. The
// replay asks the same questions of the same rays, so the gradients must be the same bits as a
// build that traces every ray twice (SHADOW_RECORD=0, no hits recorded). The scenes below occlude
// many of their light samples (boxes, spheres over a floor), so a bit or a hit read at the wrong
// depth or sample changes the gradients. Measured (kernels copied into TANDEM_KERNEL_DIR and
// edited): with the replay reading shadow bit depth + 1, or its recorded hits with u and v
// swapped, every scene's gradients differ.
#include <doctest/doctest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "core/inverse/gradient_step.h"
#include "core/render/features.h"
#include "support.h"

using namespace tandem;

namespace {

/// Runs f() with the environment variable `name` set to `value` (unset for nullptr), and unset
/// again afterwards, also when f throws.
template <class F> auto with_env(const char* name, const char* value, F f) {
    if (value) setenv(name, value, 1);
    try {
        auto r = f();
        unsetenv(name);
        return r;
    } catch (...) {
        unsetenv(name);
        throw;
    }
}

} // namespace

TEST_SUITE("gradient") {
    TEST_CASE("the replay reads its primal's record: the same gradients and guards as tracing "
              "every ray again") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        auto check = [&](const std::string& file) {
            INFO(file);
            const RenderScene scene =
                build_render_scene(load_scene(file, {{"res", "16"}, {"max_depth", "5"}}));
            BuildFlags features = render_features(scene, ctx->device());
            features.set("WAVEFRONT", 0); // the megakernels: the wavefront has its own record
            // delta of every sign, and zero in a block of pixels (whose paths both passes skip)
            std::vector<float> d(3 * 16 * 16);
            for (std::size_t i = 0; i < d.size(); ++i)
                d[i] = (i / 3) % 16 < 5 ? 0.0f : 0.01f * float(int(i % 7) - 3);
            // (SHADOW_RECORD, $TANDEM_HIT_RECORD): nothing recorded, then the shadow bits alone,
            // with the first two bounces' hits (later ones traced), and with every bounce's
            const std::vector<std::pair<int, const char*>> runs = {
                {0, "0"}, {1, "0"}, {1, "2"}, {1, "32"}};
            std::vector<std::vector<float>> grads;
            std::vector<std::uint64_t> guards;
            for (const auto& [shadow, hits] : runs) {
                features.set("SHADOW_RECORD", shadow);
                DeviceScene device(*ctx, lib, scene, features);
                const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
                Buffer<float> delta(*ctx, "delta", d);
                GradientBuffers grad(*ctx, scene.params.size());
                with_env("TANDEM_HIT_RECORD", hits, [&] {
                    backward(device, theta, 7, 6, delta, grad); // two launches of samples: 4 + 2
                    return 0;
                });
                grads.push_back(grad.value.download());
                guards.push_back(device.read_guards());
            }
            for (std::size_t r = 1; r < runs.size(); ++r) {
                INFO("SHADOW_RECORD=" << runs[r].first
                                      << " TANDEM_HIT_RECORD=" << std::string(runs[r].second));
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
        auto flag = [&](const char* value) {
            return with_env("TANDEM_SHADOW_RECORD", value, [&] {
                return render_features(scene, ctx->device()).get("SHADOW_RECORD");
            });
        };
        CHECK(flag(nullptr) == 1);
        CHECK(flag("1") == 1);
        CHECK(flag("0") == 0);
        BuildFlags features = render_features(scene, ctx->device());
        features.set("WAVEFRONT", 0);
        DeviceScene device(*ctx, lib, scene, features);
        const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
        Buffer<float> delta(*ctx, "delta", std::vector<float>(3 * 8 * 8, 0.01f));
        GradientBuffers grad(*ctx, scene.params.size());
        auto hits = [&](const char* value) {
            return with_env("TANDEM_HIT_RECORD", value, [&] {
                backward(device, theta, 7, 1, delta, grad);
                return 0;
            });
        };
        CHECK_NOTHROW(hits("32"));
        const std::vector<std::pair<const char*, std::vector<const char*>>> bad = {
            {"TANDEM_SHADOW_RECORD", {"x", "-1", "", "2"}},
            {"TANDEM_HIT_RECORD", {"x", "-1", "", "33", "1e3", "99999999999"}}};
        for (const auto& [name, values] : bad)
            for (const char* value : values) {
                INFO(std::string(name) << "='" << std::string(value) << "'");
                try {
                    std::string(name) == "TANDEM_HIT_RECORD" ? hits(value) : flag(value);
                    FAIL("no error");
                } catch (const Error& e) {
                    const std::string what = e.what();
                    CHECK(what.find(name) != std::string::npos);
                    CHECK(what.find('\n') == std::string::npos);
                }
            }
    }
}
