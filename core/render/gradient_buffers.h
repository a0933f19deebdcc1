// The adjoint pass's output: 64-bit fixed-point sums (kernels/shared/fixed_point.h), exact and
// bit-identical in any order, in units scaled by 2^s, and their float values after decoding, in
// the parameter layout.
#pragma once

#include <algorithm>
#include <optional>
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
          exponent(ctx, "gradient scale exponent", std::vector<int>(1, 0)) {}
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
};

} // namespace tandem
