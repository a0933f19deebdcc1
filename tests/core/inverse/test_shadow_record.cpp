// The PRB adjoint's shadow record (kernels/path/nee.h, ShadowRecord): adjoint_primal records the
// outcome of each NEE shadow ray, one bit per vertex, and adjoint_pass reads them instead of
// tracing the rays again. The replay asks the same questions of the same rays, so the gradients
// must be the same bits as a build that traces every shadow ray twice (SHADOW_RECORD=0). The
// scenes below occlude many of their light samples (boxes, spheres over a floor), so a bit read
// at the wrong depth or vertex changes the gradients. Measured: with the replay reading bit
// depth + 1 (kernels copied into TANDEM_KERNEL_DIR and edited), every scene's gradients differ.
#include <doctest/doctest.h>

#include <cstdlib>
#include <string>
#include <vector>

#include "core/inverse/gradient_step.h"
#include "core/render/features.h"
#include "support.h"

using namespace tandem;

TEST_SUITE("gradient") {
    TEST_CASE("the replay reads its primal's shadow record: the same gradients and guards as "
              "tracing every shadow ray again") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        auto check = [&](const std::string& file) {
            INFO(file);
            const RenderScene scene =
                build_render_scene(load_scene(file, {{"res", "16"}, {"max_depth", "5"}}));
            BuildFlags features = render_features(scene, ctx->device());
            features.set("WAVEFRONT", 0); // the megakernels: the wavefront records hits instead
            // delta of every sign, and zero in a block of pixels (whose paths both passes skip)
            std::vector<float> d(3 * 16 * 16);
            for (std::size_t i = 0; i < d.size(); ++i)
                d[i] = (i / 3) % 16 < 5 ? 0.0f : 0.01f * float(int(i % 7) - 3);
            std::vector<float> grads[2];
            std::uint64_t guards[2];
            for (int record : {0, 1}) {
                features.set("SHADOW_RECORD", record);
                DeviceScene device(*ctx, lib, scene, features);
                const Buffer<float> theta = parameter_buffer(*ctx, scene.params);
                Buffer<float> delta(*ctx, "delta", d);
                GradientBuffers grad(*ctx, scene.params.size());
                backward(device, theta, 7, 6, delta, grad); // two launches of samples: 4 + 2
                grads[record] = grad.value.download();
                guards[record] = device.read_guards();
            }
            CHECK(test::same_bytes(grads[0], grads[1]));
            CHECK(guards[0] == guards[1]);
            std::size_t nonzero = 0;
            for (float g : grads[1])
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

    TEST_CASE("TANDEM_SHADOW_RECORD selects the build flag, and a bad value is a one-line error") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const RenderScene scene = build_render_scene(
            load_scene(std::string(TANDEM_SOURCE_DIR) + "/scenes/cbox.xml", {{"res", "8"}}));
        auto flag = [&](const char* value) {
            if (value) setenv("TANDEM_SHADOW_RECORD", value, 1);
            try {
                const int f = render_features(scene, ctx->device()).get("SHADOW_RECORD");
                unsetenv("TANDEM_SHADOW_RECORD");
                return f;
            } catch (...) {
                unsetenv("TANDEM_SHADOW_RECORD");
                throw;
            }
        };
        CHECK(flag(nullptr) == 1);
        CHECK(flag("1") == 1);
        CHECK(flag("0") == 0);
        for (const char* bad : {"x", "-1", "", "2"}) {
            INFO("TANDEM_SHADOW_RECORD='" << bad << "'");
            try {
                flag(bad);
                FAIL("no error");
            } catch (const Error& e) {
                const std::string what = e.what();
                CHECK(what.find("TANDEM_SHADOW_RECORD") != std::string::npos);
                CHECK(what.find('\n') == std::string::npos);
            }
        }
    }
}
