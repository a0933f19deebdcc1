#include "runtime/fault.h"

#include <atomic>
#include <cstdlib>

namespace tandem::fault {

namespace {

/// Whether the count `n` of an event is the one the variable `name` names.
bool is_target(const char* name, unsigned long n) {
    const char* target = std::getenv(name);
    if (target == nullptr || *target == '\0') return false;
    char* end = nullptr;
    const unsigned long want = std::strtoul(target, &end, 10);
    return *end == '\0' && want == n;
}

} // namespace

bool fail_this_allocation() {
    static std::atomic<unsigned long> count{0};
    return is_target("TANDEM_FAIL_ALLOCATION", ++count);
}

bool fail_this_write() {
    static std::atomic<unsigned long> count{0};
    return is_target("TANDEM_FAIL_WRITE", ++count);
}

} // namespace tandem::fault
