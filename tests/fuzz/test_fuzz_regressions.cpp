// What the libFuzzer harnesses (fuzz/, scripts/fuzz.sh) found, kept as regressions: each input
// that crashed, tripped a sanitizer, threw another exception type or allocated without bound is now
// rejected with a one-line tandem::Error naming the file and what is wrong. The inputs live in
// tests/fuzz-regressions/<harness>/, as the files Tandem reads (the harnesses' leading
// format byte removed); the last cases run every stored input as its harness does.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <unistd.h>

#include "core/inverse/optimize_config.h"
#include "core/io/image_io.h"
#include "core/scene/mesh.h"
#include "core/scene/render_scene.h"
#include "core/scene/scene.h"
#include "runtime/error.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

const fs::path k_regressions = fs::path(TANDEM_SOURCE_DIR) / "tests" / "fuzz-regressions";

std::string regression(const std::string& name) { return (k_regressions / name).string(); }

/// A folder of this process for inputs written by the tests, removed at exit.
struct ScratchDir {
    fs::path dir = fs::temp_directory_path() / ("tandem-fuzz-test-" + std::to_string(getpid()));
    ScratchDir() { fs::create_directories(dir); }
    ~ScratchDir() {
        std::error_code ec;
        fs::remove_all(dir, ec);
    }
};

std::string write_file(const std::string& name, const std::string& text) {
    static const ScratchDir scratch;
    const std::string path = (scratch.dir / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
}

/// The message of the Error that f() throws ("" if it throws none; another exception fails).
template <class F> std::string error_of(F&& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

/// The message of the Error that reading the image at `path` throws ("" if none).
std::string read_image_error(const std::string& path) {
    return error_of([&] {
        int w = 0, h = 0;
        read_image(path, &w, &h);
    });
}

/// A config that loads, with `extra` ("key": value pairs) appended; its own target unless
/// `extra` gives one (a key given twice is an error of its own).
std::string config_with(const std::string& extra) {
    const bool own_target = extra.find("\"target\"") == std::string::npos;
    return R"({"scene": "s.xml", "params": {"p.alpha": {"lr": 0.1}})" +
           std::string(own_target ? R"(, "target": {"image": "t.exr"})" : "") +
           std::string(extra.empty() ? "" : ", ") + extra + "}";
}

} // namespace

TEST_CASE("fuzz: a JSON number beyond a double is malformed JSON, an Error naming the file") {
    // nlohmann::json throws its out_of_range (not a parse_error) for 1e3081: it escaped as
    // another exception type, without the file's name
    const std::string path = regression("config/number-overflow.json");
    CHECK(error_of([&] { load_optimize_config(path); }) ==
          path + ": malformed JSON: number overflow parsing '-1e3081'");
}

TEST_CASE("fuzz: config numbers outside their type's range are errors, not undefined casts") {
    // nlohmann converts with a plain cast: 1e300 as an int was undefined behaviour (UBSan),
    // -1 as the unsigned seed wrapped to 4294967295, 2.5 iterations truncated to 2
    const std::pair<const char*, const char*> cases[] = {
        {R"("iterations": 1e300)", "'iterations' must be an integer (1e+300)"},
        {R"("iterations": 2.5)", "'iterations' must be an integer (2.5)"},
        {R"("spp": 4294967296)", "'spp' is out of range (4294967296)"},
        {R"("seed": -1)", "'seed' is out of range (-1)"},
        {R"("epsilon": 1e300)", "'epsilon' is out of range (1e+300)"},
        {R"("target": {"scene": "t.xml", "spp": -2147483649})",
         "'spp' is out of range (-2147483649)"},
        {R"("batch": 4294967297)", "'batch' is out of range (4294967297)"},
        {R"("views": [4294967296])", "views: sensor index 4294967296 is out of range"},
        {R"("restir": {"candidates": 1e10})", "restir: 'candidates' must be an integer"},
        {R"("beta1": "0.5")", "'beta1' has the wrong type (\"0.5\")"},
    };
    for (const auto& [extra, message] : cases) {
        const std::string text = config_with(extra);
        const std::string path = write_file("config.json", text);
        INFO(text);
        CHECK(error_of([&] { load_optimize_config(path); }).find(message) != std::string::npos);
    }
    const std::string init = write_file(
        "init.json",
        R"({"scene": "s.xml", "target": {"image": "t.exr"}, "params": {"a.reflectance": {"lr": 0.1, "init": [0.5, 1e300, 0]}}})");
    CHECK(error_of([&] { load_optimize_config(init); }) ==
          init + ": params.a.reflectance: 'init' is out of range (1e+300)");
    // what loaded before still loads, with the same values
    const OptimizeConfig c = load_optimize_config(
        write_file("ok.json", config_with(R"("iterations": 7, "seed": 4294967295, "beta1": 0)")));
    CHECK(c.iterations == 7);
    CHECK(c.seed == 4294967295u);
    CHECK(c.beta1 == 0.0f);
    CHECK(c.params.at(0).lr == 0.1f);
}

TEST_CASE("fuzz: objects nested thousands deep are an error, not a stack overflow") {
    // 100000 nested <bsdf> overflowed the stack of the recursive parser (SIGSEGV)
    std::string text = "<scene version=\"3.0.0\">\n";
    const int depth = 100000;
    for (int i = 0; i < depth; ++i)
        text += "<bsdf type=\"twosided\">";
    for (int i = 0; i < depth; ++i)
        text += "</bsdf>";
    text += "\n</scene>\n";
    const std::string path = write_file("deep.xml", text);
    CHECK(error_of([&] { load_scene(path); }) ==
          path + ":2: <bsdf type=\"twosided\">: objects nested more than 64 levels deep");
}

TEST_CASE("fuzz: an image header that claims a huge size is refused before any allocation") {
    // 22 bytes claiming 100000x100000 texels: a 120 GB allocation (ASan: out of memory)
    const std::string path = regression("image/huge-header.pfm");
    CHECK(read_image_error(path) ==
          path + ": the image is 100000x100000, more than the 67108864 texels (8192x8192) "
                 "Tandem reads");
}

TEST_CASE("fuzz: an EXR header attribute larger than the file is refused before OpenEXR reads it") {
    // 340 bytes whose 'capDate' attribute claims 1929379859 bytes: OpenEXR allocated them first
    const std::string path = regression("image/exr-attribute-1.9gb.exr");
    CHECK(read_image_error(path) ==
          path + ": cannot read image: EXR header: attribute 'capDate' claims 1929379859 "
                 "bytes, the file has 84 left");
}

TEST_CASE("fuzz: an EXR attribute whose size field disagrees with its type is refused") {
    // 821 bytes whose channel list claims 55 bytes and holds 167: OpenEXR reads a channel list
    // up to its empty name, so it read the rest of the header from other offsets and then
    // allocated a string of 1868852755 bytes (fuzz_image: out of memory; 1.9 GB RSS without ASan)
    const std::string path = regression("image/exr-chlist-desync-1.9gb.exr");
    CHECK(read_image_error(path) ==
          path + ": cannot read image: EXR header: attribute 's' of type 'chlist' claims 55 "
                 "bytes and holds 167");
}

/// An EXR file's start: magic, version 2 (single part, scanlines), then `attributes` (name, type,
/// size, value each) and the header's end; no offset table or pixels (enough for the header
/// check, which refuses these before OpenEXR reads anything).
std::string exr_header(const std::string& attributes) {
    return std::string("\x76\x2f\x31\x01\x02\x00\x00\x00", 8) + attributes + std::string(1, '\0');
}

/// One attribute: name, type, the size field `size`, then `value`.
std::string exr_attribute(const std::string& name, const std::string& type, std::int32_t size,
                          const std::string& value) {
    std::string a = name + '\0' + type + '\0';
    a.append(reinterpret_cast<const char*>(&size), 4);
    return a + value;
}

std::string le32(std::int32_t v) {
    return std::string(reinterpret_cast<const char*>(&v), 4);
}

TEST_CASE("EXR headers: each attribute holds exactly what OpenEXR reads of its type") {
    auto error = [](const std::string& name, const std::string& bytes) {
        const std::string path = write_file(name, bytes);
        const std::string message = read_image_error(path);
        return message.substr(std::min(message.size(), path.size() + 2));
    };
    // a fixed-size type with another size: OpenEXR reads 16 bytes of a box2i whatever it says
    CHECK(error("box.exr", exr_header(exr_attribute("dataWindow", "box2i", 4, le32(0)) +
                                      std::string(40, 'x'))) ==
          "cannot read image: EXR header: attribute 'dataWindow' of type 'box2i' claims 4 bytes "
          "and holds 16");
    // a preview's pixels are its width times its height times 4 bytes, not its size field
    CHECK(error("preview.exr",
                exr_header(exr_attribute("preview", "preview", 8, le32(65536) + le32(65536)) +
                           std::string(40, 'x'))) ==
          "cannot read image: EXR header: attribute 'preview' of type 'preview' claims 8 bytes "
          "and holds 17179869192");
    // a string vector's strings stay within its size
    CHECK(error("vector.exr",
                exr_header(exr_attribute("names", "stringvector", 8, le32(2) + "ab" + le32(9)) +
                           std::string(40, 'x'))) ==
          "cannot read image: EXR header: attribute 'names' holds a string of 9 bytes past its "
          "end");
    // a channel list that holds exactly its size passes the check; OpenEXR then reports what is
    // missing (here, everything after the header)
    const std::string channel =
        std::string("R\0", 2) + le32(1) + std::string(4, '\0') + le32(1) + le32(1);
    const std::string fine =
        error("chlist.exr",
              exr_header(exr_attribute("channels", "chlist", std::int32_t(channel.size() + 1),
                                       channel + std::string(1, '\0'))));
    CHECK(fine.find("EXR header:") == std::string::npos);
    CHECK(fine.find("cannot read image") == 0);
}

TEST_CASE("fuzz: an image library's message of several lines becomes one line") {
    // a truncated PNG: OpenImageIO's message had two lines ("...\nPNG read error: ...")
    const std::string path = regression("image/truncated-two-line-error.png");
    const std::string message = read_image_error(path);
    CHECK(message == path + ": cannot read image (Read error: hit end of file; PNG read error: "
                            "Imag: Read error: hit end of file)");
    CHECK(one_line(" a \r\n\n b\n") == "a; b");
}

TEST_CASE("fuzz: an Error quoting a line break from a file is still one line") {
    // an EXR attribute name, a JSON key: what() showed the file's line breaks as they were
    CHECK(std::string(Error("a\nb\r").what()) == "a\\nb\\r");
    const std::string exr = regression("image/exr-name-with-line-break.exr");
    CHECK(read_image_error(exr) ==
          exr + ": cannot read image: EXR header: attribute '\\n16 16\\n-1.0\\n' claims "
                "16000 bytes, the file has 912 left");
    const std::string key = write_file("key.json", config_with(R"("lr\nate": 1)"));
    CHECK(error_of([&] { load_optimize_config(key); }).find("unknown key 'lr\\nate'") !=
          std::string::npos);
}

TEST_CASE("fuzz: malformed PLY files are errors before Assimp reads them") {
    // Assimp 5.2's PLY importer read past its buffer (SIGSEGV) on a garbled header, looped
    // forever without end_header, and aborted (an assertion) on a face without vertices and on
    // some unknown header lines: Tandem checks the file's structure first (core/scene/ply_check.h)
    const std::pair<const char*, const char*> cases[] = {
        {"header-garbage-segv.ply",
         "PLY header line 4: unexpected 'elemenperty list uchar int vertet uchar int vertex_indices'"},
        {"no-end-header-hang.ply", "PLY header line 11: unexpected '(nd_header'"},
        {"bad-property-abort.ply", "PLY header line 10: unexpected 'propertyl foat nz'"},
        {"empty-face-abort.ply", "element 'face' 0 has an empty vertex list"},
        {"empty-face-ascii.ply", "element 'face' 1 has an empty vertex list"},
    };
    for (const auto& [name, message] : cases) {
        const std::string path = regression(std::string("mesh/") + name);
        CHECK(error_of([&] { load_mesh(path); }) == path + ": cannot load mesh: " + message);
    }
    // and what the header promises must be there
    const std::string head = "ply\nformat binary_little_endian 1.0\nelement vertex 2\n"
                             "property float x\nproperty float y\nproperty float z\n"
                             "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    const std::string vertices(24, '\0');
    const std::string short_list = write_file("short.ply", head + vertices + "\x03" + std::string(8, '\0'));
    CHECK(error_of([&] { load_mesh(short_list); }) ==
          short_list + ": cannot load mesh: the PLY data ends inside element 'face' 0 of 1");
    const std::string no_ply = write_file("not.ply", "v 0 0 0\n");
    CHECK(error_of([&] { load_mesh(no_ply); }) ==
          no_ply + ": cannot load mesh: not a PLY file (the first line is not 'ply')");
    const std::string ascii = write_file(
        "ascii.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                     "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                     "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n");
    CHECK(error_of([&] { load_mesh(ascii); }) ==
          ascii + ": cannot load mesh: element 'face' 0: fewer values than the header declares");
}

TEST_CASE("fuzz: binary PLY data that begins with a line feed loads instead of aborting") {
    // Assimp's reader skipped the first data byte (0x0A) and made the face empty; its
    // triangulation then aborted the process (ply_for_assimp reads it right; test_mesh has the
    // values). The file's fourth vertex is NaN and unused, as the fuzzer left it.
    const std::string path = regression("mesh/lf-first-byte-abort.ply");
    const TriangleMesh mesh = load_mesh(path);
    REQUIRE(mesh.triangle_count() == 1);
    CHECK(mesh.positions.at(mesh.triangles[0].y) == glm::vec3(1.0f, -1.0f, 0.0f));
}

TEST_CASE("fuzz: every stored input loads or is rejected with tandem::Error") {
    // as the harnesses call them; anything else (a crash, another exception) fails the test
    int inputs = 0;
    for (const fs::directory_entry& e : fs::recursive_directory_iterator(k_regressions)) {
        if (!e.is_regular_file()) continue;
        const std::string path = e.path().string(), ext = e.path().extension().string();
        INFO(path);
        ++inputs;
        if (ext == ".xml") {
            error_of([&] { build_render_scene(load_scene(path)); });
        } else if (ext == ".json") {
            error_of([&] { load_optimize_config(path); });
        } else if (ext == ".obj" || ext == ".ply") {
            error_of([&] { load_mesh(path); });
        } else {
            error_of([&] {
                int w = 0, h = 0;
                const std::vector<float> rgb = read_image(path, &w, &h);
                RenderScene scene;
                build_envmap(rgb, w, h, glm::mat4(1.0f), scene);
            });
        }
    }
    CHECK(inputs > 0);
}
