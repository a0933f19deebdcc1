// Vector helpers and sampling routines shared by host and device: value in, value out, so doctest
// checks them on the host (chi-square, tests/kernels/shared/test_bsdf.cpp and tests/core/render/test_lights.cpp) and the device runs the same.
#ifndef TANDEM_SHARED_SAMPLING_H
#define TANDEM_SHARED_SAMPLING_H

#include "shared/compat.h"
#include "shared/det_math.h"

TANDEM_NAMESPACE_BEGIN

#define TANDEM_PI 3.14159265358979323846f
#define TANDEM_INV_PI 0.31830988618379067154f

// Own dot/cross/normalize rather than the OpenCL built-ins, whose accuracy is implementation
// defined: these give the same bits on every device and on the host.
/// (ax, ay, az) . (bx, by, bz), in this order: the one dot product (vdot applies it to float3s,
/// the wavefront's shading stage to its scalars).
TANDEM_INLINE float dot3(float ax, float ay, float az, float bx, float by, float bz) {
    return ax * bx + ay * by + az * bz;
}
TANDEM_INLINE float vdot(float3 a, float3 b) { return dot3(a.x, a.y, a.z, b.x, b.y, b.z); }
TANDEM_INLINE float3 vcross(float3 a, float3 b) {
    return make_float3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
TANDEM_INLINE float vlength(float3 a) { return sqrt(vdot(a, a)); }
TANDEM_INLINE float3 vnormalize(float3 a) { return a * (1.0f / vlength(a)); }
TANDEM_INLINE float3 xyz(float4 v) { return make_float3(v.x, v.y, v.z); }
/// The unit normal (p1 - p0) x (p2 - p0) of a triangle: the side its front faces (an emitter
/// emits on it). The host stores it in ShadingPrimitive.n_front and EmissiveTriangle's nx .. nz.
TANDEM_INLINE float3 triangle_front_normal(float3 p0, float3 p1, float3 p2) {
    return vnormalize(vcross(p1 - p0, p2 - p0));
}
TANDEM_INLINE float luminance(float3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }
TANDEM_INLINE float max_component(float3 c) { return fmax(c.x, fmax(c.y, c.z)); }
TANDEM_INLINE int all_finite(float3 c) { return isfinite(c.x) && isfinite(c.y) && isfinite(c.z); }
/// Arithmetic mean of the three channels (Mitsuba's `mean` of an RGB spectrum).
TANDEM_INLINE float mean3(float3 c) { return (c.x + c.y + c.z) * (1.0f / 3.0f); }
/// sqrt clamped at 0, for arguments that rounding may push slightly negative.
TANDEM_INLINE float safe_sqrt(float x) { return sqrt(fmax(x, 0.0f)); }
/// Mirror reflection of w about the unit vector n: 2 (w.n) n - w (w points away from the surface).
TANDEM_INLINE float3 vreflect(float3 w, float3 n) { return n * (2.0f * vdot(w, n)) - w; }

/// Origin for a ray leaving a surface at p with geometric normal n (pointing to the side the ray
/// leaves on): Waechter and Binder, "A Fast and Robust Method for Avoiding Self-Intersection", Ray
/// Tracing Gems ch. 6, 2019. Moves p a few ulps along n, scaled with its magnitude; within
/// OFFSET_ORIGIN of 0 by a fixed OFFSET_FLOAT_SCALE * n instead.
#define OFFSET_ORIGIN (1.0f / 32.0f)
#define OFFSET_FLOAT_SCALE (1.0f / 65536.0f)
#define OFFSET_INT_SCALE 256.0f
TANDEM_INLINE float offset_component(float p, float n) {
    const int32 of = (int32)(OFFSET_INT_SCALE * n);
    const float moved = as_float(as_int(p) + (p < 0.0f ? -of : of));
    return fabs(p) < OFFSET_ORIGIN ? p + OFFSET_FLOAT_SCALE * n : moved;
}
TANDEM_INLINE float3 offset_ray_origin(float3 p, float3 n) {
#if TANDEM_DEVICE
    // offset_component on the three lanes at once: the same operations lane by lane (convert_int3
    // truncates as the cast does), so the same bits. Written per component, PoCL compiled three
    // copies with a branch each. (The wavefront's scalar stage calls offset_component itself.)
    const int3 of = convert_int3(OFFSET_INT_SCALE * n);
    const int3 moved = as_int3(p) + select(of, -of, isless(p, (float3)(0.0f)));
    return select(as_float3(moved), p + OFFSET_FLOAT_SCALE * n,
                  isless(fabs(p), (float3)(OFFSET_ORIGIN)));
#else
    return make_float3(offset_component(p.x, n.x), offset_component(p.y, n.y),
                       offset_component(p.z, n.z));
#endif
}

/// Orthonormal basis (s, t, n) around unit n: Duff et al., "Building an Orthonormal Basis,
/// Revisited", JCGT 6(1), 2017.
typedef struct Frame {
    float3 s, t, n;
} Frame;

/// The tangents s and t of the frame around unit normal (nx, ny, nz), into s[0..3) and t[0..3): the
/// one definition, which frame_from_normal and the wavefront's shading stage (scalars) both use.
TANDEM_INLINE void frame_tangents(float nx, float ny, float nz, float* s, float* t) {
    const float sign = nz >= 0.0f ? 1.0f : -1.0f;
    const float a = -1.0f / (sign + nz);
    const float b = nx * ny * a;
    s[0] = 1.0f + sign * nx * nx * a;
    s[1] = sign * b;
    s[2] = -sign * nx;
    t[0] = b;
    t[1] = sign + ny * ny * a;
    t[2] = -ny;
}

TANDEM_INLINE Frame frame_from_normal(float3 n) {
    float s[3], t[3];
    frame_tangents(n.x, n.y, n.z, s, t);
    Frame f;
    f.s = make_float3(s[0], s[1], s[2]);
    f.t = make_float3(t[0], t[1], t[2]);
    f.n = n;
    return f;
}
TANDEM_INLINE float3 frame_to_local(Frame f, float3 v) {
    return make_float3(vdot(v, f.s), vdot(v, f.t), vdot(v, f.n));
}
/// Component c of the world direction whose local coordinates in a frame are v[0..3): s[c], t[c]
/// and n[c] are that component of the frame's axes.
TANDEM_INLINE float frame_world_component(float s, float t, float n, const float* v) {
    return s * v[0] + t * v[1] + n * v[2];
}
TANDEM_INLINE float3 frame_to_world(Frame f, float3 v) {
    const float l[3] = {v.x, v.y, v.z};
    return make_float3(frame_world_component(f.s.x, f.t.x, f.n.x, l),
                       frame_world_component(f.s.y, f.t.y, f.n.y, l),
                       frame_world_component(f.s.z, f.t.z, f.n.z, l));
}

/// Concentric map of [0,1)^2 to the unit disk (Shirley and Chiu 1997), into (*x, *y). The angle is
/// (pi/4) y/x in the wedges about the x axis and pi/2 - (pi/4) x/y in those about the y axis, whose
/// sine and cosine are the cosine and sine of (pi/4) x/y. Written with selects and no early exit,
/// so that a loop over paths that inlines it stays one block (the wavefront's shading stage is
/// vectorised by PoCL's loop vectoriser); the untaken sides may compute 0/0, which no select keeps.
TANDEM_INLINE void concentric_disk(float u1, float u2, float* x, float* y) {
    const float dx = 2.0f * u1 - 1.0f, dy = 2.0f * u2 - 1.0f;
    const int wide = fabs(dx) > fabs(dy);
    const float r = wide ? dx : dy;
    float s, c;
    det_sincos_quarter_pi(wide ? dy / dx : dx / dy, &s, &c);
    const int origin = dx == 0.0f && dy == 0.0f;
    *x = origin ? 0.0f : r * (wide ? c : s);
    *y = origin ? 0.0f : r * (wide ? s : c);
}
TANDEM_INLINE float3 sample_concentric_disk(float u1, float u2) {
    float x, y;
    concentric_disk(u1, u2, &x, &y);
    return make_float3(x, y, 0.0f);
}

/// Cosine-weighted direction about +z in the local frame, into w[0..3); pdf = cos(theta) / pi.
TANDEM_INLINE void cosine_hemisphere(float u1, float u2, float* w) {
    concentric_disk(u1, u2, &w[0], &w[1]);
    w[2] = sqrt(fmax(0.0f, 1.0f - w[0] * w[0] - w[1] * w[1]));
}
TANDEM_INLINE float3 sample_cosine_hemisphere(float u1, float u2) {
    float w[3];
    cosine_hemisphere(u1, u2, w);
    return make_float3(w[0], w[1], w[2]);
}
/// Density of cosine_hemisphere for a direction whose local z is wz.
TANDEM_INLINE float cosine_hemisphere_pdf(float wz) { return fmax(wz, 0.0f) * TANDEM_INV_PI; }
TANDEM_INLINE float pdf_cosine_hemisphere(float3 w) { return cosine_hemisphere_pdf(w.z); }

/// Uniform direction on the unit sphere, into w[0..3); pdf = 1 / (4 pi).
TANDEM_INLINE void uniform_sphere(float u1, float u2, float* w) {
    const float z = 1.0f - 2.0f * u1;
    const float r = sqrt(fmax(0.0f, 1.0f - z * z));
    float s, c;
    det_sincos(2.0f * TANDEM_PI * u2, &s, &c);
    w[0] = r * c;
    w[1] = r * s;
    w[2] = z;
}
TANDEM_INLINE float3 sample_uniform_sphere(float u1, float u2) {
    float w[3];
    uniform_sphere(u1, u2, w);
    return make_float3(w[0], w[1], w[2]);
}
#define PDF_UNIFORM_SPHERE (1.0f / (4.0f * TANDEM_PI))

/// Uniform barycentrics (b1, b2) on a triangle: the square-root parametrisation.
TANDEM_INLINE float3 sample_uniform_triangle(float u1, float u2) {
    const float su = sqrt(u1);
    return make_float3(1.0f - su, u2 * su, 0.0f); // weights of p0 and p1; p2 gets the rest
}

/// Power heuristic with exponent 2 (Veach 1997), for the strategy with density pdf_a. Written
/// with the ratio of the densities, so huge or infinite densities give 0 or 1, not inf / inf; and
/// with selects (the untaken ratio may be 0/0 or inf, which no select keeps), so that it
/// vectorises where the wavefront inlines it.
TANDEM_INLINE float mis_power(float pdf_a, float pdf_b) {
    const float r = pdf_a > pdf_b ? pdf_b / pdf_a : pdf_a / pdf_b;
    const float w = pdf_a > pdf_b ? 1.0f / (1.0f + r * r) : r * r / (1.0f + r * r);
    // pdf_a == pdf_b: also inf against inf
    return !(pdf_a > 0.0f) ? 0.0f : (pdf_a == pdf_b ? 0.5f : w);
}

TANDEM_NAMESPACE_END

#endif // TANDEM_SHARED_SAMPLING_H
