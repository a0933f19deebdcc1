// Shading normals of triangle meshes. As Mitsuba 3: a mesh file's vertex normals are used where it
// has them; a mesh without them gets normals derived from its vertices, each vertex the average of
// its triangles' unit normals weighted by the triangle's interior angle at it ("Computing Vertex
// Normals from Polygonal Facets", Thuermer and Wuethrich, JGT 3(1), 1998); `face_normals` keeps
// the triangles' own. Vertices at the same position share their derived normal (Mitsuba's normal
// groups), so that a file whose corners are not shared (Assimp reads OBJ corners apart) is smooth.
// Derived normals follow the vertices when they move, and the shape gradients count their
// derivatives (normal_jacobian; kernels/path/shape_adjoint.h).
#pragma once

#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

namespace tandem {

/// The derived unit normal of every vertex of the triangles (indices into positions), in double
/// precision. Triangles of zero area add nothing; a vertex that no triangle with an area touches
/// gets (1, 0, 0), as in Mitsuba.
std::vector<glm::dvec3> derived_normals(const std::vector<glm::vec3>& positions,
                                        const std::vector<glm::uvec3>& triangles);

/// The derivatives of derived_normals with respect to the positions: for vertex k, the blocks
/// [first[k], first[k + 1]) of (vertex[b], jacobian[b] = dN_k / dP_vertex[b]), one per vertex of
/// the triangles around k's position, in the order the triangles first name them.
struct NormalJacobian {
    std::vector<unsigned> first;
    std::vector<unsigned> vertex;
    std::vector<glm::dmat3> jacobian; ///< glm's column-major: jacobian[b][c] = d N / d P.c
};
NormalJacobian normal_jacobian(const std::vector<glm::vec3>& positions,
                               const std::vector<glm::uvec3>& triangles);

} // namespace tandem
