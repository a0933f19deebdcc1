// Device discovery and selection.
#include <doctest/doctest.h>

#include <cstdlib>
#include <string>

#include "runtime/context.h"
#include "runtime/device.h"
#include "runtime/error.h"
#include "runtime/launch.h"
#include "runtime/pocl_llvm.h"
#include "runtime/program.h"
#include "support.h"

using namespace tandem;

TEST_SUITE("device") {
    TEST_CASE("devices are listed with their properties") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const std::vector<DeviceInfo> devices = list_devices();
        REQUIRE(!devices.empty());
        for (std::size_t i = 0; i < devices.size(); ++i) {
            CHECK(devices[i].index == static_cast<int>(i));
            CHECK(!devices[i].name.empty());
            CHECK(devices[i].compute_units > 0);
            CHECK(devices[i].native_float_width > 0);
            CHECK(devices[i].global_mem_bytes > 0);
            CHECK(devices[i].opencl_c_version.rfind("OpenCL C", 0) == 0);
        }
    }

    TEST_CASE("selection by index, by name substring, and from TANDEM_DEVICE") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const std::vector<DeviceInfo> devices = list_devices();
        const DeviceInfo& last = devices.back();
        CHECK(select_device(std::to_string(last.index)).name == last.name);
        // a lower-case fragment of the name matches case-insensitively
        std::string fragment = last.name.substr(0, std::min<std::size_t>(6, last.name.size()));
        for (char& c : fragment)
            c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        CHECK(select_device(fragment).name.find(last.name.substr(0, fragment.size())) == 0);
        // an empty spec: the Tuning's device (TANDEM_DEVICE), else the default
        const test::ScopedEnv env("TANDEM_DEVICE", std::to_string(last.index));
        Tuning tuning = tuning_from_environment();
        CHECK(tuning.device == std::to_string(last.index));
        CHECK(select_device(tuning.device).index == last.index);
        CHECK(Context::create("", tuning).device().index == last.index);
        // the command line's --device comes first
        CHECK(Context::create("0", tuning).device().index == 0);
    }

    TEST_CASE("an unknown device is an error that names it") {
        TANDEM_REQUIRE_DEVICE(ctx);
        CHECK_THROWS_WITH_AS(select_device("no-such-device-xyz"),
                             doctest::Contains("no-such-device-xyz"), Error);
        CHECK_THROWS_WITH_AS(select_device("999"), doctest::Contains("out of range"), Error);
    }

    TEST_CASE("the wavefront's SIMD shading is expected where PoCL compiles for AVX-512") {
        // no device needed: the rule reads the platform, the type and PoCL's target in the name
        DeviceInfo d;
        d.platform = "Portable Computing Language";
        d.type = "CPU";
        for (const char* name : {"pthread-skylake-avx512", "cpu-sapphirerapids-Intel(R) Xeon(R)",
                                 "pthread-ZNVER4-AMD EPYC", "pthread-icelake-server"}) {
            d.name = name;
            CHECK_MESSAGE(pocl_widens_gathers(d), name);
        }
        for (const char* name : {"pthread-haswell-AMD EPYC", "pthread-skylake", "pthread-znver3",
                                 "pthread-generic", "cpu-cortex-a72"}) {
            d.name = name;
            CHECK_MESSAGE(!pocl_widens_gathers(d), name);
        }
        d.name = "pthread-skylake-avx512";
        d.type = "GPU";
        CHECK(!pocl_widens_gathers(d));
        d.type = "CPU";
        d.platform = "Intel(R) OpenCL";
        CHECK(!pocl_widens_gathers(d));
    }

    TEST_CASE("PoCL's work-group method: loops without vectorisers where megakernels run") {
        DeviceInfo d;
        d.platform = "Portable Computing Language";
        d.type = "CPU";
        d.name = "pthread-haswell-AMD EPYC";
        CHECK(pocl_work_group_method(d, nullptr) == std::string("workitemloops"));
        // the user's setting stays, whatever it is
        CHECK(pocl_work_group_method(d, "loopvec") == nullptr);
        CHECK(pocl_work_group_method(d, "") == nullptr);
        // AVX-512: the wavefront's stages need PoCL's loop vectoriser
        d.name = "pthread-skylake-avx512";
        CHECK(pocl_work_group_method(d, nullptr) == nullptr);
        d.name = "pthread-haswell-AMD EPYC";
        d.type = "GPU";
        CHECK(pocl_work_group_method(d, nullptr) == nullptr);
        d.type = "CPU";
        d.platform = "Intel(R) OpenCL";
        CHECK(pocl_work_group_method(d, nullptr) == nullptr);
    }

    TEST_CASE("a context waits for its queue before it is released") {
        // A command left in the queue when the process exits (its caller threw after a launch)
        // would otherwise still run, or on PoCL still be compiled by LLVM, while exit() tears
        // down the libraries it uses: a crash after every test had passed.
        TANDEM_REQUIRE_DEVICE(ctx);
        const char* src = R"(
            __kernel void spin(__global uint* out, uint n, uint count) {
                const uint id = get_global_id(0);
                uint x = id;
                for (uint i = 0; i < n; ++i)
                    x = x * 1664525u + 1013904223u;
                if (id < count) out[id] = x;
            })";
        cl::Event done;
        {
            Context own(ctx->device(), ctx->tuning());
            const Program program = Program::build_source(own, "spin", src, "");
            Kernel spin(program, "spin");
            Buffer<std::uint32_t> out(own, "out", 64);
            spin.launch(own, "spin", 64, out, 1u << 22, 64u); // ~0.1 s on a 2-core CPU
            own.queue().enqueueMarkerWithWaitList(nullptr, &done);
        }
        CHECK(done.getInfo<CL_EVENT_COMMAND_EXECUTION_STATUS>() == CL_COMPLETE);
    }

    TEST_CASE("a context on PoCL's CPU device leaves PoCL the work-group method chosen for it") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const DeviceInfo& d = ctx->device();
        // the environment holds the choice for this device (or the user's own value) before any
        // kernel is compiled: the context set it (read back as a Tuning reads it)
        const std::optional<std::string> set = tuning_from_environment().pocl_work_group_method;
        if (pocl_work_group_method(d, nullptr)) CHECK(set.has_value());
        // and every program's cache keys name it, so a kernel compiled with another method is
        // never taken for this one
        if (set && d.platform == "Portable Computing Language" && !set->empty())
            CHECK(base_build_options(d, ctx->tuning()).find("-D TANDEM_POCL_WG_") !=
                  std::string::npos);
    }
}
