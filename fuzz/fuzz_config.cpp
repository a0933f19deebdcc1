// Fuzzes the JSON config of `tandem optimize` (load_optimize_config): parsing, types, ranges.
#include <cstddef>
#include <cstdint>

#include "core/inverse/optimize_config.h"
#include "fuzz/fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string path = tandem::fuzz::write_input(data, size, "config.json");
    tandem::fuzz::expect_load_or_error([&] { tandem::load_optimize_config(path); });
    return 0;
}
