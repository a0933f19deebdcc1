// Fault injection for tests: makes the runtime fail where a real device would, or the process die
// where a kill would land, so that the failure paths (one-line error, nothing written lost, the
// caller still usable, a resumed run whole) are exercised on any machine, deterministically.
#pragma once

#include "runtime/tuning.h"

namespace tandem::fault {

/// Arms the hooks as `hooks` says (Tuning::faults), for the rest of the process or the next call:
/// every Context does so with its Tuning, and the CLI at its start. The counts of events go on
/// from where they were: they count from the process's start.
void configure(const FaultHooks& hooks);

/// True for the N-th device buffer allocation of the process (counted from 1) when the hooks are
/// armed with fail_allocation = N (TANDEM_FAIL_ALLOCATION=N): Buffer then fails as on
/// CL_MEM_OBJECT_ALLOCATION_FAILURE.
bool fail_this_allocation();

/// True for the N-th whole-file write of the process (counted from 1; core/io: atomic files and
/// images) when armed with fail_write = N (TANDEM_FAIL_WRITE=N): the write then fails as on a
/// full disk (ENOSPC) after part of the file was written.
bool fail_this_write();

/// Kills the process with SIGKILL (as `kill -9` or the OOM killer would: no handler, no cleanup)
/// at the N-th passage (counted from 1) of the point `where` when the hooks name it
/// (TANDEM_KILL_AT=WHERE:N); every point counts its own passages. The points:
///   write-middle    a whole-file write (core/io: atomic files, images, a record file's append)
///                   with part of it written: half of the temporary's bytes (an image: its
///                   header), half of an appended record
///   write-complete  a whole-file write (not an append) with its temporary complete and flushed,
///                   before the rename
///   previous-linked a write that keeps the file it replaces (checkpoint.prev.bin): with that
///                   file's link (a temporary) made, before it is renamed into place
///   previous-kept   the same write between the two renames: the previous file in place, the
///                   new one not yet
///   iteration       `tandem optimize` at the start of an iteration (core/inverse/optimize.cpp)
void kill_point(const char* where);

} // namespace tandem::fault
