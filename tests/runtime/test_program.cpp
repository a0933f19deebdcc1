// Kernel source preprocessing, build errors mapped to file:line, and the program binary cache.
#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <unistd.h>

#include "runtime/error.h"
#include "runtime/program.h"
#include "support.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

/// A throwaway kernels/-like directory.
struct TempKernels {
    fs::path dir;
    TempKernels() {
        dir = fs::temp_directory_path() / ("tandem-test-kernels-" + std::to_string(::getpid()));
        fs::create_directories(dir / "shared");
    }
    ~TempKernels() { fs::remove_all(dir); }
    void write(const std::string& name, const std::string& text) const {
        std::ofstream(dir / name) << text;
    }
};

} // namespace

TEST_SUITE("program") {
    TEST_CASE("includes are inlined once, with #line markers naming the real files") {
        TempKernels k;
        k.write("main.cl", "// main\n#include \"shared/a.h\"\n#include \"shared/a.h\"\nint x;\n");
        k.write("shared/a.h", "int a;\n");
        const std::string src = KernelLibrary::from_directory(k.dir.string()).preprocess("main.cl");
        CHECK(src == "#line 1 \"kernels/main.cl\"\n// main\n#line 1 \"kernels/shared/a.h\"\nint a;\n"
                     "#line 3 \"kernels/main.cl\"\n#line 4 \"kernels/main.cl\"\nint x;\n");
    }

    TEST_CASE("a missing include names the including file and line") {
        TempKernels k;
        k.write("main.cl", "\n\n#include \"shared/missing.h\"\n");
        CHECK_THROWS_WITH_AS(KernelLibrary::from_directory(k.dir.string()).preprocess("main.cl"),
                             doctest::Contains("kernels/main.cl:3"), Error);
    }

    TEST_CASE("the embedded kernels and TANDEM_KERNEL_DIR serve the same files") {
        const std::string embedded = KernelLibrary::embedded().read("render.cl");
        const KernelLibrary disk = KernelLibrary::from_directory(std::string(TANDEM_SOURCE_DIR) + "/kernels");
        CHECK(embedded == disk.read("render.cl"));
        test::ScopedEnv env("TANDEM_KERNEL_DIR", std::string(TANDEM_SOURCE_DIR) + "/kernels");
        CHECK(KernelLibrary::from_environment().origin() == std::string(TANDEM_SOURCE_DIR) + "/kernels");
    }

    TEST_CASE("a build failure is one line naming the file and line of the error") {
        TANDEM_REQUIRE_DEVICE(ctx);
        TempKernels k;
        k.write("broken.cl", "#include \"shared/util.h\"\n__kernel void f(__global int* o) {\n"
                             "    o[0] = helper();\n}\n");
        k.write("shared/util.h", "int helper(void) {\n    return 1\n}\n"); // missing ';' on line 2
        const test::ScopedTuning no_cache(*ctx, [](Tuning& t) { t.cache_dir.clear(); });
        try {
            Program::build(*ctx, KernelLibrary::from_directory(k.dir.string()), "broken.cl", "");
            FAIL("the build should have failed");
        } catch (const Error& e) {
            const std::string what = e.what();
            CHECK(what.find("kernels/broken.cl") != std::string::npos);
            CHECK(what.find("kernels/shared/util.h:2") != std::string::npos);
            CHECK(what.find('\n') == std::string::npos);
            CHECK(!e.detail().empty()); // the full log is kept for --verbose
        }
    }

    TEST_CASE("a kernel name the program lacks is an error that lists the kernels it has") {
        TANDEM_REQUIRE_DEVICE(ctx);
        TempKernels k;
        k.write("two.cl", "__kernel void first(__global int* o) { o[0] = 1; }\n"
                          "__kernel void second(__global int* o) { o[0] = 2; }\n");
        const Program p = Program::build(*ctx, KernelLibrary::from_directory(k.dir.string()), "two.cl", "");
        CHECK_NOTHROW(p.kernel("second"));
        CHECK_THROWS_WITH_AS(p.kernel("third"),
                             doctest::Contains("kernel 'third' not found in kernels/two.cl"), Error);
        try {
            p.kernel("third");
        } catch (const Error& e) {
            const std::string what = e.what();
            CHECK(what.find("CL_INVALID_KERNEL_NAME") != std::string::npos);
            CHECK(what.find("first") != std::string::npos);
            CHECK(what.find("second") != std::string::npos);
        }
    }

    TEST_CASE("program binaries are cached by source, options and device") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const fs::path dir =
            fs::temp_directory_path() / ("tandem-test-cache-" + std::to_string(::getpid()));
        fs::remove_all(dir);
        const test::ScopedTuning cache(*ctx, [&](Tuning& t) { t.cache_dir = dir.string(); });
        const std::string src = "__kernel void f(__global int* o) { o[0] = VALUE; }\n";
        const Program first = Program::build_source(*ctx, "cache-test", src, "-D VALUE=1");
        CHECK(!first.from_cache());
        CHECK(std::distance(fs::directory_iterator(dir), fs::directory_iterator{}) == 1);
        const Program second = Program::build_source(*ctx, "cache-test", src, "-D VALUE=1");
        CHECK(second.from_cache());
        const Program other = Program::build_source(*ctx, "cache-test", src, "-D VALUE=2");
        CHECK(!other.from_cache());
        // A corrupt cache entry is ignored and rebuilt, not an error.
        for (const auto& entry : fs::directory_iterator(dir)) std::ofstream(entry.path()) << "garbage";
        const Program rebuilt = Program::build_source(*ctx, "cache-test", src, "-D VALUE=1");
        CHECK(!rebuilt.from_cache());
        CHECK(Program::build_source(*ctx, "cache-test", src, "-D VALUE=1").from_cache());
        fs::remove_all(dir);
    }

    TEST_CASE("a Tuning from the environment: the cache directory, the kernels, the build options") {
        {
            const test::ScopedEnv dir("TANDEM_CACHE_DIR", "/somewhere/cache");
            const test::ScopedEnv off("TANDEM_NO_CACHE", nullptr);
            CHECK(tuning_from_environment().cache_dir == "/somewhere/cache");
            const test::ScopedEnv on("TANDEM_NO_CACHE", "1");
            CHECK(tuning_from_environment().cache_dir.empty());
        }
        {
            const test::ScopedEnv dir("TANDEM_CACHE_DIR", nullptr);
            const test::ScopedEnv xdg("XDG_CACHE_HOME", "/xdg");
            CHECK(tuning_from_environment().cache_dir == "/xdg/tandem");
            const test::ScopedEnv no_xdg("XDG_CACHE_HOME", nullptr);
            const test::ScopedEnv home("HOME", "/home/someone");
            CHECK(tuning_from_environment().cache_dir == "/home/someone/.cache/tandem");
        }
        {
            const test::ScopedEnv kill("TANDEM_KILL_AT", "write-middle:3");
            const test::ScopedEnv fail("TANDEM_FAIL_WRITE", "x");
            const Tuning t = tuning_from_environment();
            CHECK(t.faults.kill_point == "write-middle");
            CHECK(t.faults.kill_count == 3);
            CHECK(t.faults.fail_write == 0); // malformed: never
        }
        DeviceInfo d;
        d.correctly_rounded_divide_sqrt = true;
        Tuning t;
        CHECK(base_build_options(d, t) == "-cl-std=CL1.2 -cl-fp32-correctly-rounded-divide-sqrt");
        t.kernel_debug = true;
        t.pocl_slp = true;
        CHECK(base_build_options(d, t) ==
              "-cl-std=CL1.2 -cl-fp32-correctly-rounded-divide-sqrt -g -D TANDEM_POCL_SLP=1");
    }
}
