// Shared by the libFuzzer harnesses: a private folder for the inputs (loaders read files), and
// the rule that a bad input may only be rejected with tandem::Error.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

#include "core/bvh/bvh_build.h"
#include "runtime/error.h"

namespace tandem::fuzz {

/// A fresh folder of this process under $TMPDIR (removed at exit), holding links to the assets
/// the seed inputs refer to by relative paths: textures/ and meshes/ (fuzz/assets).
const std::string& work_dir();

/// Writes `size` bytes to work_dir()/name and returns its path.
std::string write_input(const std::uint8_t* data, std::size_t size, const std::string& name);

/// Keeps the image libraries on one thread (the fuzzers run beside other work).
void single_threaded_images();

/// Builds `mesh`'s BVH in this layout and checks it with check_bvh; a malformed tree is a finding
/// (check_bvh's tandem::Error would count as a rejection, so this aborts instead). An Error of the
/// build itself is a rejection, as from a loader.
void build_and_check_bvh(const TriangleMesh& mesh, int width, LeafFormat leaves);

/// True when $TANDEM_FUZZ_VERBOSE is set: print why each input was rejected (for triage).
bool verbose();

/// Runs f(). A tandem::Error with a one-line message is the correct answer to a bad input; a
/// message of several lines aborts (a finding), and any other exception escapes to libFuzzer,
/// which reports it (uncaught: std::terminate) as a crash.
template <class F> void expect_load_or_error(F&& f) {
    try {
        f();
        if (verbose()) std::fprintf(stderr, "loaded\n");
    } catch (const Error& e) {
        if (verbose()) std::fprintf(stderr, "rejected: %s\n", e.what());
        if (std::strchr(e.what(), '\n')) {
            std::fprintf(stderr, "fuzz: an Error message of more than one line: %s\n", e.what());
            std::abort();
        }
    }
}

} // namespace tandem::fuzz
