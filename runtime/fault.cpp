#include "runtime/fault.h"

#include <atomic>
#include <cstdlib>

namespace tandem::fault {

bool fail_this_allocation() {
    static std::atomic<unsigned long> count{0};
    const unsigned long n = ++count;
    const char* target = std::getenv("TANDEM_FAIL_ALLOCATION");
    if (target == nullptr || *target == '\0') return false;
    char* end = nullptr;
    const unsigned long want = std::strtoul(target, &end, 10);
    return *end == '\0' && want == n;
}

} // namespace tandem::fault
