// One writer per output folder: an exclusive lock (flock) on a lock file in it, held for the
// lifetime of the object. The kernel releases it when its holder exits, however it exits
// (SIGKILL included), so a lock never outlives its process and a stale one cannot block.
#pragma once

#include <string>

namespace tandem {

class FolderLock {
public:
    /// The name of the lock file in the folder.
    static constexpr const char* k_file = ".tandem.lock";

    /// Locks `folder` (which exists) without waiting, and records this process's id in the lock
    /// file. Throws Error "FOLDER: in use by another tandem run (process PID); ..." when another
    /// process (or another FolderLock of this one) holds it, and Error naming the file when it
    /// cannot be created. `what`: the command, for the message ("tandem optimize").
    FolderLock(const std::string& folder, const std::string& what);
    ~FolderLock();
    FolderLock(const FolderLock&) = delete;
    FolderLock& operator=(const FolderLock&) = delete;

private:
    int m_fd = -1;
};

} // namespace tandem
