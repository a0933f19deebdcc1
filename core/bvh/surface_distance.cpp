// Surface distances (core/bvh/surface_distance.h).
#include "core/bvh/surface_distance.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include <glm/geometric.hpp>

#include "runtime/error.h"

namespace tandem {

namespace {

glm::dvec3 vertex(const TriangleMesh& mesh, std::size_t t, int k) {
    return glm::dvec3(mesh.positions[mesh.triangles[t][k]]);
}

/// The point of triangle abc closest to p ("Real-Time Collision Detection", Ericson 2005,
/// Sec. 5.1.5: the Voronoi regions of the vertices, then the edges, then the face).
glm::dvec3 closest_on_triangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                               const glm::dvec3& c) {
    const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return a;
    const glm::dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + d1 / (d1 - d3) * ab;
    const glm::dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + d2 / (d2 - d6) * ac;
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0)
        return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
    const double denom = va + vb + vc;
    if (!(denom > 0.0)) return a; // a degenerate triangle: its vertices' region covers it
    return a + ab * (vb / denom) + ac * (vc / denom);
}

struct Query {
    const TriangleMesh* mesh;
    glm::dvec3 p;
    double best;  ///< the squared distance so far
    double slack; ///< |p - the float point Embree queries from|
};

bool closest_primitive(RTCPointQueryFunctionArguments* args) {
    Query& q = *static_cast<Query*>(args->userPtr);
    const std::size_t t = args->primID;
    const glm::dvec3 c = closest_on_triangle(q.p, vertex(*q.mesh, t, 0), vertex(*q.mesh, t, 1),
                                             vertex(*q.mesh, t, 2));
    const double d2 = glm::dot(c - q.p, c - q.p);
    if (!(d2 < q.best)) return false;
    q.best = d2;
    // shrink the search, by as much as Embree's float query point can differ from p: a triangle
    // nearer to p than the best so far is never culled
    args->query->radius = std::nextafter(float(std::sqrt(d2) + q.slack), INFINITY);
    return true;
}

} // namespace

std::vector<glm::dvec3> surface_samples(const TriangleMesh& mesh, std::size_t count) {
    std::vector<double> cdf(mesh.triangles.size());
    double total = 0.0;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const glm::dvec3 a = vertex(mesh, t, 0);
        total += 0.5 * glm::length(glm::cross(vertex(mesh, t, 1) - a, vertex(mesh, t, 2) - a));
        cdf[t] = total;
    }
    if (!(total > 0.0) || !std::isfinite(total))
        throw Error(mesh.source + ": the surface has no area to sample");
    std::vector<glm::dvec3> out(count);
    // R2 ("The Unreasonable Effectiveness of Quasirandom Sequences", Roberts 2018): 1/g, 1/g^2
    const double g = 1.32471795724474602596, a1 = 1.0 / g, a2 = 1.0 / (g * g);
    for (std::size_t i = 0; i < count; ++i) {
        const double at = (double(i) + 0.5) / double(count) * total;
        const std::size_t t = std::min<std::size_t>(
            std::lower_bound(cdf.begin(), cdf.end(), at) - cdf.begin(), cdf.size() - 1);
        double u1 = 0.5 + a1 * double(i + 1), u2 = 0.5 + a2 * double(i + 1);
        u1 -= std::floor(u1), u2 -= std::floor(u2);
        const double s = std::sqrt(u1); // uniform in the triangle's area
        out[i] = (1.0 - s) * vertex(mesh, t, 0) + s * (1.0 - u2) * vertex(mesh, t, 1) +
                 s * u2 * vertex(mesh, t, 2);
    }
    return out;
}

std::vector<double> distances_to_surface(const EmbreeDevice& device, const TriangleMesh& mesh,
                                         const std::vector<glm::dvec3>& points) {
    std::unique_ptr<RTCSceneTy, void (*)(RTCScene)> scene(rtcNewScene(device.get()), rtcReleaseScene);
    std::unique_ptr<RTCGeometryTy, void (*)(RTCGeometry)> geom(
        rtcNewGeometry(device.get(), RTC_GEOMETRY_TYPE_TRIANGLE), rtcReleaseGeometry);
    device.check("rtcNewScene");
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
        geom.get(), RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.positions.size()));
    auto* f = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        geom.get(), RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh.triangles.size()));
    device.check("rtcSetNewGeometryBuffer");
    for (std::size_t i = 0; i < mesh.positions.size(); ++i)
        for (int k = 0; k < 3; ++k) v[3 * i + std::size_t(k)] = mesh.positions[i][k];
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) f[3 * t + std::size_t(k)] = mesh.triangles[t][k];
    rtcCommitGeometry(geom.get());
    rtcAttachGeometry(scene.get(), geom.get());
    rtcCommitScene(scene.get());
    device.check(("Embree scene for " + mesh.source).c_str());
    std::vector<double> out(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        RTCPointQuery query{};
        query.x = float(points[i].x), query.y = float(points[i].y), query.z = float(points[i].z);
        const glm::dvec3 held(query.x, query.y, query.z);
        Query q{&mesh, points[i], INFINITY, glm::length(points[i] - held)};
        query.radius = INFINITY;
        RTCPointQueryContext context;
        rtcInitPointQueryContext(&context);
        rtcPointQuery(scene.get(), &query, &context, closest_primitive, &q);
        out[i] = std::sqrt(q.best);
    }
    device.check("rtcPointQuery");
    return out;
}

SurfaceDistance surface_distance(const EmbreeDevice& device, const TriangleMesh& a,
                                 const TriangleMesh& b, std::size_t samples) {
    if (samples == 0) throw Error("surface distance: at least one sample per surface");
    SurfaceDistance d;
    for (const auto& [from, to] : {std::pair{&a, &b}, std::pair{&b, &a}}) {
        const std::vector<double> r = distances_to_surface(device, *to, surface_samples(*from, samples));
        double sum = 0.0;
        for (double x : r) sum += x, d.hausdorff = std::max(d.hausdorff, x);
        d.chamfer += 0.5 * sum / double(r.size());
    }
    return d;
}

} // namespace tandem
