// Fuzzes OpenVDB grids as Tandem reads them (read_volume on a .vdb: read_vdb, a heterogeneous
// medium's density or albedo): OpenVDB's own reader, then the dense block Tandem makes of it.
// OpenVDB is a system library built without the sanitizers, so what this finds inside it is
// reported upstream, not fixed here; Tandem's part must reject every input with tandem::Error.
#include <cstddef>
#include <cstdint>

#include "core/io/volume_io.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = tandem::fuzz::write_input(data, size, "grid.vdb");
    tandem::fuzz::expect_load_or_error([&] { tandem::read_volume(path); });
    return 0;
}
