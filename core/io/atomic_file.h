// Whole-file writes that never leave a target half-written: write a temporary beside it, then
// rename over it (atomic on POSIX file systems).
#pragma once

#include <string>

namespace tandem {

/// Replaces `path` with `contents`, flushed to the disk (fsync) before the rename, so that a
/// crash or a power loss leaves the old file or the new one. Throws Error naming the file on
/// failure (a full disk, say); the old file, if any, is then left untouched and no temporary
/// remains. With `previous`, the file it replaces, if any, becomes `previous` (replacing it) just
/// before: hard-linked (copied where the file system has no hard links) to a temporary renamed
/// over `previous`, so that `path` exists at every moment.
void write_file_atomic(const std::string& path, const std::string& contents,
                       const std::string& previous = {});

/// A file that grows by whole records, as a log does: created (or replaced) atomically with
/// `initial`, then appended to, one record at a time, at a cost independent of its length (a
/// per-iteration rewrite made a 10^4-iteration `tandem optimize` three times slower by its end).
/// A failed append (a full disk) cuts the file back to its last whole record before throwing
/// Error naming it, so a reader never sees a partial record. Appends are not flushed to the disk
/// one by one: a caller that needs them after a crash keeps its own durable copy (tandem
/// optimize: the checkpoint's rows, from which --resume writes metrics.csv again).
class RecordFile {
public:
    RecordFile(std::string path, const std::string& initial);
    ~RecordFile();
    RecordFile(const RecordFile&) = delete;
    RecordFile& operator=(const RecordFile&) = delete;

    void append(const std::string& record);

private:
    std::string m_path;
    int m_fd = -1;
    long long m_size = 0; ///< bytes of whole records
};

/// Checks, before any work, that a file can be written at `path`: a file name whose folder
/// exists and that is not itself a folder. Throws Error naming `path` otherwise.
void check_output_file(const std::string& path);

/// The temporary write_file_atomic() and write_image() write `path` through: ".NAME.tmpPID" in
/// the same folder, with `ext` appended (image formats are chosen by extension).
std::string temporary_for(const std::string& path, const std::string& ext = {});

/// Removes the temporaries of writes that a killed process left in `dir` (names as
/// temporary_for() makes them, of processes no longer running). Returns how many it removed.
int remove_stale_temporaries(const std::string& dir);

/// The whole file at `path`. Throws Error naming it when it cannot be read.
std::string read_file(const std::string& path);

} // namespace tandem
