// Fault injection for tests: makes the runtime fail where a real device would, so that the
// failure paths (one-line error, nothing written lost, the caller still usable) are exercised
// on any machine.
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

} // namespace tandem::fault
