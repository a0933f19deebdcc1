// Fault injection hooks (runtime/fault.h), each read from the environment where it is passed.
#include "runtime/fault.h"

#include <atomic>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <map>
#include <mutex>
#include <string>
#include <unistd.h>

namespace tandem::fault {

namespace {

/// Whether the count `n` of an event is the one the decimal number `target` names.
bool is_target_count(const char* target, unsigned long n) {
    if (target == nullptr || *target == '\0') return false;
    char* end = nullptr;
    const unsigned long want = std::strtoul(target, &end, 10);
    return *end == '\0' && want == n;
}

/// Whether the count `n` of an event is the one the variable `name` names.
bool is_target(const char* name, unsigned long n) {
    return is_target_count(std::getenv(name), n);
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

void kill_point(const char* where) {
    static std::mutex mutex;
    static std::map<std::string, unsigned long> passages;
    const char* target = std::getenv("TANDEM_KILL_AT");
    if (target == nullptr) return;
    const char* colon = std::strrchr(target, ':');
    if (colon == nullptr || std::string(target, colon) != where) return;
    unsigned long n = 0;
    {
        const std::lock_guard<std::mutex> lock(mutex);
        n = ++passages[where];
    }
    if (is_target_count(colon + 1, n)) ::kill(::getpid(), SIGKILL);
}

} // namespace tandem::fault
