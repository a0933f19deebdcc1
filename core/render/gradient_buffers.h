// The adjoint pass's output: 64-bit fixed-point sums (kernels/shared/fixed_point.h), exact and
// bit-identical in any order, in units scaled by 2^s, and their float values after decoding, in
// the parameter layout.
#pragma once

#include <algorithm>
#include <optional>
#include <utility>
#include <vector>

#include "runtime/buffer.h"
#include "shared/fixed_point.h"

namespace tandem {

struct GradientBuffers {
    GradientBuffers() = default;
    /// Zeroed buffers for `count` parameter elements (at least one: OpenCL buffers cannot be
    /// empty).
    GradientBuffers(Context& ctx, std::size_t count)
        : fixed(ctx, "fixed-point gradients",
                std::vector<unsigned>(GRAD_WORDS * std::max<std::size_t>(1, count), 0u)),
          value(ctx, "gradient", std::vector<float>(std::max<std::size_t>(1, count), 0.0f)),
          exponent(ctx, "gradient scale exponent", std::vector<int>(1, 0)),
          active(ctx, "differentiated elements",
                 std::vector<unsigned>((std::max<std::size_t>(1, count) + 31) / 32, ~0u)),
          m_active((std::max<std::size_t>(1, count) + 31) / 32, ~0u), m_count(count) {}
    Buffer<unsigned> fixed; ///< GRAD_WORDS words per element; kept zero between passes
    Buffer<float> value;    ///< dloss/dtheta of the last backward()
    /// s of the last backward(): its contributions were scaled by 2^s (shared/fixed_point.h).
    /// Chosen on the device from sum |delta|; read it only to report it.
    Buffer<int> exponent;
    /// Scratch of backward(): the chunk sums of |delta| (sized on first use).
    Buffer<float> delta_sums;
    /// Tests: every backward() scales by 2^forced_exponent instead of choosing s from delta
    /// (0: the unscaled units of 2^-40).
    std::optional<int> forced_exponent;
    /// One bit per element (bit i % 32 of word i / 32): backward() computes the gradients of
    /// the elements whose bit is set and leaves the others 0. All are set at first.
    Buffer<unsigned> active;

    /// Differentiates only the elements [offset, offset + size) of the given ranges (the
    /// optimized parameters): the adjoint skips every add to the others, which on a GPU contend
    /// for the same words. The gradients of the elements kept are the same bits as with all of
    /// them.
    void differentiate_only(const std::vector<std::pair<std::size_t, std::size_t>>& ranges) {
        std::vector<unsigned> bits(active.size(), 0u);
        for (const auto& [offset, size] : ranges)
            for (std::size_t i = offset; i < offset + size && i < m_count; ++i)
                bits[i / 32] |= 1u << (i % 32);
        active.upload(bits);
        m_active = std::move(bits);
        m_selected = true;
    }
    /// Whether differentiate_only() chose the elements. Shape gradients (their boundary terms,
    /// core/render/boundary.h) are taken only for parameters chosen so: all elements, the
    /// default, leave the vertices of every mesh of the scene out.
    bool selected() const { return m_selected; }
    /// Whether element i's bit in `active` is set (the host's copy).
    bool differentiated(std::size_t i) const {
        return i / 32 < m_active.size() && ((m_active[i / 32] >> (i % 32)) & 1u) != 0u;
    }

private:
    std::vector<unsigned> m_active; ///< the bits of `active`
    std::size_t m_count = 0;
    bool m_selected = false;
};

} // namespace tandem
