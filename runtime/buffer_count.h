// A process-wide count of live device buffers (Buffer objects that hold an allocation) and their
// bytes, for `tandem bench soak` and tests: two relaxed atomics, updated on construction,
// destruction and assignment.
#pragma once

#include <atomic>
#include <cstddef>

namespace tandem {

namespace detail {
inline std::atomic<std::size_t> g_live_buffers{0};
inline std::atomic<std::size_t> g_live_buffer_bytes{0};

/// A member of Buffer: counted while it holds an allocation of `bytes`. A copy is counted as
/// another live buffer (it shares the allocation); a moved-from one is no longer counted.
class LiveBufferCount {
public:
    LiveBufferCount() = default;
    explicit LiveBufferCount(std::size_t bytes) { acquire(bytes); }
    LiveBufferCount(const LiveBufferCount& o) {
        if (o.m_live) acquire(o.m_bytes);
    }
    LiveBufferCount(LiveBufferCount&& o) noexcept : m_live(o.m_live), m_bytes(o.m_bytes) {
        o.m_live = false;
        o.m_bytes = 0;
    }
    LiveBufferCount& operator=(const LiveBufferCount& o) {
        if (this != &o) {
            release();
            if (o.m_live) acquire(o.m_bytes);
        }
        return *this;
    }
    LiveBufferCount& operator=(LiveBufferCount&& o) noexcept {
        if (this != &o) {
            release();
            m_live = o.m_live;
            m_bytes = o.m_bytes;
            o.m_live = false;
            o.m_bytes = 0;
        }
        return *this;
    }
    ~LiveBufferCount() { release(); }

private:
    void acquire(std::size_t bytes) {
        m_live = true;
        m_bytes = bytes;
        g_live_buffers.fetch_add(1, std::memory_order_relaxed);
        g_live_buffer_bytes.fetch_add(bytes, std::memory_order_relaxed);
    }
    void release() {
        if (!m_live) return;
        g_live_buffers.fetch_sub(1, std::memory_order_relaxed);
        g_live_buffer_bytes.fetch_sub(m_bytes, std::memory_order_relaxed);
        m_live = false;
        m_bytes = 0;
    }
    bool m_live = false;
    std::size_t m_bytes = 0;
};
} // namespace detail

/// Buffer objects alive in this process that hold a device allocation.
inline std::size_t live_buffers() { return detail::g_live_buffers.load(std::memory_order_relaxed); }
/// Their allocated bytes (at least one element each, as allocated).
inline std::size_t live_buffer_bytes() {
    return detail::g_live_buffer_bytes.load(std::memory_order_relaxed);
}

} // namespace tandem
