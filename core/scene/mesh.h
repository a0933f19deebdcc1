// Triangle meshes: loading OBJ and PLY (ASCII and binary) through Assimp, and validation.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace tandem {

struct Bounds {
    glm::vec3 lo{std::numeric_limits<float>::infinity()};
    glm::vec3 hi{-std::numeric_limits<float>::infinity()};
    void extend(const glm::vec3& p) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    glm::vec3 center() const { return 0.5f * (lo + hi); }
    glm::vec3 extent() const { return hi - lo; }
};

/// An analytic sphere, world space.
struct Sphere {
    glm::vec3 center{0.0f};
    float radius = 1.0f;
    float orientation = 1.0f; ///< +1: its front side faces outward; -1: inward (flip_normals)
    /// Rotation from world to the sphere's own axes, in which its texture coordinates are taken
    /// (a unit quaternion x, y, z, w; the identity by default).
    glm::vec4 to_local{0.0f, 0.0f, 0.0f, 1.0f};
};

/// An analytic disk, world space: centre + x x_axis + y y_axis for x^2 + y^2 <= 1, the axes
/// orthogonal and as long as its radius.
struct Disk {
    glm::vec3 center{0.0f};
    glm::vec3 x_axis{1.0f, 0.0f, 0.0f}, y_axis{0.0f, 1.0f, 0.0f};
    float orientation = 1.0f; ///< +1: its front side faces x_axis x y_axis; -1: the other
};

/// An indexed triangle mesh in world space, and the scene's analytic spheres and disks. Triangle
/// i of the input file keeps index i: it is the primitive id that traversal reports; sphere j
/// has primitive id triangles.size() + j, and disk k the id after every sphere's.
struct TriangleMesh {
    std::string source;                ///< file it was loaded from, for messages
    std::vector<glm::vec3> positions;  ///< world space
    std::vector<glm::uvec3> triangles; ///< indices into positions
    std::vector<glm::vec2> uvs;        ///< per vertex texture coordinates; empty if none
    /// per vertex unit shading normals (core/scene/vertex_normals.h); empty: the triangles are
    /// shaded with their own normals. In a merged mesh (RenderScene), zero for the vertices of
    /// shapes without.
    std::vector<glm::vec3> normals;
    /// whether `normals` were derived from the vertices (they follow them: vertex_normals.h)
    bool normals_derived = false;
    std::vector<Sphere> spheres;       ///< after the triangles in primitive order
    std::vector<Disk> disks;           ///< after the spheres

    std::size_t triangle_count() const { return triangles.size(); }
    std::size_t primitive_count() const { return triangles.size() + spheres.size() + disks.size(); }
    /// Bounds of the vertices that triangles reference (unreferenced vertices do not count), of
    /// the spheres and of the disks.
    Bounds bounds() const;
};

/// For each of the n vertices at p, the index of its first copy: the first vertex at the same
/// position (itself if none comes before). A cube's faces and a seam of texture coordinates split
/// one point of the surface into copies.
std::vector<unsigned> weld_by_position(const glm::vec3* p, std::size_t n);

/// The half extents of a disk's bounding box along the world axes.
glm::vec3 disk_half_extent(const Disk& d);

/// Loads every triangle of an OBJ or PLY file (other formats Assimp reads work too). Polygons are
/// triangulated; points and lines are dropped. Texture coordinates are kept when every part of
/// the file has them; OBJ's v is flipped (v = 1 - v), as Mitsuba does by default. Vertex normals
/// likewise (normalised; a zero or non-finite one throws, naming the vertex). Throws Error naming the file on a missing, unreadable,
/// corrupt or empty file, and on NaN or Inf coordinates (naming the vertex).
TriangleMesh load_mesh(const std::string& path);

/// Throws Error naming mesh.source if the mesh has no primitives, an index out of range, a
/// non-finite coordinate in a referenced vertex, a sphere whose centre is not finite or whose
/// radius is not positive and finite, or a disk with a non-finite value or a zero axis.
void validate_mesh(const TriangleMesh& mesh);

} // namespace tandem
