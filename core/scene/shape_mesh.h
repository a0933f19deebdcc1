// Triangle meshes for the shapes of a scene: Mitsuba's built-in shapes tessellated, mesh files
// loaded, all moved to world space.
#pragma once

#include "core/scene/mesh.h"
#include "core/scene/scene.h"

namespace tandem {

/// The shape's triangles in world space, wound so that (p1 - p0) x (p2 - p0) is the normal Mitsuba
/// would use (after flip_normals and mirroring transforms). rectangle: [-1,1]^2 in z = 0, normal
/// +z; cube: [-1,1]^3, outward; disk: the unit disk in z = 0, normal +z, 64 segments; sphere:
/// 64 x 32 latitude-longitude, outward. Shading normals (core/scene/vertex_normals.h): an obj's or
/// ply's own or derived ones (none with face_normals), a sphere's exact ones. Throws Error naming the scene file and line on failure.
TriangleMesh shape_mesh(const Shape& shape, const std::string& scene_path);

} // namespace tandem
