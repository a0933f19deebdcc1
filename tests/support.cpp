// Test helpers: the shared device context.
#include "support.h"

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <unistd.h>
#include <iostream>
#include <memory>

#include <doctest/doctest.h>
#include <glm/geometric.hpp>

#include "runtime/error.h"

namespace tandem::test {

/// Exit code that ctest reports as a skipped test (SKIP_RETURN_CODE in tests/CMakeLists.txt).
constexpr int k_skip_code = 77;

namespace {

/// The context device_context() opens once, released by release_device_context() before main
/// returns (tests/main.cpp).
std::unique_ptr<Context>& shared_context() {
    static std::unique_ptr<Context> ctx;
    return ctx;
}

} // namespace

void release_device_context() {
    shared_context().reset();
}

Context* device_context() {
    std::unique_ptr<Context>& ctx = shared_context();
    static std::string error;
    if (!ctx && error.empty()) {
        try {
            const Tuning tuning = tuning_from_environment();
            ctx = std::make_unique<Context>(select_device(tuning.device), tuning);
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

ScopedEnv::ScopedEnv(const std::string& name, const char* value) : m_name(name) {
    const char* old = std::getenv(name.c_str());
    m_had = old != nullptr;
    if (old) m_old = old;
    if (value)
        setenv(name.c_str(), value, 1);
    else
        unsetenv(name.c_str());
}

ScopedEnv::~ScopedEnv() {
    if (m_had)
        setenv(m_name.c_str(), m_old.c_str(), 1);
    else
        unsetenv(m_name.c_str());
}

std::string scratch_path(const std::string& name) {
    static const std::filesystem::path dir = [] {
        const auto d = std::filesystem::temp_directory_path() /
                       ("tandem-test-" + std::to_string(::getpid()));
        std::filesystem::create_directories(d);
        return d;
    }();
    return (dir / name).string();
}

std::string mesh_path(const std::string& name) {
    return std::string(TANDEM_TEST_MESH_DIR) + "/" + name;
}

TriangleMesh mesh_with_analytic_shapes() {
    TriangleMesh mesh = load_mesh(mesh_path("knot_small.obj"));
    const Bounds b = mesh.bounds();
    const float diag = glm::length(b.extent());
    std::uint32_t state = 12345u;
    auto uniform = [&] { // a 32-bit LCG: the test needs variety, not quality
        state = state * 1664525u + 1013904223u;
        return static_cast<float>(state >> 8) * (1.0f / 16777216.0f);
    };
    for (int i = 0; i < 40; ++i) {
        Sphere s;
        s.center = b.lo + b.extent() * glm::vec3(uniform(), uniform(), uniform());
        s.radius = diag * (0.01f + 0.07f * uniform());
        s.orientation = i % 3 == 2 ? -1.0f : 1.0f;
        mesh.spheres.push_back(s);
    }
    for (int i = 0; i < 30; ++i) {
        Disk d;
        d.center = b.lo + b.extent() * glm::vec3(uniform(), uniform(), uniform());
        const glm::vec3 n = glm::normalize(glm::vec3(uniform(), uniform(), uniform()) - 0.5f);
        const glm::vec3 x = glm::normalize(glm::cross(n, std::fabs(n.x) < 0.9f ? glm::vec3(1, 0, 0)
                                                                               : glm::vec3(0, 1, 0)));
        const float radius = diag * (0.01f + 0.07f * uniform());
        d.x_axis = x * radius;
        d.y_axis = glm::cross(n, x) * radius;
        d.orientation = i % 3 == 2 ? -1.0f : 1.0f;
        mesh.disks.push_back(d);
    }
    return mesh;
}

} // namespace tandem::test
