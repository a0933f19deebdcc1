// Integrity of what `tandem optimize` keeps: content digests (core/io/digest.h), checksummed
// sections (core/io/sections.h), the previous file kept by an atomic write (core/io/atomic_file.h)
// and the one-writer folder lock (core/io/folder_lock.h).
#include <doctest/doctest.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

#include "core/io/atomic_file.h"
#include "core/io/digest.h"
#include "core/io/folder_lock.h"
#include "core/io/sections.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

fs::path fresh_dir(const std::string& name) {
    const fs::path dir =
        fs::temp_directory_path() / ("tandem-" + name + "-" + std::to_string(getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void write(const fs::path& p, const std::string& bytes) {
    std::ofstream(p, std::ios::binary) << bytes;
}

/// The message of the Error a FolderLock on `dir` throws; "" if it locks.
std::string lock_refusal(const fs::path& dir) {
    try {
        FolderLock lock(dir.string(), "tandem optimize");
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

constexpr char k_magic[8] = {'T', 'E', 'S', 'T', 'S', 'E', 'C', '1'};

/// Three sections, one of them empty, one larger than a few blocks of anything.
std::string three_sections() {
    SectionWriter w;
    w.add("alpha", "first payload");
    w.add("empty", "");
    std::string big;
    for (int i = 0; i < 3000; ++i)
        big += char(i * 7 + 1);
    w.add("state:theta", big);
    return w.bytes(k_magic);
}

/// True when `data` (a damaged copy of three_sections()) is refused as damaged.
bool refused(const std::string& data) {
    try {
        SectionReader r("f.bin", data);
    } catch (const DamagedFile&) {
        return true;
    }
    return false;
}

} // namespace

TEST_CASE("digest is libxxhash's XXH3-64, of bytes and of whole files read in blocks") {
    // the reference value of XXH3_64bits("", 0) (xxHash's own test vectors, seed 0)
    CHECK(digest("", 0) == 0x2D06800538D394C2ull);
    CHECK(digest_hex(0x2D06800538D394C2ull) == "2d06800538d394c2");
    const fs::path dir = fresh_dir("digest");
    std::string bytes(3 * (1 << 20) + 12345, '\0'); // more than the 1 MiB read blocks
    for (std::size_t i = 0; i < bytes.size(); ++i)
        bytes[i] = char((i * 2654435761u) >> 13);
    write(dir / "f", bytes);
    CHECK(digest_file((dir / "f").string()) == digest(bytes));
    bytes[bytes.size() / 2] ^= 0x40;
    CHECK(digest_file((dir / "f").string()) != digest(bytes));
    CHECK_THROWS_WITH_AS(digest_file((dir / "missing").string()), doctest::Contains("missing"),
                         Error);
    fs::remove_all(dir);
}

TEST_CASE("sections read back as written, by name") {
    const std::string data = three_sections();
    const SectionReader r("f.bin", data);
    CHECK(r.names() == std::vector<std::string>{"alpha", "empty", "state:theta"});
    CHECK(r.payload("alpha") == "first payload");
    CHECK(r.payload("empty").empty());
    CHECK(r.payload("state:theta").size() == 3000);
    CHECK_THROWS_WITH_AS(r.payload("beta"), doctest::Contains("f.bin: no section 'beta'"), Error);
    SectionWriter w;
    w.add("a", "");
    CHECK_THROWS_AS(w.add("a", ""), Error);
    CHECK_THROWS_AS(w.add("index", ""), Error);
}

TEST_CASE("every flipped bit, truncation and zeroed block of a sectioned file is found") {
    const std::string good = three_sections();
    REQUIRE_FALSE(refused(good));
    int missed = 0;
    for (std::size_t at = 8; at < good.size(); ++at) // past the magic, which the caller checks
        for (int bit = 0; bit < 8; ++bit) {
            std::string d = good;
            d[at] = char(d[at] ^ (1 << bit));
            missed += refused(d) ? 0 : 1;
        }
    CHECK(missed == 0);
    for (std::size_t size = 0; size < good.size(); ++size)
        missed += refused(good.substr(0, size)) ? 0 : 1;
    CHECK(missed == 0);
    for (std::size_t at = 8; at + 16 <= good.size(); at += 5) {
        std::string d = good;
        d.replace(at, 16, 16, '\0');
        if (d != good) missed += refused(d) ? 0 : 1;
    }
    CHECK(missed == 0);
    CHECK(refused(good + "x")); // bytes after the last section
}

TEST_CASE("a damaged section is named, from the index") {
    const std::string good = three_sections();
    std::string d = good;
    d[d.size() - 100] ^= 0x40; // inside state:theta's payload
    CHECK_THROWS_WITH_AS(SectionReader("f.bin", d),
                         "f.bin: section 3 of 3 ('state:theta') is damaged (checksum mismatch)",
                         DamagedFile);
    const std::size_t alpha = good.find("first payload");
    d = good;
    d[alpha] ^= 0x01;
    CHECK_THROWS_WITH_AS(SectionReader("f.bin", d),
                         "f.bin: section 1 of 3 ('alpha') is damaged (checksum mismatch)",
                         DamagedFile);
    const std::size_t theta_starts = good.rfind("state:theta") - 4;
    CHECK_THROWS_WITH_AS(SectionReader("f.bin", good.substr(0, theta_starts)),
                         "f.bin: truncated after section 2 of 3 (1 more expected)", DamagedFile);
    CHECK_THROWS_WITH_AS(SectionReader("f.bin", good.substr(0, 8)),
                         "f.bin: no sections (truncated)", DamagedFile);
}

TEST_CASE("write_file_atomic keeps the file it replaces as the previous one when asked") {
    const fs::path dir = fresh_dir("previous");
    const std::string path = (dir / "checkpoint.bin").string();
    const std::string prev = (dir / "checkpoint.prev.bin").string();
    write_file_atomic(path, "one", prev);
    CHECK(read_file(path) == "one");
    CHECK_FALSE(fs::exists(prev)); // nothing to keep yet
    write_file_atomic(path, "two", prev);
    CHECK(read_file(path) == "two");
    CHECK(read_file(prev) == "one");
    write_file_atomic(path, "three", prev);
    CHECK(read_file(prev) == "two");
    write_file_atomic(path, "four"); // without: the previous one stays as it was
    CHECK(read_file(prev) == "two");
    // a kill between the two renames leaves both names links to one file: the next write keeps
    // it as the previous one, and leaves no temporary (a rename of a link over another does not)
    fs::remove(prev);
    fs::create_hard_link(path, prev);
    write_file_atomic(path, "five", prev);
    CHECK(read_file(path) == "five");
    CHECK(read_file(prev) == "four");
    std::size_t files = 0;
    for (const auto& e : fs::directory_iterator(dir))
        files += e.is_regular_file() ? 1 : 0;
    CHECK(files == 2); // no temporaries left
    fs::remove_all(dir);
}

TEST_CASE("FolderLock: one holder at a time, named to the next, released when its holder dies") {
    const fs::path dir = fresh_dir("lock");
    {
        FolderLock first(dir.string(), "tandem optimize");
        // a second lock of the same process is refused too (flock: per open file)
        CHECK(lock_refusal(dir) == dir.string() + ": in use by another tandem optimize (process " +
                                       std::to_string(getpid()) +
                                       " holds .tandem.lock); wait for it to finish or write "
                                       "elsewhere (--out)");
    }
    CHECK(lock_refusal(dir).empty());                    // released with its holder
    CHECK(fs::file_size(dir / FolderLock::k_file) == 0); // and its id gone

    // a holder killed with SIGKILL leaves nothing that blocks
    int ready[2];
    REQUIRE(pipe(ready) == 0);
    const pid_t child = fork();
    REQUIRE(child >= 0);
    if (child == 0) {
        try {
            FolderLock held(dir.string(), "tandem optimize");
            const char c = 1;
            if (::write(ready[1], &c, 1) != 1) _exit(2);
            pause();
        } catch (...) {
            _exit(3);
        }
        _exit(0);
    }
    char c = 0;
    REQUIRE(::read(ready[0], &c, 1) == 1);
    CHECK(lock_refusal(dir).find("(process " + std::to_string(child) + " holds") !=
          std::string::npos);
    kill(child, SIGKILL);
    int status = 0;
    REQUIRE(waitpid(child, &status, 0) == child);
    CHECK(lock_refusal(dir).empty());
    close(ready[0]);
    close(ready[1]);
    fs::remove_all(dir);
}

TEST_CASE("FolderLock refuses a lock file that is a link, and leaves what it points to alone") {
    const fs::path dir = fresh_dir("lock-link");
    write(dir / "precious", "keep me");
    fs::create_symlink(dir / "precious", dir / FolderLock::k_file);
    CHECK(lock_refusal(dir) == (dir / FolderLock::k_file).string() + ": a link, not a lock file");
    CHECK(read_file((dir / "precious").string()) == "keep me");
    fs::remove_all(dir);
}
