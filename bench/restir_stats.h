// The error measures of `tandem bench restir` (bench/restir_bench.h): a reference gradient from
// independent chunks, and the relMSE, relative L2 error and bias checks of an estimator's
// gradients over seeds against it.
#pragma once

#include <vector>

#include "bench/restir_bench.h"

namespace tandem {

/// Elements grouped into blocks for the bias check: a texture's texels in squares of
/// `k_block` x `k_block` (all channels together), any other parameter element by element.
struct RestirBlocks {
    static constexpr int k_block = 16;
    std::vector<int> of; ///< the block of each element
    int count = 0;
    RestirBlocks() = default;
    /// For `elements` values; `width` x `height` texels of `channels` values each, or 0 x 0.
    RestirBlocks(std::size_t elements, int width, int height, int channels);
    /// Per-block sums of `g`.
    std::vector<double> sums(const std::vector<float>& g) const;
};

struct RestirReference {
    std::vector<double> mean;   ///< g*, the mean of the chunks
    std::vector<double> var;    ///< the variance of that mean, per element (0 with one chunk)
    double eps = 0;             ///< 1e-2 mean(g*^2)
    double norm2 = 0;           ///< ||g*||^2
    double floor = 0;           ///< mean var / (g*^2 + eps): the reference's own relMSE
    double rel_l2 = 0;          ///< sqrt(sum var) / ||g*||
    double sum = 0, sum_se = 0; ///< sum_j g*_j and its standard error (the chunks' spread)
    RestirBlocks blocks;
    std::vector<double> block_mean, block_se; ///< per block: the sum of g*, its standard error
};

/// g* and its noise from equal-sized independent chunks (each the gradient of its own seeds).
RestirReference make_reference(const std::vector<std::vector<float>>& chunks,
                               const RestirBlocks& blocks);

/// Fills the error fields of `e` from the gradients of its seeds (one vector per seed).
void measure_estimate(const std::vector<std::vector<float>>& grads, const RestirReference& ref,
                      RestirEstimate* e);

/// The median of `v` (0 if empty).
double median(std::vector<double> v);

} // namespace tandem
