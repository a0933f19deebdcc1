// Atomic whole-file writes.
#include "core/io/atomic_file.h"

#include <cerrno>
#include <csignal>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <unistd.h>
#include <utility>

#include "runtime/error.h"
#include "runtime/fault.h"

namespace tandem {

namespace fs = std::filesystem;

void check_output_file(const std::string& path) {
    const fs::path target(path);
    if (target.filename().empty()) throw Error(path + ": not a file name");
    const fs::path folder = target.parent_path().empty() ? fs::path(".") : target.parent_path();
    std::error_code ec;
    if (!fs::is_directory(folder, ec))
        throw Error(path + (fs::exists(folder, ec)
                                ? ": " + folder.string() + " is not a folder"
                                : ": the folder " + folder.string() + " does not exist"));
    if (fs::is_directory(target, ec)) throw Error(path + ": is a folder, not a file name");
}

std::string temporary_for(const std::string& path, const std::string& ext) {
    const fs::path target(path);
    const std::string name = ext.empty() ? target.filename().string() : target.stem().string();
    return (target.parent_path() / ("." + name + ".tmp" + std::to_string(::getpid()) + ext))
        .string();
}

int remove_stale_temporaries(const std::string& dir) {
    static const std::regex pattern(R"(\..+\.tmp([0-9]+)(\.[A-Za-z0-9]+)?)");
    int removed = 0;
    std::error_code ec;
    for (const fs::directory_entry& e : fs::directory_iterator(dir, ec)) {
        std::smatch m;
        const std::string name = e.path().filename().string();
        if (!e.is_regular_file(ec) || !std::regex_match(name, m, pattern)) continue;
        const long pid = std::stol(m[1].str());
        if (pid == ::getpid() || (::kill(pid_t(pid), 0) == 0 || errno == EPERM)) continue; // alive
        removed += fs::remove(e.path(), ec) ? 1 : 0;
    }
    return removed;
}

namespace {

/// Writes `n` bytes from `data` to `fd`, however many calls that takes. Returns 0, or the errno of
/// the failure.
int write_all(int fd, const char* data, std::size_t n) {
    for (std::size_t done = 0; done < n;) {
        const ssize_t w = ::write(fd, data + done, n - done);
        if (w < 0 && errno == EINTR) continue;
        if (w < 0) return errno;
        done += std::size_t(w);
    }
    return 0;
}

} // namespace

void write_file_atomic(const std::string& path, const std::string& contents,
                       const std::string& previous) {
    const fs::path target(path);
    const fs::path tmp = temporary_for(path);
    auto fail = [&](const std::string& why) {
        std::error_code ec;
        fs::remove(tmp, ec);
        throw Error(path + ": write failed (" + why + ")");
    };
    // POSIX I/O rather than a stream: the data must reach the disk (fsync) before the rename.
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) throw Error(path + ": cannot write (" + std::strerror(errno) + ")");
    const bool inject = fault::fail_this_write(); // tests: a disk that fills up mid-file
    const std::size_t half = contents.size() / 2;
    int err = write_all(fd, contents.data(), half);
    if (err == 0) fault::kill_point("write-middle"); // tests: a kill with half of it written
    if (err == 0 && inject) {
        ::close(fd);
        fail(std::string(std::strerror(ENOSPC)) + "; injected: TANDEM_FAIL_WRITE");
    }
    if (err == 0) err = write_all(fd, contents.data() + half, contents.size() - half);
    if (err != 0) {
        ::close(fd);
        fail(std::strerror(err));
    }
    if (::fsync(fd) != 0 || ::close(fd) != 0) fail(std::strerror(errno));
    fault::kill_point("write-complete"); // tests: a kill between the flush and the rename
    std::error_code ec;
    // The file it replaces becomes `previous`. Already is, when a kill landed between the two
    // renames below last time (both names are then links to it): a rename of one link of a file
    // over another does nothing, so skip it.
    const bool keep = !previous.empty() && fs::exists(target, ec) &&
                      !(fs::exists(previous, ec) && fs::equivalent(target, previous, ec));
    ec.clear();
    if (keep) {
        const fs::path kept = temporary_for(previous);
        fs::remove(kept, ec); // none, unless this process id's write was killed here before
        ec.clear();
        if (::link(target.c_str(), kept.c_str()) != 0) fs::copy_file(target, kept, ec);
        fault::kill_point("previous-linked"); // tests: a kill with the previous one's link made
        if (!ec) fs::rename(kept, previous, ec);
        if (ec) {
            const std::string why = ec.message();
            fs::remove(kept, ec);
            fs::remove(tmp, ec);
            throw Error(previous + ": cannot keep the previous " + target.filename().string() +
                        " (" + why + ")");
        }
        fault::kill_point("previous-kept"); // tests: a kill between the two renames
    }
    fs::rename(tmp, target, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw Error(path + ": cannot replace (" + ec.message() + ")");
    }
}

RecordFile::RecordFile(std::string path, const std::string& initial) : m_path(std::move(path)) {
    write_file_atomic(m_path, initial);
    m_fd = ::open(m_path.c_str(), O_WRONLY | O_APPEND | O_CLOEXEC);
    if (m_fd < 0) throw Error(m_path + ": cannot write (" + std::strerror(errno) + ")");
    m_size = static_cast<long long>(initial.size());
}

RecordFile::~RecordFile() {
    if (m_fd >= 0) ::close(m_fd);
}

void RecordFile::append(const std::string& record) {
    const bool inject = fault::fail_this_write(); // tests: a disk that fills up mid-record
    const std::size_t half = record.size() / 2;
    int err = write_all(m_fd, record.data(), half);
    if (err == 0) fault::kill_point("write-middle"); // tests: a kill with half of it written
    if (err == 0 && !inject) err = write_all(m_fd, record.data() + half, record.size() - half);
    if (err == 0 && !inject) {
        m_size += static_cast<long long>(record.size());
        return;
    }
    // Back to the last whole record; if even that fails, the message says so.
    const std::string why =
        err != 0 ? std::strerror(err)
                 : std::string(std::strerror(ENOSPC)) + "; injected: TANDEM_FAIL_WRITE";
    if (::ftruncate(m_fd, off_t(m_size)) != 0)
        throw Error(m_path + ": write failed (" + why +
                    "), and cutting back the partial record failed too (" + std::strerror(errno) +
                    ")");
    throw Error(m_path + ": write failed (" + why + ")");
}

std::string read_file(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(path + ": cannot open (" + std::strerror(errno) + ")");
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

} // namespace tandem
