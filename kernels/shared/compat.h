// Host/device compatibility layer: lets every header in kernels/shared compile both as C++17 (host)
// and as OpenCL C 1.2 (device). Shared structs use only the types defined here.
#ifndef TANDEM_SHARED_COMPAT_H
#define TANDEM_SHARED_COMPAT_H

#ifdef __OPENCL_C_VERSION__
// ---- Device: OpenCL C already has uint, ulong, float4, as_uint, ... ----
#define TANDEM_DEVICE 1
#define TANDEM_NAMESPACE_BEGIN
#define TANDEM_NAMESPACE_END
// `static inline`: a plain C99 `inline` emits no body, so a compiler that declines to inline
// (at -O0, say) would fail to link. Clang-based compilers (PoCL, ROCm, Intel) are also told to
// inline always: PoCL otherwise keeps the traversal helpers as calls, and the hit record they
// update then lives in memory.
//
// A function whose struct result ends up in memory writes it through a pointer argument instead of
// returning it (the traversal's Hit, the Interaction, the AlbedoSource). Clang returns a struct
// through a hidden `noalias` (sret) pointer, and LLVM's inliner (12 and later) marks the accesses
// of the inlined body through it with calls to the no-op intrinsic
// llvm.experimental.noalias.scope.decl. Optimisation drops them where the result ends up in
// registers, but they stay where it is stored into memory that outlives the call: a result handed
// on as the caller's own return value, or a local whose address is passed on. Oclgrind 21.10
// (Debian 12) cannot run that intrinsic and refuses to create the kernel. The `oclgrind` ctest label
// creates and runs every kernel under it.
#if defined(__clang__)
#define TANDEM_INLINE static inline __attribute__((always_inline))
#else
#define TANDEM_INLINE static inline
#endif
#define TANDEM_STATIC_ASSERT_SIZE(T, n)
// A Clang-based compiler that generates x86 code with AVX (PoCL on CPUs): there x86 built-ins
// stand in for portable forms that compile to many instructions (movmskps: BVH_MOVEMASK; roundss:
// det_floor), the eight-wide traversal can ask for cache lines ahead (__builtin_prefetch:
// BVH_PREFETCH), and a path vertex hashes its eight random numbers at once (PATH_RNG_LANES,
// path/random.h). Every other compiler (GPUs; Oclgrind, which cannot run the built-ins) takes the
// portable forms; all give the same bits.
#if defined(__clang__) && defined(__AVX__) && defined(__x86_64__)
#define TANDEM_X86_CLANG 1
#else
#define TANDEM_X86_CLANG 0
#endif
#define TANDEM_GLOBAL __global
#define TANDEM_CONSTANT __constant
typedef int int32;

#else
// ---- Host: C++17 definitions of the OpenCL C scalar and vector types used in shared code ----
#include <cmath>
#include <cstdint>
#include <cstring>

#define TANDEM_DEVICE 0
#define TANDEM_NAMESPACE_BEGIN namespace tandem::gpu {
#define TANDEM_NAMESPACE_END }
#define TANDEM_INLINE inline
#define TANDEM_X86_CLANG 0
#define TANDEM_STATIC_ASSERT_SIZE(T, n)                                                            \
    static_assert(sizeof(T) == (n), "shared struct " #T " must be " #n " bytes on every compiler")
#define TANDEM_GLOBAL
#define TANDEM_CONSTANT

TANDEM_NAMESPACE_BEGIN

typedef std::uint32_t uint;
typedef std::int32_t int32;
typedef std::uint64_t ulong;

/// 16-byte vector with the layout of OpenCL's float4 (float3 is avoided in shared structs).
struct alignas(16) float4 {
    float x, y, z, w;
};
static_assert(sizeof(float4) == 16, "float4 must be 16 bytes");
/// float3 for private arithmetic only (never in shared structs, where OpenCL pads it to 16 bytes).
struct float3 {
    float x, y, z;
};
inline float3 operator+(float3 a, float3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline float3 operator-(float3 a, float3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline float3 operator*(float3 a, float3 b) { return {a.x * b.x, a.y * b.y, a.z * b.z}; }
inline float3 operator*(float3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline float3 operator*(float s, float3 a) { return {a.x * s, a.y * s, a.z * s}; }
inline float3 operator/(float3 a, float s) { return {a.x / s, a.y / s, a.z / s}; }
inline float3 operator-(float3 a) { return {-a.x, -a.y, -a.z}; }
inline float3& operator+=(float3& a, float3 b) { return a = a + b; }
inline float3& operator*=(float3& a, float3 b) { return a = a * b; }
inline float3& operator*=(float3& a, float s) { return a = a * s; }
struct alignas(16) uint4 {
    uint x, y, z, w;
};
struct alignas(8) uint2 {
    uint x, y;
};
struct alignas(16) int4 {
    int32 x, y, z, w;
};

inline uint as_uint(float f) {
    uint u;
    std::memcpy(&u, &f, sizeof u);
    return u;
}
inline int32 as_int(float f) {
    int32 i;
    std::memcpy(&i, &f, sizeof i);
    return i;
}
inline float as_float(int32 i) {
    float f;
    std::memcpy(&f, &i, sizeof f);
    return f;
}
inline float as_float(uint u) {
    float f;
    std::memcpy(&f, &u, sizeof f);
    return f;
}
inline float4 make_float4(float x, float y, float z, float w) { return float4{x, y, z, w}; }

// Single-precision overloads of the OpenCL math built-ins, so unqualified calls inside shared code
// never silently promote to double on the host.
inline float fabs(float x) { return std::fabs(x); }
inline float fmin(float a, float b) { return std::fmin(a, b); }
inline float fmax(float a, float b) { return std::fmax(a, b); }
inline float sqrt(float x) { return std::sqrt(x); }
/// a * b + c rounded once: OpenCL's fma, which every implementation must round correctly.
inline float fma(float a, float b, float c) { return std::fma(a, b, c); }
inline int isfinite(float x) { return std::isfinite(x) ? 1 : 0; }
inline float floor(float x) { return std::floor(x); }
inline uint min(uint a, uint b) { return a < b ? a : b; }

// The float4 arithmetic and relational built-ins shared code uses, with OpenCL's semantics:
// comparisons give -1 (true) or 0 per component, select(a, b, c) takes b where c's sign bit is set.
inline float4 operator+(float4 a, float4 b) { return {a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w}; }
inline float4 operator-(float4 a, float4 b) { return {a.x - b.x, a.y - b.y, a.z - b.z, a.w - b.w}; }
inline float4 operator*(float4 a, float4 b) { return {a.x * b.x, a.y * b.y, a.z * b.z, a.w * b.w}; }
inline float4 operator*(float4 a, float b) { return {a.x * b, a.y * b, a.z * b, a.w * b}; }
inline float4 operator/(float4 a, float4 b) {
    return {a.x / b.x, a.y / b.y, a.z / b.z, a.w / b.w};
}
inline float4 operator-(float4 a) {
    return {-a.x, -a.y, -a.z, -a.w};
}
inline int4 operator|(int4 a, int4 b) {
    return {a.x | b.x, a.y | b.y, a.z | b.z, a.w | b.w};
}
inline int4 operator&(int4 a, int4 b) {
    return {a.x & b.x, a.y & b.y, a.z & b.z, a.w & b.w};
}
inline int4 operator~(int4 a) {
    return {~a.x, ~a.y, ~a.z, ~a.w};
}
inline int4 isnotequal(float4 a, float4 b) {
    return {a.x != b.x ? -1 : 0, a.y != b.y ? -1 : 0, a.z != b.z ? -1 : 0, a.w != b.w ? -1 : 0};
}
inline int4 isless(float4 a, float4 b) {
    return {a.x < b.x ? -1 : 0, a.y < b.y ? -1 : 0, a.z < b.z ? -1 : 0, a.w < b.w ? -1 : 0};
}
inline int4 islessequal(float4 a, float4 b) {
    return {a.x <= b.x ? -1 : 0, a.y <= b.y ? -1 : 0, a.z <= b.z ? -1 : 0, a.w <= b.w ? -1 : 0};
}
inline float4 select(float4 a, float4 b, int4 c) {
    return {c.x < 0 ? b.x : a.x, c.y < 0 ? b.y : a.y, c.z < 0 ? b.z : a.z, c.w < 0 ? b.w : a.w};
}

/// float8 and int8 with OpenCL's component names and the built-ins the eight-wide BVH traversal
/// uses (kernels/shared/bvh8_traverse.h), lane by lane with the same semantics as float4's.
struct float8 {
    float s0, s1, s2, s3, s4, s5, s6, s7;
};
struct int8 {
    int32 s0, s1, s2, s3, s4, s5, s6, s7;
};
template <class V, class F> inline V lanes8(F f) {
    V v;
    for (int k = 0; k < 8; ++k)
        (&v.s0)[k] = f(k);
    return v;
}
inline float8 vload8(std::size_t offset, const float* p) {
    return lanes8<float8>([&](int k) { return p[8 * offset + k]; });
}
inline void vstore8(float8 v, std::size_t offset, float* p) {
    for (int k = 0; k < 8; ++k)
        p[8 * offset + k] = (&v.s0)[k];
}
inline float8 operator-(float8 a, float8 b) {
    return lanes8<float8>([&](int k) { return (&a.s0)[k] - (&b.s0)[k]; });
}
inline float8 operator*(float8 a, float b) {
    return lanes8<float8>([&](int k) { return (&a.s0)[k] * b; });
}
inline int8 operator&(int8 a, int8 b) {
    return lanes8<int8>([&](int k) { return (&a.s0)[k] & (&b.s0)[k]; });
}
inline int8 isless(float8 a, float8 b) {
    return lanes8<int8>([&](int k) { return (&a.s0)[k] < (&b.s0)[k] ? -1 : 0; });
}
inline int8 islessequal(float8 a, float8 b) {
    return lanes8<int8>([&](int k) { return (&a.s0)[k] <= (&b.s0)[k] ? -1 : 0; });
}
inline int8 isnotequal(float8 a, float8 b) {
    return lanes8<int8>([&](int k) { return (&a.s0)[k] != (&b.s0)[k] ? -1 : 0; });
}
inline float8 select(float8 a, float8 b, int8 c) {
    return lanes8<float8>([&](int k) { return (&c.s0)[k] < 0 ? (&b.s0)[k] : (&a.s0)[k]; });
}
inline float8 splat_float8(float x) {
    return float8{x, x, x, x, x, x, x, x};
}
/// uint8 with the lane-wise integer operations of the eight-lane hash (shared/rng.h).
struct uint8 {
    uint s0, s1, s2, s3, s4, s5, s6, s7;
};
inline uint8 operator+(uint8 a, uint8 b) {
    return lanes8<uint8>([&](int k) { return (&a.s0)[k] + (&b.s0)[k]; });
}
inline uint8 operator*(uint8 a, uint8 b) {
    return lanes8<uint8>([&](int k) { return (&a.s0)[k] * (&b.s0)[k]; });
}
inline uint8 operator^(uint8 a, uint8 b) {
    return lanes8<uint8>([&](int k) { return (&a.s0)[k] ^ (&b.s0)[k]; });
}
inline uint8 operator>>(uint8 a, uint b) {
    return lanes8<uint8>([&](int k) { return (&a.s0)[k] >> b; });
}
inline uint8 splat_uint8(uint x) {
    return uint8{x, x, x, x, x, x, x, x};
}
inline uint8 make_uint8(uint a, uint b, uint c, uint d, uint e, uint f, uint g, uint h) {
    return uint8{a, b, c, d, e, f, g, h};
}
inline float8 convert_float8(uint8 a) {
    return lanes8<float8>([&](int k) { return static_cast<float>((&a.s0)[k]); });
}
/// OpenCL's clz: the number of leading zero bits (32 for zero).
inline uint clz(uint x) {
    return x == 0u ? 32u : static_cast<uint>(__builtin_clz(x));
}

TANDEM_NAMESPACE_END
#endif

#ifdef __OPENCL_C_VERSION__
#define make_float4(x, y, z, w) ((float4)((x), (y), (z), (w)))
#define make_float3(x, y, z) ((float3)((x), (y), (z)))
#define splat_float4(x) ((float4)(x))
#define splat_float8(x) ((float8)(x))
#define splat_uint8(x) ((uint8)(x))
#define make_uint8(a, b, c, d, e, f, g, h) ((uint8)((a), (b), (c), (d), (e), (f), (g), (h)))
#else
TANDEM_NAMESPACE_BEGIN
inline float4 splat_float4(float x) { return float4{x, x, x, x}; }
inline float3 make_float3(float x, float y, float z) { return float3{x, y, z}; }
TANDEM_NAMESPACE_END
#endif

#endif // TANDEM_SHARED_COMPAT_H
