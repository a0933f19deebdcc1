// Participating media in the path tracer (HAS_MEDIA builds): free flights by spectral tracking
// against a majorant and transmittance by ratio tracking (closed form in a homogeneous medium).
// Their adjoint is path/media_adjoint.h; the volumetric path that uses them, path/volume.h
// (docs/method.md, "Participating media").
//
// RGB extinction: one distance for all three channels, drawn from the majorant of the largest
// channel, then spectral tracking (Kutz et al. 2017, "Spectral and Decomposition Tracking for
// Rendering Heterogeneous Volumes", section 5.2, with its history-aware probabilities and
// absorption folded into the weights): at a tentative collision the path scatters with
// probability P_s = avg(|beta sigma_s|) / (avg(|beta sigma_s|) + avg(|beta sigma_n|)) and weight
// sigma_s / (mu P_s), or goes on with weight sigma_n / (mu (1 - P_s)). One distance for every
// channel is what the gradients need: the two-state path and the replay walk the same collisions
// for every channel and both parameter states, under one majorant. (Mitsuba's volpath picks a hero
// channel per path instead; both are unbiased.)
#ifndef TANDEM_KERNELS_PATH_MEDIA_H
#define TANDEM_KERNELS_PATH_MEDIA_H

#include "path/continuation.h"
#include "path/emission.h"
#include "path/nee.h"
#include "shared/medium.h"

// The random numbers of free flights and ratio tracking: a stream of their own per path vertex and
// purpose (the free flights that lead from the vertex, or its shadow ray's ratio tracking), keyed
// by a hash of (seed, depth, purpose) in place of the seed, its dimensions counted from 0. (Not
// dimensions with a high bit set beside the path's own: pcg4d mixes inputs that differ only in
// their high bits poorly, and such streams came out correlated with the vertex's light sample,
// which biased single scattering by about 1 % where null collisions occur.) A walk that would draw
// more than MEDIA_MAX_DRAWS (2^18 collisions, far beyond any medium a majorant bounds sensibly)
// gives up, and so does a path or shadow ray that would cross more than MEDIA_MAX_CROSSINGS null
// surfaces: the sample's radiance is then not a number (media_gave_up), which the passes drop
// and count in their guards, as any non-finite sample.
#define MEDIA_MAX_DRAWS 0x80000u
#define MEDIA_STREAM_TAG 0x6D656469u /* "medi" */
/// Null surfaces a path or shadow ray crosses between two scattering vertices, at most.
#define MEDIA_MAX_CROSSINGS 64u

/// The radiance of a sample whose walk gave up (see above): dropped and counted by the passes.
TANDEM_INLINE float3 media_gave_up(void) { return make_float3(NAN, NAN, NAN); }

#define FLIGHT_ESCAPED 0
#define FLIGHT_SCATTERED 1
#define FLIGHT_ABSORBED 2

/// A stream of random numbers for one walk: dimensions `dim` up to `end` of the stream's key.
typedef struct MediaRng {
    PathRng rng;
    uint dim, end;
    int exhausted;
} MediaRng;

#define MEDIA_FLIGHTS 0u      /* the free flights that lead from a vertex */
#define MEDIA_SHADOW 1u       /* its shadow ray's ratio tracking */
#define MEDIA_FLIGHTS_GRAD 2u /* the replay's points on the free flights' segments */
#define MEDIA_SHADOW_GRAD 3u  /* the replay's points on the shadow ray's segments */
#define MEDIA_DRT_PICK 4u     /* the replay's choice of its differential ratio tracking segment */
#define MEDIA_DRT_POINT 5u    /* that segment's point and transmittance */
#define MEDIA_DRT_PATH 6u     /* the key of the path that estimates the radiance there */

/// The stream of `purpose` (MEDIA_*) of the vertex at `depth` of the path of `rng`.
TANDEM_INLINE MediaRng media_rng(PathRng rng, uint depth, uint purpose) {
    uint key[4];
    rng_pcg4d(rng.seed, depth, purpose, MEDIA_STREAM_TAG, key);
    MediaRng r;
    r.rng = path_rng(key[0], rng.pixel, rng.sample);
    r.dim = 0u;
    r.end = MEDIA_MAX_DRAWS;
    r.exhausted = 0;
    return r;
}

TANDEM_INLINE float media_rand(MediaRng* r) {
    if (r->dim == r->end) {
        r->exhausted = 1;
        return 0.0f;
    }
    return path_rand(r->rng, r->dim++);
}

/// The medium a ray of direction d is in after crossing the surface of record `info` whose front
/// normal is n_front, coming from `current`: the shape's interior (d against the normal) or
/// exterior, where the shape is a medium transition; `current` where it is not (Mitsuba's rule).
TANDEM_INLINE uint medium_crossed(const TriangleInfo* info, float3 d, float3 n_front,
                                  uint current) {
    if (info->interior == NO_MEDIUM && info->exterior == NO_MEDIUM) return current;
    return vdot(d, n_front) < 0.0f ? info->interior : info->exterior;
}

/// Medium `index` with its differentiable values taken from params (Medium's *_param), ready for
/// the functions below: sigma_t.w is the scale; a homogeneous medium's sigma_t.xyz is its
/// extinction times the scale. `majorant` is what free flights and ratio tracking draw against: a
/// homogeneous medium's largest channel of that extinction, or the factor on a grid's majorant
/// cells (its scale).
TANDEM_INLINE Medium medium_load(const SceneRefs* s, __global const float* params, uint index) {
    Medium m = s->media[index];
    if (m.scale_param != NO_PARAM) m.sigma_t.w = params[m.scale_param];
    if (m.g_param != NO_PARAM) m.g = params[m.g_param];
    if (m.albedo_grid == NO_GRID && m.albedo_param != NO_PARAM) {
        const float3 a = param_rgb(params, m.albedo_param);
        m.albedo = make_float4(a.x, a.y, a.z, 0.0f);
    }
    if (m.kind == MEDIUM_HOMOGENEOUS) {
        const float3 st = param_rgb_or(params, m.sigma_t_param, xyz(m.sigma_t)) * m.sigma_t.w;
        m.sigma_t = make_float4(st.x, st.y, st.z, m.sigma_t.w);
        m.majorant = fmax(st.x, fmax(st.y, st.z));
    } else {
        m.majorant = m.sigma_t.w;
    }
    return m;
}

/// The previous parameter state theta_{n-1} that a two-state path (CV-PS) carries beside the new
/// one ("Recursive Control Variates for Inverse Rendering", section 5; path/volume.h): its
/// parameters, its throughput along the same path and its radiance so far.
typedef struct OldState {
    __global const float* params;
    float3 beta, L;
} OldState;

/// Medium `index` in the new state (params) into *m and, for a two-state path (old not 0), in the
/// old state into *m_old, both with one majorant that bounds the two: the larger of their
/// majorants (for a grid, whose majorant cells DeviceScene::refresh_majorants takes over both
/// parameter buffers, the larger scale). Both states then see the same tentative collisions.
TANDEM_INLINE void medium_load_states(const SceneRefs* s, __global const float* params,
                                      const OldState* old, uint index, Medium* m, Medium* m_old) {
    *m = medium_load(s, params, index);
    if (!old) return;
    *m_old = medium_load(s, old->params, index);
    m->majorant = m_old->majorant = fmax(m->majorant, m_old->majorant);
}

/// Extinction and scattering coefficients (rgb) of medium m (medium_load) at world point x. Grids
/// are parameters: their voxels are read from params.
TANDEM_INLINE void medium_coefficients(const SceneRefs* s, __global const float* params,
                                       const Medium* m, float3 x, float3* sigma_t,
                                       float3* sigma_s) {
    float3 st = xyz(m->sigma_t), albedo = xyz(m->albedo);
    if (m->kind == MEDIUM_GRID) {
        const DeviceGrid g = s->grids[m->sigma_t_grid];
        st = grid_eval3(params, &g, grid_local(&g, x)) * m->sigma_t.w;
    }
    if (m->albedo_grid != NO_GRID) {
        const DeviceGrid g = s->grids[m->albedo_grid];
        albedo = grid_eval3(params, &g, grid_local(&g, x));
    }
    *sigma_t = st;
    *sigma_s = st * albedo;
}

/// A walk along a ray through a medium's majorant: pieces [a, b) of the ray, in order, each with
/// one majorant mu. A homogeneous medium is one piece; a grid medium's are the cells of its
/// majorant grid that the ray crosses inside the grid's unit cube (a 3D DDA: Amanatides and Woo
/// 1987), outside of which the medium is empty.
typedef struct MajorantWalk {
    float t, t_end; ///< the walk's position and its end
    float mu;       ///< homogeneous: the majorant
    int grid;       ///< walks the cells of a majorant grid
    int cx, cy, cz, sx, sy, sz;
    float next_x, next_y, next_z, dx, dy, dz;
    uint nx, ny, nz, offset;
    float scale;
    float piece_t, piece_end, piece_mu; ///< majorant_collision's place in the current piece
} MajorantWalk;

/// The DDA's setup on one axis: ray origin o and direction d in cell units, the start cell c;
/// the ray parameter of the next cell face, the step between faces, and the cell step.
TANDEM_INLINE void walk_axis(float o, float d, int c, float* next, float* delta, int* step) {
    if (d > 0.0f) {
        *next = ((float)(c + 1) - o) / d;
        *delta = 1.0f / d;
        *step = 1;
    } else if (d < 0.0f) {
        *next = ((float)c - o) / d;
        *delta = -1.0f / d;
        *step = -1;
    } else {
        *next = INFINITY;
        *delta = INFINITY;
        *step = 0;
    }
}

/// The slab [0, n] on one axis of a ray o + t d (cell units), intersected into [*t0, *t1).
TANDEM_INLINE void walk_clip(float o, float d, float n, float* t0, float* t1) {
    if (d == 0.0f) {
        if (!(o >= 0.0f && o <= n)) *t1 = *t0; // parallel and outside: empty
        return;
    }
    const float a = (0.0f - o) / d, b = (n - o) / d;
    *t0 = fmax(*t0, fmin(a, b));
    *t1 = fmin(*t1, fmax(a, b));
}

/// Cell c of an axis of n cells at coordinate p (clamped: p is in [0, n] up to rounding).
TANDEM_INLINE int walk_cell(float p, uint n) {
    const int c = (int)det_floor(p), last = (int)n - 1;
    return c < 0 ? 0 : (c > last ? last : c);
}

/// Starts the walk through medium m along o + t d (d unit, world space) over [t0, t1).
TANDEM_INLINE void majorant_walk_begin(const SceneRefs* s, const Medium* m, float3 o, float3 d,
                                       float t0, float t1, MajorantWalk* w) {
    w->t = t0;
    w->t_end = t1;
    w->piece_t = w->piece_end = w->piece_mu = 0.0f; // no piece yet
    w->mu = m->majorant;
    w->grid = m->kind == MEDIUM_GRID;
    if (!w->grid) return;
    const DeviceGrid g = s->grids[m->majorant_grid];
    w->nx = g.nx;
    w->ny = g.ny;
    w->nz = g.nz;
    w->offset = g.offset;
    w->scale = m->majorant;
    const float3 res = make_float3((float)g.nx, (float)g.ny, (float)g.nz);
    const float3 ol = grid_local(&g, o) * res, dl = grid_local_dir(&g, d) * res;
    walk_clip(ol.x, dl.x, res.x, &w->t, &w->t_end);
    walk_clip(ol.y, dl.y, res.y, &w->t, &w->t_end);
    walk_clip(ol.z, dl.z, res.z, &w->t, &w->t_end);
    if (!(w->t < w->t_end)) return;
    const float3 p = ol + dl * w->t;
    w->cx = walk_cell(p.x, g.nx);
    w->cy = walk_cell(p.y, g.ny);
    w->cz = walk_cell(p.z, g.nz);
    walk_axis(ol.x, dl.x, w->cx, &w->next_x, &w->dx, &w->sx);
    walk_axis(ol.y, dl.y, w->cy, &w->next_y, &w->dy, &w->sy);
    walk_axis(ol.z, dl.z, w->cz, &w->next_z, &w->dz, &w->sz);
}

/// The walk's next piece [*a, *b) and its majorant *mu; 0 when the walk is over.
TANDEM_INLINE int majorant_walk_next(const SceneRefs* s, MajorantWalk* w, float* a, float* b,
                                     float* mu) {
    if (!(w->t < w->t_end)) return 0;
    *a = w->t;
    if (!w->grid) {
        *b = w->t_end;
        *mu = w->mu;
        w->t = w->t_end;
        return 1;
    }
    if (w->cx < 0 || w->cy < 0 || w->cz < 0 || w->cx >= (int)w->nx || w->cy >= (int)w->ny ||
        w->cz >= (int)w->nz)
        return 0;
    const uint cell = ((uint)w->cz * w->ny + (uint)w->cy) * w->nx + (uint)w->cx;
    *mu = w->scale * s->medium_data[w->offset + cell];
    const float tn = fmin(w->next_x, fmin(w->next_y, w->next_z));
    *b = fmin(tn, w->t_end);
    if (w->next_x == tn) {
        w->cx += w->sx;
        w->next_x += w->dx;
    } else if (w->next_y == tn) {
        w->cy += w->sy;
        w->next_y += w->dy;
    } else {
        w->cz += w->sz;
        w->next_z += w->dz;
    }
    w->t = *b;
    return 1;
}

/// The walk's next tentative collision: its distance *t and the majorant *mu it was drawn against
/// (exponential steps against each piece's majorant, from the piece's start: free flights and
/// ratio tracking alike). Returns 0 when the walk is over, or when r ran out (r->exhausted).
TANDEM_INLINE int majorant_collision(const SceneRefs* s, MajorantWalk* w, MediaRng* r, float* t,
                                     float* mu) {
    for (;;) {
        if (w->piece_mu > 0.0f) {
            w->piece_t -= det_log(1.0f - media_rand(r)) / w->piece_mu;
            if (r->exhausted) return 0;
            if (w->piece_t < w->piece_end) {
                *t = w->piece_t;
                *mu = w->piece_mu;
                return 1;
            }
        }
        if (!majorant_walk_next(s, w, &w->piece_t, &w->piece_end, &w->piece_mu)) return 0;
    }
}

/// The sum of a channel triple (the adjoint of a value that is the same in every channel).
TANDEM_INLINE float channel_sum(float3 v) { return v.x + v.y + v.z; }

/// The mean of a channel triple's magnitudes (spectral tracking's probabilities).
TANDEM_INLINE float media_mean(float3 v) {
    return (fabs(v.x) + fabs(v.y) + fabs(v.z)) * (1.0f / 3.0f);
}

/// The majorant of medium m (medium_load) at world point x: a grid's majorant cell there times
/// its scale, the majorant of a homogeneous one (what a walk through x draws against).
TANDEM_INLINE float medium_majorant_at(const SceneRefs* s, const Medium* m, float3 x) {
    if (m->kind != MEDIUM_GRID) return m->majorant;
    const DeviceGrid g = s->grids[m->majorant_grid];
    const float3 l = grid_local(&g, x);
    const uint cell = ((uint)walk_cell(l.z * (float)g.nz, g.nz) * g.ny +
                       (uint)walk_cell(l.y * (float)g.ny, g.ny)) * g.nx +
                      (uint)walk_cell(l.x * (float)g.nx, g.nx);
    return m->majorant * s->medium_data[g.offset + cell];
}

/// A point on o + t d over [t0, t1) in medium m drawn from its majorant: the walk's first
/// tentative collision, *t, with its density *pdf = mu(t) exp(-int_t0^t mu) (a free flight through
/// the majorant alone; the density is defective: 0 where the walk ends first, and then there is no
/// point). Differential ratio tracking's point (path/media_drt.h). Returns whether there is one.
TANDEM_INLINE int medium_majorant_point(const SceneRefs* s, const Medium* m, float3 o, float3 d,
                                        float t0, float t1, MediaRng* r, float* t, float* pdf) {
    MajorantWalk w;
    majorant_walk_begin(s, m, o, d, t0, t1, &w);
    float a, b, mu, tau = 0.0f;
    while (majorant_walk_next(s, &w, &a, &b, &mu)) {
        if (!(mu > 0.0f)) continue;
        const float step = -det_log(1.0f - media_rand(r)) / mu; // memoryless: afresh per piece
        if (r->exhausted) return 0;
        if (a + step < b) {
            *t = a + step;
            *pdf = mu * det_exp(-(tau + mu * step));
            return *pdf > 0.0f;
        }
        tau += mu * (b - a);
    }
    return 0;
}

/// sigma_n = mu - sigma_t per channel: the null collisions' coefficient under majorant mu.
TANDEM_INLINE float3 media_null(float mu, float3 sigma_t) {
    return make_float3(fmax(mu - sigma_t.x, 0.0f), fmax(mu - sigma_t.y, 0.0f),
                       fmax(mu - sigma_t.z, 0.0f));
}

/// A free flight through `medium` along o + t d over [t0, t1) (t1: the surface the ray found, or
/// +inf), by spectral tracking (see the top of this file) with random numbers from r. Returns
/// FLIGHT_SCATTERED with the collision's distance in *t_out, FLIGHT_ESCAPED at t1, or
/// FLIGHT_ABSORBED (nothing of the throughput is left, or r ran out: r->exhausted); *beta is
/// weighted either way.
///
/// A two-state path (old not 0; m and m_old from medium_load_states, under one majorant) walks one
/// flight for both states ("Recursive Control Variates for Inverse Rendering", section 5): the
/// probabilities P_s and P_n come from both throughputs (the sums of each state's avg |beta sigma|),
/// and each state's throughput takes its own sigma_s / (mu P_s) or sigma_n / (mu P_n). Each state's
/// weights then have the expectation of its own transmittance and scattering, so both estimates
/// are unbiased, and P_s > 0 wherever either state scatters. With equal states the probabilities
/// are those of one state (both sums double), and so are the weights, bit for bit.
TANDEM_INLINE int medium_free_flight(const SceneRefs* s, __global const float* params,
                                     const Medium* m, float3 o, float3 d, float t0, float t1,
                                     MediaRng* r, float3* beta, float* t_out, OldState* old,
                                     const Medium* m_old) {
    MajorantWalk w;
    majorant_walk_begin(s, m, o, d, t0, t1, &w);
    float t, mu;
    while (majorant_collision(s, &w, r, &t, &mu)) {
        float3 st, ss, ss_old = make_float3(0.0f, 0.0f, 0.0f), sn_old = ss_old;
        medium_coefficients(s, params, m, o + d * t, &st, &ss);
        const float3 sn = media_null(mu, st);
        float ps = media_mean(*beta * ss), pn = media_mean(*beta * sn);
        if (old) {
            float3 st_old;
            medium_coefficients(s, old->params, m_old, o + d * t, &st_old, &ss_old);
            sn_old = media_null(mu, st_old);
            ps += media_mean(old->beta * ss_old);
            pn += media_mean(old->beta * sn_old);
        }
        if (!(ps + pn > 0.0f)) return FLIGHT_ABSORBED;
        const float p_scatter = ps / (ps + pn);
        if (pn == 0.0f || media_rand(r) < p_scatter) {
            const float k = 1.0f / (mu * p_scatter);
            *beta = *beta * ss * k;
            if (old) old->beta = old->beta * ss_old * k;
            *t_out = t;
            return FLIGHT_SCATTERED;
        }
        const float k = 1.0f / (mu * (1.0f - p_scatter));
        *beta = *beta * sn * k;
        if (old) old->beta = old->beta * sn_old * k;
    }
    return r->exhausted ? FLIGHT_ABSORBED : FLIGHT_ESCAPED;
}

/// exp(-sigma t) of one channel: 1 where sigma is 0, whatever t (even +inf).
TANDEM_INLINE float media_beer(float sigma, float t) {
    return sigma > 0.0f ? det_exp(-sigma * t) : 1.0f;
}

/// The transmittance (rgb) of `medium` along o + t d over [t0, t1): in closed form in a
/// homogeneous medium, by ratio tracking (Novak et al. 2014, "Residual Ratio Tracking for
/// Estimating Attenuation in Participating Media", section 3) against the majorant walk in a grid
/// one, with random numbers from r (0 where r runs out).
TANDEM_INLINE float3 medium_transmittance(const SceneRefs* s, __global const float* params,
                                          const Medium* m, float3 o, float3 d, float t0, float t1,
                                          MediaRng* r) {
    if (m->kind == MEDIUM_HOMOGENEOUS) {
        const float len = t1 - t0;
        return make_float3(media_beer(m->sigma_t.x, len), media_beer(m->sigma_t.y, len),
                           media_beer(m->sigma_t.z, len));
    }
    float3 T = make_float3(1.0f, 1.0f, 1.0f);
    MajorantWalk w;
    majorant_walk_begin(s, m, o, d, t0, t1, &w);
    float t, mu;
    while (majorant_collision(s, &w, r, &t, &mu)) {
        float3 st, ss;
        medium_coefficients(s, params, m, o + d * t, &st, &ss);
        T = T * media_null(mu, st) * (1.0f / mu);
        if (!(max_component(T) > 0.0f)) return T;
    }
    return r->exhausted ? media_gave_up() : T;
}

#endif // TANDEM_KERNELS_PATH_MEDIA_H
