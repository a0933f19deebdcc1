// The guided share of the secondary boundary term's directions (docs/method.md, "Glossy
// receivers"): where the edge point x_B has a slot in the guide (shared/boundary.h:
// SecondaryGuide; built by core/render/boundary_guide.h from camera paths), a direction is drawn
// from that slot's piecewise-constant density over cells of equal solid angle, learnt where the
// receivers' BSDF lobes meet silhouettes. As Mitsuba 3's projective sampling guides its boundary
// samples ("Projective Sampling for Differentiable Rendering of Geometry", Zhang et al. 2023,
// Sec. 5), the estimate stays unbiased whatever the guide holds: its density is evaluated exactly,
// in the mixture with the unguided directions, which keep every direction reachable.
#ifndef TANDEM_KERNELS_PATH_BOUNDARY_GUIDE_H
#define TANDEM_KERNELS_PATH_BOUNDARY_GUIDE_H

#include "shared/boundary.h"

/// The guide's tables as the kernels read them.
typedef struct GuideRefs {
    SecondaryGuide g;
    __global const uint* edge_slot; ///< per edge: GUIDE_NO_SLOT or its first slot
    __global const float* cdf;      ///< per slot, dir_res^2 cells: the inclusive CDF
} GuideRefs;

/// The slot of the point at parameter t of edge `edge`: GUIDE_NO_SLOT without a guide or where the
/// edge has none.
TANDEM_INLINE uint guide_slot(const GuideRefs* r, uint edge, float t) {
    if (!(r->g.fraction > 0.0f)) return GUIDE_NO_SLOT;
    const uint first = r->edge_slot[edge];
    if (first == GUIDE_NO_SLOT) return GUIDE_NO_SLOT;
    return first + min((uint)(t * (float)r->g.bins), r->g.bins - 1u);
}

/// The density per unit solid angle of guide_sample's directions w in slot `slot`.
TANDEM_INLINE float guide_pdf(const GuideRefs* r, uint slot, float3 w) {
    const uint n = r->g.dir_res, cells = n * n;
    const uint c = secondary_guide_cell(w, n);
    __global const float* cdf = r->cdf + slot * cells;
    const float p = cdf[c] - (c > 0u ? cdf[c - 1u] : 0.0f);
    return p * (float)cells * (0.25f * TANDEM_INV_PI);
}

/// A direction from slot `slot`'s density: its cell by the CDF (the first whose CDF exceeds
/// u_cell), then uniform inside it (uniform_sphere over the cell's part of the square).
TANDEM_INLINE float3 guide_sample(const GuideRefs* r, uint slot, float u_cell, float u1, float u2) {
    const uint n = r->g.dir_res, cells = n * n;
    __global const float* cdf = r->cdf + slot * cells;
    uint lo = 0u, hi = cells - 1u;
    while (lo < hi) {
        const uint mid = (lo + hi) >> 1u;
        if (cdf[mid] > u_cell) hi = mid;
        else lo = mid + 1u;
    }
    const float inv_n = 1.0f / (float)n;
    return sample_uniform_sphere(((float)(lo / n) + u1) * inv_n, ((float)(lo % n) + u2) * inv_n);
}

#endif // TANDEM_KERNELS_PATH_BOUNDARY_GUIDE_H
