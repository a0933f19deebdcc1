// Test helpers: the shared device context.
#include "support.h"

#include <cstdlib>
#include <iostream>
#include <memory>

#include <doctest/doctest.h>

#include "runtime/error.h"

namespace tandem::test {

/// Exit code that ctest reports as a skipped test (SKIP_RETURN_CODE in tests/CMakeLists.txt).
constexpr int k_skip_code = 77;

Context* device_context() {
    static std::unique_ptr<Context> ctx;
    static std::string error;
    if (!ctx && error.empty()) {
        try {
            ctx = std::make_unique<Context>(select_device());
        } catch (const Error& e) {
            error = e.what();
        }
    }
    if (ctx) return ctx.get();
    const char* allow = std::getenv("TANDEM_TESTS_ALLOW_NO_DEVICE");
    if (allow && std::string(allow) == "1") {
        std::cerr << "\n*** SKIPPED: no OpenCL device (" << error << ") ***\n\n";
        std::exit(k_skip_code);
    }
    FAIL("no OpenCL device (" << error
                              << "); set TANDEM_TESTS_ALLOW_NO_DEVICE=1 to skip device tests");
    return nullptr;
}

std::string mesh_path(const std::string& name) {
    return std::string(TANDEM_TEST_MESH_DIR) + "/" + name;
}

} // namespace tandem::test
