// The parameter state: the single owner of what an optimization carries from one iteration to
// the next. theta, theta_prev, the valid ranges and learning rates, the fixed-point gradient
// accumulator, the optimizer's step count, and named buffers that their owners register (the
// optimizer's moments, the control variate's statistics, the ReSTIR reservoirs). Checkpoints save
// and restore all of it generically, without knowing what the named buffers hold.
#pragma once

#include <cstdint>
#include <cstring>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/io/sections.h"
#include "core/render/gradient_buffers.h"
#include "core/scene/params.h"
#include "runtime/error.h"

namespace tandem {

/// The name of a view's own copy of a parameter state's buffer `name` (its per-view state: the
/// control variate's statistics, the reservoirs, the parameters it was last rendered with):
/// `name` itself in a scene with one sensor (so that its checkpoints are as before), else `name`
/// + ".view" + the sensor's index.
inline std::string view_buffer(const std::string& name, unsigned sensor, unsigned sensors) {
    return sensors == 1 ? name : name + ".view" + std::to_string(sensor);
}

class ParamState {
public:
    /// theta = theta_prev = the registry's values, learning rates 0 (nothing optimized), ranges
    /// from the registry, gradients zero, no named buffers.
    ParamState(Context& ctx, const ParamRegistry& registry);
    ParamState(const ParamState&) = delete;
    ParamState& operator=(const ParamState&) = delete;

    Context& context() { return *m_ctx; }

    /// Elements of every flat buffer (at least 1: OpenCL buffers cannot be empty).
    std::size_t size() const { return m_theta.size(); }

    Buffer<float>& theta() { return m_theta; }           ///< theta_n, read by the passes
    Buffer<float>& theta_prev() { return m_theta_prev; } ///< theta_{n-1} (control variate)
    /// theta_prev <- theta (enqueued): call before a step changes theta, so that the next
    /// iteration's control variate compares with the state this one rendered.
    void remember_theta() { m_theta_prev.copy_from(m_theta); }
    Buffer<float>& learning_rates() { return m_lr; } ///< per element; 0: not optimized
    Buffer<float>& lower() { return m_lower; }       ///< per-element valid range
    Buffer<float>& upper() { return m_upper; }
    GradientBuffers& gradient() { return m_gradient; } ///< the adjoint pass's output
    /// The adjoint computes the gradients of `params` only (GradientBuffers::differentiate_only).
    void differentiate_only(const std::vector<const Parameter*>& params) {
        std::vector<std::pair<std::size_t, std::size_t>> ranges;
        for (const Parameter* p : params)
            ranges.emplace_back(p->offset, p->size);
        m_gradient.differentiate_only(ranges);
    }
    /// Steps taken by the state's optimizer (core/inverse/optimizer.h), saved with the state.
    unsigned steps() const { return m_steps; }
    void count_step() { ++m_steps; }

    /// Registers a named per-pixel (or any) buffer of `count` elements, all `init`; checkpoints
    /// save it. A buffer of `any_size` is restored at the size it was saved with (its owner
    /// resizes it: a move-assignment keeps the reference valid); any other must have it. Throws
    /// Error if the name is taken.
    template <class T>
    Buffer<T>& add_buffer(const std::string& name, std::size_t count, const T& init,
                          bool any_size = false) {
        auto holder =
            std::make_unique<Typed<T>>(Buffer<T>(*m_ctx, name, std::vector<T>(count, init)));
        holder->any_size = any_size;
        holder->context = m_ctx;
        holder->name = name;
        Buffer<T>& b = *holder->buffer;
        insert(name, std::move(holder));
        return b;
    }
    /// The named buffer `name` of element type T; throws Error if absent or of another type.
    template <class T> Buffer<T>& buffer(const std::string& name) {
        auto* named = dynamic_cast<Typed<T>*>(find(name));
        if (!named) throw Error("parameter state: '" + name + "' holds another element type");
        return *named->buffer;
    }
    bool has_buffer(const std::string& name) const { return m_named.count(name) != 0; }
    /// Forgets the named buffer `name` (its owner goes); nothing if there is none.
    void remove_buffer(const std::string& name) { m_named.erase(name); }
    /// The bytes of the named buffer `name` (blocks for the download), and their restore into it
    /// (of its size; throws Error otherwise): a view's state sent from the process that keeps it
    /// to the one that writes the checkpoint (core/inverse/ranks.h).
    std::string buffer_bytes(const std::string& name) { return find(name)->bytes(); }
    void set_buffer_bytes(const std::string& name, const std::string& bytes);

    /// Adds the state to a checkpoint's sections (core/io/sections.h): "state" (the step count
    /// and the buffers' names), then one section "state:NAME" per buffer (element size, count,
    /// bytes), so that each carries its own checksum. Blocks for the downloads.
    void save(SectionWriter& out) const;
    /// Restores what save() wrote, from verified sections. Checks every buffer before it changes
    /// anything: throws Error naming the file and section when a buffer is missing, extra, of
    /// another size or element type.
    void load(const SectionReader& in);

private:
    struct AnyBuffer {
        virtual ~AnyBuffer() = default;
        virtual std::size_t element_size() const = 0;
        virtual std::size_t count() const = 0;
        virtual std::string bytes() const = 0;
        /// `count` elements (the buffer's own count unless any_size)
        virtual void set_bytes(const char* data, std::size_t count) = 0;
        bool any_size = false;
    };
    /// A typed buffer, owned (a named buffer) or a view of a member (theta, theta_prev).
    template <class T> struct Typed final : AnyBuffer {
        explicit Typed(Buffer<T>& member) : buffer(&member) {}
        explicit Typed(Buffer<T>&& b)
            : owned(std::make_unique<Buffer<T>>(std::move(b))), buffer(owned.get()) {}
        std::unique_ptr<Buffer<T>> owned;
        Buffer<T>* buffer;
        std::size_t element_size() const override { return sizeof(T); }
        std::size_t count() const override { return buffer->size(); }
        std::string bytes() const override {
            const std::vector<T> v = buffer->download();
            return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
        }
        void set_bytes(const char* data, std::size_t n) override {
            std::vector<T> v(n);
            std::memcpy(v.data(), data, v.size() * sizeof(T));
            if (n == buffer->size())
                buffer->upload(v);
            else
                *buffer = Buffer<T>(*context, name, v);
        }
        Context* context = nullptr; ///< where a named buffer of any_size is made again
        std::string name;
    };
    void insert(const std::string& name, std::unique_ptr<AnyBuffer> b);
    AnyBuffer* find(const std::string& name);
    /// Every saved buffer, in a fixed order: the members, then the named buffers by name.
    std::vector<std::pair<std::string, AnyBuffer*>> saved() const;

    Context* m_ctx;
    Buffer<float> m_theta, m_theta_prev, m_lr, m_lower, m_upper;
    GradientBuffers m_gradient;
    unsigned m_steps = 0;
    std::map<std::string, std::unique_ptr<AnyBuffer>> m_named;
    std::vector<std::pair<std::string, std::unique_ptr<AnyBuffer>>> m_members;
};

} // namespace tandem
