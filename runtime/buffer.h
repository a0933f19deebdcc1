// Typed RAII device buffers. Transfers are enqueued under a stage name, so their time is reported.
#pragma once

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "runtime/buffer_count.h"
#include "runtime/context.h"
#include "runtime/error.h"
#include "runtime/fault.h"

namespace tandem {

/// `v`, or one default element when it is empty: OpenCL buffers cannot be empty, and the kernels
/// never read that element.
template <class T> std::vector<T> at_least_one(std::vector<T> v) {
    if (v.empty()) v.resize(1);
    return v;
}

template <class T> class Buffer {
public:
    Buffer() = default;
    /// Allocates `count` elements. Throws Error naming `name` and the size if the device refuses.
    Buffer(Context& ctx, std::string name, std::size_t count,
           cl_mem_flags flags = CL_MEM_READ_WRITE)
        : m_ctx(&ctx), m_name(std::move(name)), m_count(count) {
        const std::size_t bytes = std::max<std::size_t>(1, count) * sizeof(T);
        if (bytes > ctx.device().max_alloc_bytes)
            throw DeviceError(out_of_memory_message(bytes) +
                              " (larger than CL_DEVICE_MAX_MEM_ALLOC_SIZE)");
        if (fault::fail_this_allocation())
            throw DeviceError(out_of_memory_message(bytes) + ": " +
                              cl_error_name(CL_MEM_OBJECT_ALLOCATION_FAILURE) +
                              " (injected: TANDEM_FAIL_ALLOCATION)");
        try {
            m_buffer = cl::Buffer(ctx.cl_context(), flags, bytes);
        } catch (const cl::Error& e) {
            throw DeviceError(out_of_memory_message(bytes) + ": " + cl_error_name(e.err()));
        }
        m_live = detail::LiveBufferCount(bytes);
    }
    /// Allocates data.size() elements and uploads `data` (stage "upload <name>").
    Buffer(Context& ctx, std::string name, const std::vector<T>& data,
           cl_mem_flags flags = CL_MEM_READ_WRITE)
        : Buffer(ctx, std::move(name), data.size(), flags) {
        upload(data);
    }

    std::size_t size() const { return m_count; }
    std::size_t bytes() const { return m_count * sizeof(T); }
    const cl::Buffer& cl() const { return m_buffer; }
    const std::string& name() const { return m_name; }

    /// Blocking write of data[0..size()) (stage "upload <name>").
    void upload(const std::vector<T>& data) { upload(data.data(), data.size()); }
    /// Blocking write of `count` elements at `data`, which must be size() (stage "upload <name>").
    void upload(const T* data, std::size_t count) {
        if (count != m_count)
            throw Error("upload to '" + m_name + "': " + std::to_string(count) +
                        " elements for a buffer of " + std::to_string(m_count));
        if (m_count == 0) return;
        cl::Event event;
        enqueue("upload", [&] {
            m_ctx->queue().enqueueWriteBuffer(m_buffer, CL_TRUE, 0, bytes(), data, nullptr,
                                              timed(event));
        });
        record("upload", event);
    }
    /// Blocking write of `count` elements at `data` into elements [offset, offset + count)
    /// (stage "upload <name>").
    void write(std::size_t offset, const T* data, std::size_t count) {
        if (offset + count > m_count)
            throw Error("write to '" + m_name + "': elements [" + std::to_string(offset) + ", " +
                        std::to_string(offset + count) + ") of " + std::to_string(m_count));
        if (count == 0) return;
        cl::Event event;
        enqueue("upload", [&] {
            m_ctx->queue().enqueueWriteBuffer(m_buffer, CL_TRUE, offset * sizeof(T),
                                              count * sizeof(T), data, nullptr, timed(event));
        });
        record("upload", event);
    }
    /// Sets every element to `value` on the device (stage "fill <name>"). clEnqueueFillBuffer
    /// takes patterns of 1, 2, 4, ..., 128 bytes; an element of another size is filled as bytes
    /// when all of its bytes are equal (a zero state, say), and uploaded otherwise.
    void fill(const T& value) {
        if (m_count == 0) return;
        constexpr std::size_t size = sizeof(T);
        constexpr bool pattern = size <= 128 && (size & (size - 1)) == 0;
        unsigned char byte[size];
        std::memcpy(byte, &value, size);
        const bool uniform =
            std::all_of(byte, byte + size, [&](unsigned char b) { return b == byte[0]; });
        if (!pattern && !uniform) {
            upload(std::vector<T>(m_count, value));
            return;
        }
        cl::Event event;
        enqueue("fill", [&] {
            if (pattern)
                m_ctx->queue().enqueueFillBuffer(m_buffer, value, 0, bytes(), nullptr,
                                                 timed(event));
            else
                m_ctx->queue().enqueueFillBuffer(m_buffer, byte[0], 0, bytes(), nullptr,
                                                 timed(event));
        });
        record("fill", event);
    }
    /// Device-side copy of `other` (same size) into this buffer (stage "copy <name>").
    void copy_from(const Buffer& other) {
        if (other.m_count != m_count)
            throw Error("copy to '" + m_name + "': " + std::to_string(other.m_count) +
                        " elements for a buffer of " + std::to_string(m_count));
        if (m_count == 0) return;
        cl::Event event;
        enqueue("copy", [&] {
            m_ctx->queue().enqueueCopyBuffer(other.m_buffer, m_buffer, 0, 0, bytes(), nullptr,
                                             timed(event));
        });
        record("copy", event);
    }
    /// Enqueues a read of elements [offset, offset + count) into dst without waiting: dst is
    /// valid once the queue has finished (Context::finish). Stage "download <name>".
    void enqueue_read(std::size_t offset, std::size_t count, T* dst) const {
        if (offset + count > m_count)
            throw Error("read of '" + m_name + "': elements [" + std::to_string(offset) + ", " +
                        std::to_string(offset + count) + ") of " + std::to_string(m_count));
        if (count == 0) return;
        cl::Event event;
        enqueue("download", [&] {
            m_ctx->queue().enqueueReadBuffer(m_buffer, CL_FALSE, offset * sizeof(T),
                                             count * sizeof(T), dst, nullptr, timed(event));
        });
        record("download", event);
    }
    /// Blocking read of the whole buffer (stage "download <name>").
    std::vector<T> download() const {
        std::vector<T> data(m_count);
        if (m_count == 0) return data;
        cl::Event event;
        enqueue("download", [&] {
            m_ctx->queue().enqueueReadBuffer(m_buffer, CL_TRUE, 0, bytes(), data.data(), nullptr,
                                             timed(event));
        });
        record("download", event);
        return data;
    }

private:
    /// The event pointer of an enqueue: only with stage timing on (no event otherwise).
    cl::Event* timed(cl::Event& event) const { return m_ctx->stage_timing() ? &event : nullptr; }
    /// Records the stage "<what> <name>" with stage timing on.
    void record(const char* what, const cl::Event& event) const {
        if (m_ctx->stage_timing()) m_ctx->record(std::string(what) + " " + m_name, event);
    }
    std::string out_of_memory_message(std::size_t bytes) const {
        char size[32];
        if (bytes < (std::size_t{1} << 20))
            std::snprintf(size, sizeof size, "%zu bytes", bytes);
        else
            std::snprintf(size, sizeof size, "%.1f MiB", double(bytes) / (1024.0 * 1024.0));
        return "out of device memory: cannot allocate " + std::string(size) + " for '" + m_name +
               "' on '" + m_ctx->device().name + "'";
    }
    template <class F> void enqueue(const char* what, F&& f) const {
        try {
            f();
        } catch (const cl::Error& e) {
            const cl_int code = e.err();
            if (code == CL_MEM_OBJECT_ALLOCATION_FAILURE || code == CL_OUT_OF_RESOURCES)
                throw DeviceError(out_of_memory_message(bytes()) + ": " + cl_error_name(code));
            throw DeviceError(std::string(what) + " of '" + m_name + "' failed: " + cl_error_name(code));
        }
    }

    Context* m_ctx = nullptr;
    std::string m_name;
    std::size_t m_count = 0;
    cl::Buffer m_buffer;
    detail::LiveBufferCount m_live; ///< live_buffers(), live_buffer_bytes()
};

} // namespace tandem
