// The guide of the secondary boundary term's directions (kernels/path/boundary_guide.h;
// docs/method.md, "Glossy receivers"): where the receivers' BSDFs are narrow lobes, directions
// drawn uniformly or toward lights from an edge point rarely land in them. Camera paths learn
// where they do (kernels/boundary.cl: boundary_guide_train), and the guide, a density of
// directions for each part of the edges they found, sends a share of the samples there and picks
// those edges more often. The estimate evaluates the mixtures' densities exactly, so the guide
// changes its variance only, never its mean.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/render/device_scene.h"
#include "shared/boundary.h"

namespace tandem {

/// The guide's tables: its header (fraction 0: no guide), each edge's first slot (GUIDE_NO_SLOT:
/// none), each slot's CDF over dir_res^2 direction cells, and each edge's training weight.
struct SecondaryGuideTables {
    gpu::SecondaryGuide guide{};
    std::vector<unsigned> edge_slot;
    std::vector<float> cdf;
    std::vector<double> edge_weight;
};

/// Its resolution and shares: `bins` slots along each edge it keeps, at most max_slots in all
/// (the edges of most training weight first), dir_res^2 cells of directions in each, `fraction`
/// of the directions drawn from it, and the edges picked by a mixture of their length
/// (1 - edge_fraction) and their training weight (edge_fraction).
struct SecondaryGuideShape {
    unsigned bins = 4;
    unsigned max_slots = 512;
    unsigned dir_res = 64;
    float fraction = 0.9f;
    float edge_fraction = 0.5f;
};

/// The BoundarySamples::guide of a name: "auto" -1, "on" 1, "off" 0; else Error naming `what`.
int secondary_guide_mode(const std::string& name, const std::string& what);

/// Whether the secondary term of `scene` is guided by default: where a surface's BSDF has a glossy lobe
/// (roughconductor, roughplastic), which the unguided directions sample poorly. The one place
/// this is decided.
bool secondary_guided(const RenderScene& scene);

/// The guide from training samples (t on its edge, weight; weight 0: none), their direction cells
/// and their edges (of edge_count), summed in order (deterministic). Each slot's histogram is
/// blurred by [1 2 1]^2 / 16 over its cells (wrapping in phi), so that a lobe between training
/// samples keeps a density, and a slot that no sample reached takes its edge's whole histogram.
/// No guide (fraction 0) where no sample has weight. Throws Error for a shape the kernels cannot
/// index (bins or dir_res 0, dir_res over 1024, max_slots dir_res^2 of 2^32 or more).
SecondaryGuideTables build_secondary_guide(const std::vector<gpu::float4>& samples,
                                           const std::vector<unsigned>& cells,
                                           const std::vector<unsigned>& edge_of,
                                           unsigned edge_count, const SecondaryGuideShape& shape);

/// Mixes the training's edge weights into the edges' probabilities (SecondaryEdge::n0.w, by
/// length): (1 - edge_fraction) of them as they are, edge_fraction in proportion to the weight.
/// Leaves them where the guide has no weight.
void guide_edge_choice(const SecondaryGuideTables& guide, const SecondaryGuideShape& shape,
                       std::vector<gpu::SecondaryEdge>& edges);

/// Trains and builds the guide of view `view` for the secondary edges `edges` (count of them),
/// with `seed`'s own stream: as many training samples as the estimate takes (per_pixel per
/// pixel), at least 2^10, at most 2^20 and at most 2^28 / edge_count (each looks for its nearest
/// silhouette over every edge: time in proportion to samples x edges).
SecondaryGuideTables train_secondary_guide(const View& view, const Buffer<float>& params,
                                           std::uint32_t seed, int per_pixel,
                                           const Buffer<gpu::SecondaryEdge>& edges,
                                           unsigned edge_count,
                                           const SecondaryGuideShape& shape = {});

} // namespace tandem
