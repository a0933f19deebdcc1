// Fuzzes Mitsuba .vol grids as Tandem reads them (read_volume: a heterogeneous medium's
// density or albedo), and writes back what loaded (volume_bytes), which must give the same bytes.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "core/io/atomic_file.h"
#include "core/io/volume_io.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = tandem::fuzz::write_input(data, size, "grid.vol");
    tandem::fuzz::expect_load_or_error([&] {
        const tandem::VolumeGrid g = tandem::read_volume(path);
        if (tandem::volume_bytes(g) != tandem::read_file(path)) std::abort(); // not a round trip
    });
    return 0;
}
