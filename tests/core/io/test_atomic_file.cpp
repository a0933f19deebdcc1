// remove_stale_temporaries (core/io/atomic_file.h): the temporaries of writes whose process is
// gone are removed, those of a live process and every other file are kept.
#include <doctest/doctest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

#include "core/io/atomic_file.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

/// The id of a process that has exited and been reaped: no process runs under it (until the
/// system hands it out again, which takes a full cycle of process ids).
pid_t dead_pid() {
    const pid_t child = fork();
    REQUIRE(child >= 0);
    if (child == 0) _exit(0);
    int status = 0;
    REQUIRE(waitpid(child, &status, 0) == child);
    return child;
}

std::set<std::string> names(const fs::path& dir) {
    std::set<std::string> out;
    for (const fs::directory_entry& e : fs::directory_iterator(dir))
        out.insert(e.path().filename().string());
    return out;
}

} // namespace

TEST_CASE("remove_stale_temporaries removes a dead process's temporaries and keeps the rest") {
    const fs::path dir =
        fs::temp_directory_path() / ("tandem-stale-test-" + std::to_string(getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    const std::string dead = std::to_string(dead_pid());
    const std::string own = std::to_string(getpid());
    const std::string parent = std::to_string(getppid()); // alive while the test runs
    // what temporary_for() names, for this process and for a dead one
    CHECK(temporary_for((dir / "checkpoint.bin").string()) ==
          (dir / (".checkpoint.bin.tmp" + own)).string());
    CHECK(temporary_for((dir / "iter_0003.exr").string(), ".exr") ==
          (dir / (".iter_0003.tmp" + own + ".exr")).string());
    const std::set<std::string> stale = {
        ".checkpoint.bin.tmp" + dead, ".iter_0003.tmp" + dead + ".exr", ".params.json.tmp" + dead};
    const std::set<std::string> kept = {
        ".checkpoint.bin.tmp" + own,               // this process's write in progress
        ".metrics.csv.tmp" + parent,               // a live process's
        "checkpoint.bin.tmp" + dead,               // not hidden: not a temporary of ours
        ".checkpoint.bin.tmp",                     // no process id
        ".checkpoint.bin.tmp" + dead + ".exr.bak", // more after the extension
        "checkpoint.bin",
    };
    for (const std::set<std::string>* set : {&stale, &kept})
        for (const std::string& name : *set)
            std::ofstream(dir / name) << "x";
    fs::create_directory(dir / (".folder.tmp" + dead)); // not a file: kept
    CHECK(remove_stale_temporaries(dir.string()) == int(stale.size()));
    std::set<std::string> expected = kept;
    expected.insert(".folder.tmp" + dead);
    CHECK(names(dir) == expected);
    CHECK(remove_stale_temporaries(dir.string()) == 0); // nothing more to remove
    fs::remove_all(dir);
}
