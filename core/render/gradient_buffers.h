// The adjoint pass's output: 64-bit fixed-point sums (kernels/shared/fixed_point.h), exact and
// bit-identical in any order, and their float values after decoding, in the parameter layout.
#pragma once

#include <algorithm>
#include <vector>

#include "runtime/buffer.h"

namespace tandem {

struct GradientBuffers {
    GradientBuffers() = default;
    /// Zeroed buffers for `count` parameter elements (at least one: OpenCL buffers cannot be
    /// empty).
    GradientBuffers(Context& ctx, std::size_t count)
        : fixed(ctx, "fixed-point gradients",
                std::vector<unsigned>(2 * std::max<std::size_t>(1, count), 0u)),
          value(ctx, "gradient", std::vector<float>(std::max<std::size_t>(1, count), 0.0f)) {}
    Buffer<unsigned> fixed; ///< 2 words per element; kept zero between passes
    Buffer<float> value;    ///< dloss/dtheta of the last backward()
};

} // namespace tandem
