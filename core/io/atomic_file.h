// Whole-file writes that never leave a target half-written: write a temporary beside it, then
// rename over it (atomic on POSIX file systems).
#pragma once

#include <string>

namespace tandem {

/// Replaces `path` with `contents`, flushed to the disk (fsync) before the rename, so that a
/// crash or a power loss leaves the old file or the new one. Throws Error naming the file on
/// failure (a full disk, say); the old file, if any, is then left untouched and no temporary
/// remains.
void write_file_atomic(const std::string& path, const std::string& contents);

/// The temporary write_file_atomic() and write_image() write `path` through: ".NAME.tmpPID" in
/// the same folder, with `ext` appended (image formats are chosen by extension).
std::string temporary_for(const std::string& path, const std::string& ext = {});

/// Removes the temporaries of writes that a killed process left in `dir` (names as
/// temporary_for() makes them, of processes no longer running). Returns how many it removed.
int remove_stale_temporaries(const std::string& dir);

/// The whole file at `path`. Throws Error naming it when it cannot be read.
std::string read_file(const std::string& path);

} // namespace tandem
