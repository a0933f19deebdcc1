// Shared by the libFuzzer harnesses.
#include "fuzz/fuzz_common.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <OpenImageIO/imageio.h>
#include <unistd.h>

namespace tandem::fuzz {

namespace fs = std::filesystem;

namespace {

std::string make_work_dir() {
    // $TMPDIR, else /tmp
    const fs::path dir = fs::temp_directory_path() / ("tandem-fuzz-" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    for (const char* sub : {"textures", "meshes", "volumes"})
        fs::create_directory_symlink(fs::path(TANDEM_FUZZ_ASSETS) / sub, dir / sub);
    return dir.string();
}

void remove_work_dir() {
    std::error_code ec;
    fs::remove_all(work_dir(), ec); // removes the links, not what they point to
}

} // namespace

const std::string& work_dir() {
    // never destroyed: the atexit handler reads it after static destructors may have run
    static const std::string* dir = [] {
        auto* d = new std::string(make_work_dir());
        std::atexit(remove_work_dir);
        return d;
    }();
    return *dir;
}

std::string write_input(const std::uint8_t* data, std::size_t size, const std::string& name) {
    const std::string path = work_dir() + "/" + name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    out.close();
    if (!out) {
        std::perror(path.c_str());
        std::abort(); // the harness itself failed: not a finding
    }
    return path;
}

bool verbose() {
    static const bool on = std::getenv("TANDEM_FUZZ_VERBOSE") != nullptr;
    return on;
}

void single_threaded_images() {
    OIIO::attribute("threads", 1);
    OIIO::attribute("exr_threads", 1);
}

void build_and_check_bvh(const TriangleMesh& mesh, int width, LeafFormat leaves) {
    static const EmbreeDevice embree;
    const FlatBvh bvh = build_bvh(embree, mesh, width, leaves);
    try {
        check_bvh(bvh, mesh.primitive_count());
    } catch (const Error&) {
        __builtin_trap();
    }
}

} // namespace tandem::fuzz
