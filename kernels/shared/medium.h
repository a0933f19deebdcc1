// Participating media, the parts that host and device share: phase functions (isotropic and
// Henyey-Greenstein, Mitsuba's conventions) and trilinear grid lookups (Mitsuba's gridvolume).
// The free flights and transmittance that use them are path pieces (kernels/path/media.h).
#ifndef TANDEM_SHARED_MEDIUM_H
#define TANDEM_SHARED_MEDIUM_H

#include "shared/compat.h"
#include "shared/det_math.h"
#include "shared/sampling.h"
#include "shared/scene_layout.h"

TANDEM_NAMESPACE_BEGIN

/// Below this |g| the Henyey-Greenstein phase is sampled and evaluated as isotropic (its sampling
/// formula divides by g); the two stay consistent, so the phase sample's weight is exactly 1.
#define PHASE_HG_MIN_G 1e-3f

/// The phase function's density (1/sr) of scattering by the angle whose cosine to the direction of
/// travel is cos_theta: 1 / (4 pi) for isotropic; Henyey-Greenstein's
/// (1 - g^2) / (4 pi (1 + g^2 - 2 g cos_theta)^(3/2)), forward scattering for g > 0 (Mitsuba's hg,
/// whose cosine is taken to wi = minus the direction of travel, hence its + 2 g).
TANDEM_INLINE float phase_eval(uint kind, float g, float cos_theta) {
    if (kind != PHASE_HG || fabs(g) < PHASE_HG_MIN_G) return 1.0f / (4.0f * TANDEM_PI);
    const float denom = 1.0f + g * g - 2.0f * g * cos_theta;
    return (1.0f - g * g) / (4.0f * TANDEM_PI * denom * sqrt(denom));
}

/// d/dg of the logarithm of the phase function's density at cos_theta (as phase_eval's): 0 for
/// isotropic; for Henyey-Greenstein -2 g / (1 - g^2) + 3 (cos_theta - g) / (1 + g^2 - 2 g cos_theta),
/// also below PHASE_HG_MIN_G (3 cos_theta at g = 0: the derivative of the phase that
/// phase_eval rounds to isotropic there).
TANDEM_INLINE float phase_dlog_dg(uint kind, float g, float cos_theta) {
    if (kind != PHASE_HG) return 0.0f;
    return -2.0f * g / (1.0f - g * g) + 3.0f * (cos_theta - g) / (1.0f + g * g - 2.0f * g * cos_theta);
}

/// The cosine to the direction of travel of a scattering direction drawn from the phase function
/// with u (its inverse CDF): 2u - 1 for isotropic; for Henyey-Greenstein
/// (1 + g^2 - ((1 - g^2) / (1 - g + 2 g u))^2) / (2 g), which runs from -1 at u = 0 to 1 at u = 1.
TANDEM_INLINE float phase_sample_cos(uint kind, float g, float u) {
    if (kind != PHASE_HG || fabs(g) < PHASE_HG_MIN_G) return 2.0f * u - 1.0f;
    const float q = (1.0f - g * g) / (1.0f - g + 2.0f * g * u);
    return fmin(fmax((1.0f + g * g - q * q) / (2.0f * g), -1.0f), 1.0f);
}

/// A direction drawn from the phase function about unit direction of travel d with (u1, u2): the
/// cosine from u1 (phase_sample_cos), the azimuth 2 pi u2 in d's frame (frame_from_normal). Its
/// density is phase_eval of its cosine, so the sample's weight (phase / density) is 1.
TANDEM_INLINE float3 phase_sample(uint kind, float g, float3 d, float u1, float u2) {
    const float c = phase_sample_cos(kind, g, u1);
    const float s = sqrt(fmax(0.0f, 1.0f - c * c));
    float sin_phi, cos_phi;
    det_sincos(2.0f * TANDEM_PI * u2, &sin_phi, &cos_phi);
    return frame_to_world(frame_from_normal(d), make_float3(s * cos_phi, s * sin_phi, c));
}

/// The local point of world point x in grid g (its to_local rows).
TANDEM_INLINE float3 grid_local(const DeviceGrid* g, float3 x) {
    return make_float3(dot3(g->to_local0.x, g->to_local0.y, g->to_local0.z, x.x, x.y, x.z) +
                           g->to_local0.w,
                       dot3(g->to_local1.x, g->to_local1.y, g->to_local1.z, x.x, x.y, x.z) +
                           g->to_local1.w,
                       dot3(g->to_local2.x, g->to_local2.y, g->to_local2.z, x.x, x.y, x.z) +
                           g->to_local2.w);
}

/// The local direction of world direction d in grid g (the linear part of to_local).
TANDEM_INLINE float3 grid_local_dir(const DeviceGrid* g, float3 d) {
    return make_float3(dot3(g->to_local0.x, g->to_local0.y, g->to_local0.z, d.x, d.y, d.z),
                       dot3(g->to_local1.x, g->to_local1.y, g->to_local1.z, d.x, d.y, d.z),
                       dot3(g->to_local2.x, g->to_local2.y, g->to_local2.z, d.x, d.y, d.z));
}

/// The two voxels, i0 and i1, that a trilinear lookup at local coordinate p (in [0, 1]) blends
/// along an axis of n voxels, and the weight f of i1: voxel centres at (i + 1/2) / n, clamped at
/// the faces.
TANDEM_INLINE void grid_axis(float p, uint n, uint* i0, uint* i1, float* f) {
    const float u = p * (float)n - 0.5f;
    const float fl = det_floor(u);
    *f = u - fl;
    const int last = (int)n - 1, a = (int)fl;
    *i0 = (uint)(a < 0 ? 0 : (a > last ? last : a));
    *i1 = (uint)(a + 1 < 0 ? 0 : (a + 1 > last ? last : a + 1));
}

/// The voxels [*lo, *hi] that the trilinear interpolant (grid_axis: voxel centres at (i + 1/2) / n,
/// clamped) blends over cell c of `cells` equal cells along an axis of n voxels: what a majorant
/// cell must bound. In integers, exactly: the cell spans u = p n - 1/2 from (2 c n - cells) /
/// (2 cells) to (2 (c + 1) n - cells) / (2 cells).
TANDEM_INLINE void majorant_cell_voxels(uint c, uint cells, uint n, uint* lo, uint* hi) {
    const int den = 2 * (int)cells, a = 2 * (int)(c * n) - (int)cells,
              b = 2 * (int)((c + 1u) * n) - (int)cells, last = (int)n - 1;
    int l = a >= 0 ? a / den : -((-a + den - 1) / den); // floor(a / den)
    int h = b >= 0 ? (b + den - 1) / den : -((-b) / den); // ceil(b / den)
    l = l < 0 ? 0 : (l > last ? last : l);
    h = h < 0 ? 0 : (h > last ? last : h);
    *lo = (uint)l;
    *hi = (uint)h;
}

/// Channel c of grid g at local point l: trilinear between the eight voxels around it (Mitsuba's
/// gridvolume with filter_type "trilinear" and wrap_mode "clamp").
TANDEM_INLINE float grid_eval(TANDEM_GLOBAL const float* data, const DeviceGrid* g, float3 l, uint c) {
    uint x0, x1, y0, y1, z0, z1;
    float fx, fy, fz;
    grid_axis(l.x, g->nx, &x0, &x1, &fx);
    grid_axis(l.y, g->ny, &y0, &y1, &fy);
    grid_axis(l.z, g->nz, &z0, &z1, &fz);
    TANDEM_GLOBAL const float* v = data + g->offset;
    const uint ch = g->channels, row = g->nx, slice = g->nx * g->ny;
    const float v000 = v[(z0 * slice + y0 * row + x0) * ch + c];
    const float v100 = v[(z0 * slice + y0 * row + x1) * ch + c];
    const float v010 = v[(z0 * slice + y1 * row + x0) * ch + c];
    const float v110 = v[(z0 * slice + y1 * row + x1) * ch + c];
    const float v001 = v[(z1 * slice + y0 * row + x0) * ch + c];
    const float v101 = v[(z1 * slice + y0 * row + x1) * ch + c];
    const float v011 = v[(z1 * slice + y1 * row + x0) * ch + c];
    const float v111 = v[(z1 * slice + y1 * row + x1) * ch + c];
    const float a0 = v000 + (v100 - v000) * fx, a1 = v010 + (v110 - v010) * fx;
    const float b0 = v001 + (v101 - v001) * fx, b1 = v011 + (v111 - v011) * fx;
    const float a = a0 + (a1 - a0) * fy, b = b0 + (b1 - b0) * fy;
    return a + (b - a) * fz;
}

/// The eight voxels that a trilinear lookup of grid g at local point l blends (grid_eval), as
/// element indices of channel 0 relative to g->offset, and their weights (summing to 1): what the
/// lookup's derivative with respect to each voxel is.
TANDEM_INLINE void grid_corners(const DeviceGrid* g, float3 l, uint index[8], float weight[8]) {
    uint x[2], y[2], z[2];
    float fx, fy, fz;
    grid_axis(l.x, g->nx, &x[0], &x[1], &fx);
    grid_axis(l.y, g->ny, &y[0], &y[1], &fy);
    grid_axis(l.z, g->nz, &z[0], &z[1], &fz);
    for (uint k = 0; k < 8u; ++k) {
        const uint i = k & 1u, j = (k >> 1) & 1u, h = k >> 2;
        index[k] = ((z[h] * g->ny + y[j]) * g->nx + x[i]) * g->channels;
        weight[k] = (i ? fx : 1.0f - fx) * (j ? fy : 1.0f - fy) * (h ? fz : 1.0f - fz);
    }
}

/// Resampling a grid to another resolution (the optimizer's resolution schedule:
/// core/inverse/grid_schedule.h): voxel i of n_dst along an axis reads the grid of n_src voxels at
/// its centre (i + 1/2) / n_dst, as a lookup there would (grid_axis): voxels *i0 and *i1, the
/// weight f of *i1.
TANDEM_INLINE void grid_resample_axis(uint i, uint n_dst, uint n_src, uint* i0, uint* i1,
                                      float* f) {
    grid_axis(((float)i + 0.5f) / (float)n_dst, n_src, i0, i1, f);
}

/// The weight with which voxel i of n_dst reads voxel j of n_src along an axis (0 unless j is one
/// of the two it blends; both where they coincide at a face).
TANDEM_INLINE float grid_resample_weight(uint i, uint n_dst, uint n_src, uint j) {
    uint a, b;
    float f;
    grid_resample_axis(i, n_dst, n_src, &a, &b, &f);
    return (a == j ? 1.0f - f : 0.0f) + (b == j ? f : 0.0f);
}

/// The source voxels [*lo, *hi] along an axis that can give voxel j of n_src a non-zero weight in
/// a resampling to n_dst: those whose centres lie within one source voxel of j's (all of them up
/// to the faces for the first and last voxel, which the clamp widens), with a voxel's margin.
TANDEM_INLINE void grid_resample_span(uint j, uint n_src, uint n_dst, uint* lo, uint* hi) {
    const float r = (float)n_dst / (float)n_src;
    const int a = (int)det_floor(((float)j - 0.5f) * r) - 1, b = (int)det_floor(((float)j + 1.5f) * r) + 1;
    const int last = (int)n_dst - 1;
    *lo = (uint)(j == 0u || a < 0 ? 0 : a);
    *hi = (uint)(j + 1u == n_src || b > last ? last : b);
}

/// Element (x, y, z, c) of a grid of (dx, dy, dz) voxels of `ch` channels resampled from `src`
/// (sx, sy, sz voxels, the same channels; flat, channel fastest, then x, y, z): the trilinear blend
/// of the eight source voxels around the voxel's centre, as products of the axes' weights.
TANDEM_INLINE float grid_resample_at(TANDEM_GLOBAL const float* src, uint sx, uint sy, uint sz,
                                     uint ch, uint x, uint y, uint z, uint dx, uint dy, uint dz,
                                     uint c) {
    uint xi[2], yi[2], zi[2];
    float fx, fy, fz;
    grid_resample_axis(x, dx, sx, &xi[0], &xi[1], &fx);
    grid_resample_axis(y, dy, sy, &yi[0], &yi[1], &fy);
    grid_resample_axis(z, dz, sz, &zi[0], &zi[1], &fz);
    float v = 0.0f;
    for (uint k = 0; k < 8u; ++k) {
        const uint i = k & 1u, j = (k >> 1) & 1u, h = k >> 2;
        const float w = (i ? fx : 1.0f - fx) * (j ? fy : 1.0f - fy) * (h ? fz : 1.0f - fz);
        v += w * src[((zi[h] * sy + yi[j]) * sx + xi[i]) * ch + c];
    }
    return v;
}

/// The adjoint of grid_resample_at at source element (x, y, z, c): the sum over the resampled
/// grid's voxels of their weight on it times their adjoint g_dst (the same layouts), in a fixed
/// order. With it, a step on a coarse grid u whose resampling P u is what renders takes the
/// gradient P^T g.
TANDEM_INLINE float grid_resample_adjoint_at(TANDEM_GLOBAL const float* g_dst, uint dx, uint dy,
                                             uint dz, uint ch, uint x, uint y, uint z, uint sx,
                                             uint sy, uint sz, uint c) {
    uint x0, x1, y0, y1, z0, z1;
    grid_resample_span(x, sx, dx, &x0, &x1);
    grid_resample_span(y, sy, dy, &y0, &y1);
    grid_resample_span(z, sz, dz, &z0, &z1);
    float sum = 0.0f;
    for (uint k = z0; k <= z1; ++k) {
        const float wz = grid_resample_weight(k, dz, sz, z);
        if (wz == 0.0f) continue;
        for (uint j = y0; j <= y1; ++j) {
            const float wy = grid_resample_weight(j, dy, sy, y);
            if (wy == 0.0f) continue;
            for (uint i = x0; i <= x1; ++i) {
                const float wx = grid_resample_weight(i, dx, sx, x);
                if (wx != 0.0f) sum += wx * wy * wz * g_dst[((k * dy + j) * dx + i) * ch + c];
            }
        }
    }
    return sum;
}

/// Grid g at local point l as rgb: its three channels, or its one channel in all three.
TANDEM_INLINE float3 grid_eval3(TANDEM_GLOBAL const float* data, const DeviceGrid* g, float3 l) {
    if (g->channels == 1u) {
        const float v = grid_eval(data, g, l, 0u);
        return make_float3(v, v, v);
    }
    return make_float3(grid_eval(data, g, l, 0u), grid_eval(data, g, l, 1u),
                       grid_eval(data, g, l, 2u));
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_MEDIUM_H
