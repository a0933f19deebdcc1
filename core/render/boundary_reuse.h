// Reuse of the secondary boundary term's light vertices across iterations (kernels/path/
// boundary_reuse.h; "Amortizing Samples in Physics-Based Inverse Rendering using ReSTIR", Wang et
// al. 2023, Sec. 5.2; docs/restir.md, "Reuse for the boundary"): what it does (SecondaryReuseConfig)
// and the reservoirs it keeps from one pass to the next (SecondaryReservoirs), which the caller
// of the passes owns and hands to them (BoundarySamples::reuse, core/render/passes.h).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "runtime/buffer.h"
#include "runtime/context.h"
#include "shared/boundary.h"
#include "shared/reservoir.h"

namespace tandem {

struct RenderScene;

/// What the secondary term's reuse does.
struct SecondaryReuseConfig {
    int candidates = 8;       ///< fresh light points per sample (streaming RIS)
    int neighbours = 4;       ///< previous reservoirs of the same cell to combine with (0 to 8)
    float m_cap = 20.0f;      ///< a previous reservoir's confidence is capped at this when read
    float cell = 1.0f / 64.0f; ///< the grid's cell, as a fraction of the edges' bounding diagonal
    /// the target weighs down light points that neither side of the edge sees (one or two rays
    /// per target; off: from a silhouette toward a light point the light is mostly in view)
    bool visibility = false;
    bool receiver = false;    ///< and directions whose receiver the camera does not see
    /// the target's luminance floor, as a fraction of the brightest emitter's (the light that
    /// emitters' surfaces reflect)
    float floor = 1e-3f;
};

/// Checks `config`'s ranges; throws Error "WHERE: ..." naming the field.
void validate_secondary_reuse(const SecondaryReuseConfig& config, const std::string& where);

/// The secondary term's reservoirs of the previous pass, keyed by the grid cell of their boundary
/// point, and this pass's. A pass reads the previous ones and writes its own (begin()); commit()
/// makes them the previous ones. The grid's cell and the target's floor are fixed at the first
/// pass, for the run. Deterministic: the buckets list their reservoirs in slot order.
class SecondaryReservoirs {
public:
    SecondaryReservoirs(Context& ctx, const SecondaryReuseConfig& config);

    const SecondaryReuseConfig& config() const { return m_config; }

    /// The kernel's settings for a pass of `samples` samples over `edges` (secondary_edges) of
    /// `scene`; sizes current() to `samples`.
    gpu::SecondaryReuse begin(const RenderScene& scene, const std::vector<gpu::SecondaryEdge>& edges,
                              std::size_t samples);
    /// The pass's reservoirs become the previous ones, with the pass's edge table `edges`; their
    /// buckets are built on the host (a blocking read of current()).
    void commit(const std::vector<gpu::SecondaryEdge>& edges);
    /// Forgets the previous reservoirs (the next pass resamples fresh candidates alone).
    void reset();

    /// All a later pass reads of the passes before it: the grid's cell and the floor (once fixed
    /// by the first pass), the previous reservoirs and their edge table (none before the first
    /// commit). What a checkpoint carries (core/inverse/secondary_reuse_state.h).
    struct Saved {
        bool fixed = false;
        float cell = 0.0f, lum_floor = 0.0f;
        std::vector<gpu::BoundaryReservoir> previous;
        std::vector<gpu::SecondaryEdge> edges;
    };
    Saved saved() const;
    /// Continues from what saved() gave, bit for bit (the buckets are built again).
    void restore(const Saved& s);

    const Buffer<gpu::BoundaryReservoir>& previous() const { return m_prev; }
    const Buffer<gpu::SecondaryEdge>& previous_edges() const { return m_prev_edges; }
    const Buffer<unsigned>& bucket_first() const { return m_first; }
    const Buffer<unsigned>& bucket_slots() const { return m_slots; }
    Buffer<gpu::BoundaryReservoir>& current() { return m_current; }
    std::size_t buckets() const { return m_buckets; } ///< 0 before the first commit

    /// The buckets of `reservoirs`: a power of two at least twice their count; first (buckets + 1
    /// entries) the starts into slots, which lists every reservoir of each bucket (its cell's low
    /// bits), empty ones too, in slot order.
    struct Buckets {
        std::vector<unsigned> first, slots;
    };
    static Buckets bucket(const std::vector<gpu::BoundaryReservoir>& reservoirs);

private:
    /// The previous reservoirs' buckets and edge table.
    void set_previous(const std::vector<gpu::BoundaryReservoir>& reservoirs,
                      const std::vector<gpu::SecondaryEdge>& edges);

    Context& m_ctx;
    SecondaryReuseConfig m_config;
    float m_cell = 0.0f;      ///< world units, from the first pass's edges
    float m_lum_floor = -1.0f; ///< from the first pass's scene
    std::size_t m_buckets = 0;
    Buffer<gpu::BoundaryReservoir> m_prev, m_current;
    Buffer<gpu::SecondaryEdge> m_prev_edges;
    Buffer<unsigned> m_first, m_slots;
};

} // namespace tandem
