// Fault injection hooks (runtime/fault.h), armed from a Tuning (FaultHooks).
#include "runtime/fault.h"

#include <atomic>
#include <csignal>
#include <map>
#include <mutex>
#include <string>
#include <unistd.h>

namespace tandem::fault {

namespace {

std::atomic<unsigned long> g_fail_allocation{0};
std::atomic<unsigned long> g_fail_write{0};

/// The kill point and its passage, and the passages of every point so far.
struct KillState {
    std::mutex mutex;
    std::string point;
    unsigned long count = 0;
    std::map<std::string, unsigned long> passages;
};

KillState& kill_state() {
    static KillState state;
    return state;
}

} // namespace

void configure(const FaultHooks& hooks) {
    g_fail_allocation = hooks.fail_allocation;
    g_fail_write = hooks.fail_write;
    KillState& k = kill_state();
    const std::lock_guard<std::mutex> lock(k.mutex);
    k.point = hooks.kill_point;
    k.count = hooks.kill_count;
}

bool fail_this_allocation() {
    static std::atomic<unsigned long> count{0};
    const unsigned long n = ++count;
    return g_fail_allocation != 0 && n == g_fail_allocation;
}

bool fail_this_write() {
    static std::atomic<unsigned long> count{0};
    const unsigned long n = ++count;
    return g_fail_write != 0 && n == g_fail_write;
}

void kill_point(const char* where) {
    KillState& k = kill_state();
    bool kill = false;
    {
        const std::lock_guard<std::mutex> lock(k.mutex);
        if (k.point.empty() || k.point != where) return;
        kill = ++k.passages[where] == k.count;
    }
    if (kill) ::kill(::getpid(), SIGKILL);
}

} // namespace tandem::fault
