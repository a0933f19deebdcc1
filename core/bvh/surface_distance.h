// Distances between two triangle surfaces, for measuring a recovered shape against the true one:
// the Chamfer and Hausdorff distances over points spread evenly on each surface, each point's
// distance to the other surface exact (Embree's point query over the triangles, the closest point
// of each triangle computed in double).
#pragma once

#include <cstddef>
#include <vector>

#include <glm/vec3.hpp>

#include "core/bvh/embree_device.h"
#include "core/scene/mesh.h"

namespace tandem {

/// `count` points on the triangles of `mesh`, spread in proportion to area: point i at the
/// (i + 1/2) / count quantile of the cumulative area, placed within its triangle by the R2
/// low-discrepancy sequence (uniform in area). The same points on every run. Throws Error for a
/// mesh of zero area.
std::vector<glm::dvec3> surface_samples(const TriangleMesh& mesh, std::size_t count);

/// The distance from each point to the nearest point of the surface of `mesh` (its triangles), in
/// double; Embree's search, from the point rounded to float, keeps every triangle that could be
/// nearer than the best so far.
std::vector<double> distances_to_surface(const EmbreeDevice& device, const TriangleMesh& mesh,
                                         const std::vector<glm::dvec3>& points);

struct SurfaceDistance {
    double chamfer = 0;   ///< (mean over a of d(a, B) + mean over b of d(b, A)) / 2
    double hausdorff = 0; ///< the larger of max over a of d(a, B) and max over b of d(b, A)
};

/// The Chamfer and Hausdorff distances between the surfaces of `a` and `b`, over `samples`
/// points of each (surface_samples; Error for 0), in the meshes' units.
SurfaceDistance surface_distance(const EmbreeDevice& device, const TriangleMesh& a,
                                 const TriangleMesh& b, std::size_t samples = 100000);

} // namespace tandem
