// Host/device parity of every shared struct's size and field offsets.
#include <doctest/doctest.h>

#include <cstddef>

#include "runtime/launch.h"
#include "probes/layout_probe.h"
#include "probes/probes.h"
#include "support.h"

using namespace tandem;
using namespace tandem::gpu;

TEST_SUITE("device") {
    TEST_CASE("shared structs have the same layout on host and device") {
        TANDEM_REQUIRE_DEVICE(ctx);
        std::vector<unsigned> host;
        std::vector<std::string> names;
#define HOST_STRUCT(T)                                                                             \
    host.push_back(sizeof(T));                                                                     \
    names.push_back("sizeof(" #T ")");
#define HOST_FIELD(T, f)                                                                           \
    host.push_back(offsetof(T, f));                                                                \
    names.push_back("offsetof(" #T ", " #f ")");
        TANDEM_SHARED_LAYOUT(HOST_STRUCT, HOST_FIELD)
#undef HOST_STRUCT
#undef HOST_FIELD

        const Program program =
            Program::build(*ctx, probe_library(), "probes/layout.cl", "");
        Kernel probe(program, "layout_probe");
        const unsigned capacity = 256;
        Buffer<unsigned> out(*ctx, "layout", capacity);
        probe.launch(*ctx, "layout probe", 1, out, capacity);
        const std::vector<unsigned> device = out.download();
        REQUIRE(device[capacity - 1] == host.size());
        for (std::size_t i = 0; i < host.size(); ++i) {
            INFO(names[i]);
            CHECK(device[i] == host[i]);
        }
    }
}
