// Fault injection for tests: makes the runtime fail where a real device would, or the process die
// where a kill would land, so that the failure paths (one-line error, nothing written lost, the
// caller still usable, a resumed run whole) are exercised on any machine, deterministically.
#pragma once

namespace tandem::fault {

/// True for the N-th device buffer allocation of the process (counted from 1) when the
/// environment variable TANDEM_FAIL_ALLOCATION=N is set: Buffer then fails as on
/// CL_MEM_OBJECT_ALLOCATION_FAILURE. Read at every allocation, so a test can set it mid-run.
bool fail_this_allocation();

/// True for the N-th whole-file write of the process (counted from 1; core/io: atomic files and
/// images) when TANDEM_FAIL_WRITE=N is set: the write then fails as on a full disk (ENOSPC)
/// after part of the file was written.
bool fail_this_write();

/// Kills the process with SIGKILL (as `kill -9` or the OOM killer would: no handler, no cleanup)
/// at the N-th passage (counted from 1) of the point `where` when TANDEM_KILL_AT=WHERE:N names
/// it; every point counts its own passages. The points:
///   write-middle    a whole-file write (core/io: atomic files, images, a record file's append)
///                   with part of it written: half of the temporary's bytes (an image: its
///                   header), half of an appended record
///   write-complete  a whole-file write (not an append) with its temporary complete and flushed,
///                   before the rename
///   iteration       `tandem optimize` at the start of an iteration (core/inverse/optimize.cpp)
void kill_point(const char* where);

} // namespace tandem::fault
