// One writer per output folder.
#include "core/io/folder_lock.h"

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include "runtime/error.h"

namespace tandem {

FolderLock::FolderLock(const std::string& folder, const std::string& what) {
    const std::string path = (std::filesystem::path(folder) / k_file).string();
    // O_NOFOLLOW: the id is written into the lock file itself, never through a link elsewhere
    m_fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (m_fd < 0 && errno == EACCES) // another user's lock file: it locks read-only too
        m_fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    if (m_fd < 0)
        throw Error(path + (errno == ELOOP ? std::string(": a link, not a lock file")
                                           : ": cannot create the lock file (" +
                                                 std::string(std::strerror(errno)) + ")"));
    struct stat st {};
    if (::fstat(m_fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        ::close(m_fd);
        throw Error(path + ": not a regular file, so not a lock file");
    }
    // flock, not fcntl: its lock belongs to this open file, so a second FolderLock of the same
    // process conflicts too, and closing another descriptor of the file does not drop it. (On
    // NFS, Linux emulates flock with whole-file POSIX locks: processes still exclude each other,
    // locks of one process do not.)
    int rc;
    do
        rc = ::flock(m_fd, LOCK_EX | LOCK_NB);
    while (rc != 0 && errno == EINTR);
    if (rc != 0) {
        const int err = errno;
        std::string holder;
        if (err == EWOULDBLOCK) { // the holder wrote its id once it had the lock
            char buf[32] = {};
            const ssize_t n = ::pread(m_fd, buf, sizeof(buf) - 1, 0);
            for (ssize_t i = 0; i < n && buf[i] >= '0' && buf[i] <= '9'; ++i)
                holder += buf[i];
        }
        ::close(m_fd);
        if (err != EWOULDBLOCK)
            throw Error(path + ": cannot lock (" + std::string(std::strerror(err)) + ")");
        throw Error(folder + ": in use by another " + what + " (" +
                    (holder.empty() ? std::string("a process that has not written its id")
                                    : "process " + holder) +
                    " holds " + k_file + "); wait for it to finish or write elsewhere (--out)");
    }
    const std::string id = std::to_string(::getpid()) + "\n";
    // The id is for a second writer's message; the lock holds without it (a full disk).
    const bool recorded =
        ::ftruncate(m_fd, 0) == 0 && ::pwrite(m_fd, id.data(), id.size(), 0) == ssize_t(id.size());
    (void)recorded;
}

FolderLock::~FolderLock() {
    if (m_fd < 0) return;
    // The file stays (removing it would let a process that opened it just before lock a file no
    // longer in the folder while a third creates and locks a new one); its id goes, so that a
    // finished run's folder holds the same bytes whichever process wrote it.
    const bool cleared = ::ftruncate(m_fd, 0) == 0;
    (void)cleared;
    ::close(m_fd); // releases the lock
}

} // namespace tandem
