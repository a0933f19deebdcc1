// Test helpers: the shared device context.
#include "support.h"

#include <iostream>
#include <memory>

#include "runtime/error.h"

namespace tandem::test {

Context* device_context() {
    static std::unique_ptr<Context> ctx;
    static bool tried = false;
    if (!tried) {
        tried = true;
        try {
            ctx = std::make_unique<Context>(select_device());
        } catch (const Error& e) {
            std::cerr << "\n*** SKIPPING DEVICE TESTS: no OpenCL device (" << e.what() << ") ***\n\n";
        }
    }
    return ctx.get();
}

std::string mesh_path(const std::string& name) { return std::string(TANDEM_TEST_MESH_DIR) + "/" + name; }

} // namespace tandem::test
