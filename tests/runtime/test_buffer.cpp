// Typed buffers, kernel launch with stage timing, and allocation failure.
#include <doctest/doctest.h>

#include <numeric>

#include "runtime/error.h"
#include "runtime/launch.h"
#include "support.h"

using namespace tandem;

TEST_SUITE("device") {
    TEST_CASE("upload, launch with named stage, download") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const Program program = Program::build_source(
            *ctx, "scale-test",
            "__kernel void scale(__global const float* in, __global float* out, float k, uint n) {\n"
            "    const uint i = get_global_id(0);\n    if (i < n) out[i] = in[i] * k;\n}\n",
            "");
        Kernel scale(program, "scale");
        std::vector<float> data(1000);
        std::iota(data.begin(), data.end(), 0.0f);
        Buffer<float> in(*ctx, "in", data);
        Buffer<float> out(*ctx, "out", data.size());
        ctx->set_stage_timing(true);
        ctx->stage_times();
        scale.launch(*ctx, "scale", data.size(), in, out, 2.5f, static_cast<unsigned>(data.size()));
        scale.launch(*ctx, "scale", data.size(), in, out, 3.0f, static_cast<unsigned>(data.size()));
        const std::vector<float> result = out.download();
        for (std::size_t i = 0; i < data.size(); ++i) REQUIRE(result[i] == data[i] * 3.0f);
        const std::vector<StageTime> times = ctx->stage_times();
        REQUIRE(times.size() == 2);
        CHECK(times[0].stage == "scale");
        CHECK(times[0].count == 2);
        CHECK(times[0].seconds > 0.0);
        CHECK(times[1].stage == "download out");
        // timing is on request: off, nothing is recorded
        ctx->set_stage_timing(false);
        scale.launch(*ctx, "scale", data.size(), in, out, 1.0f, static_cast<unsigned>(data.size()));
        CHECK(ctx->stage_times().empty());
    }

    TEST_CASE("an allocation the device cannot hold is a clear error") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const std::size_t too_many = ctx->device().max_alloc_bytes / sizeof(float) + 1024;
        CHECK_THROWS_WITH_AS(Buffer<float>(*ctx, "huge", too_many),
                             doctest::Contains("out of device memory: cannot allocate"), Error);
        // the size in MiB with one decimal, and the buffer's name
        try {
            Buffer<float>(*ctx, "huge", too_many);
            FAIL("no error");
        } catch (const Error& e) {
            const std::string m = e.what();
            const std::size_t mib = m.find(" MiB for 'huge' on '");
            REQUIRE(mib != std::string::npos);
            // one decimal: "...allocate 2048.0 MiB", not "2048.000000 MiB"
            CHECK(m[mib - 2] == '.');
        }
    }

    TEST_CASE("uploading the wrong number of elements is an error") {
        TANDEM_REQUIRE_DEVICE(ctx);
        Buffer<int> b(*ctx, "small", 4);
        CHECK_THROWS_AS(b.upload(std::vector<int>(5)), Error);
    }
}
