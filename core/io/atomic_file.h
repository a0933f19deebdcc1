// Whole-file writes that never leave a target half-written: write a temporary beside it, then
// rename over it (atomic on POSIX file systems).
#pragma once

#include <string>

namespace tandem {

/// Replaces `path` with `contents`. Throws Error naming the file on failure; the old file, if
/// any, is then left untouched.
void write_file_atomic(const std::string& path, const std::string& contents);

/// The whole file at `path`. Throws Error naming it when it cannot be read.
std::string read_file(const std::string& path);

} // namespace tandem
