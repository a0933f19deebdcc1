// Tessellation of Mitsuba's built-in shapes, and world-space transformation of every shape.
#include "core/scene/shape_mesh.h"

#include <cmath>

#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/scene/vertex_normals.h"
#include "runtime/error.h"

namespace tandem {

namespace {

constexpr float k_pi = 3.14159265358979323846f;

TriangleMesh rectangle() {
    TriangleMesh m;
    m.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
    m.uvs = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    m.triangles = {{0, 1, 2}, {0, 2, 3}};
    return m;
}

TriangleMesh cube() {
    TriangleMesh m;
    // Each face: a corner and two edge directions whose cross product points outward.
    const glm::vec3 faces[6][3] = {
        {{1, -1, -1}, {0, 2, 0}, {0, 0, 2}},   {{-1, -1, -1}, {0, 0, 2}, {0, 2, 0}},
        {{-1, 1, -1}, {0, 0, 2}, {2, 0, 0}},   {{-1, -1, -1}, {2, 0, 0}, {0, 0, 2}},
        {{-1, -1, 1}, {2, 0, 0}, {0, 2, 0}},   {{-1, -1, -1}, {0, 2, 0}, {2, 0, 0}},
    };
    for (const auto& f : faces) {
        const auto base = static_cast<unsigned>(m.positions.size());
        m.positions.push_back(f[0]);
        m.positions.push_back(f[0] + f[1]);
        m.positions.push_back(f[0] + f[1] + f[2]);
        m.positions.push_back(f[0] + f[2]);
        m.uvs.insert(m.uvs.end(), {{0, 0}, {1, 0}, {1, 1}, {0, 1}});
        m.triangles.emplace_back(base, base + 1, base + 2);
        m.triangles.emplace_back(base, base + 2, base + 3);
    }
    return m;
}

TriangleMesh disk(int segments = 64) {
    // uv = (radius, angle / 2 pi), as Mitsuba's disk: each wedge has its own centre vertex (at its
    // mid angle) and the seam is duplicated (v = 0 and v = 1), so uvs interpolate correctly.
    TriangleMesh m;
    for (int i = 0; i <= segments; ++i) {
        const float a = 2.0f * k_pi * static_cast<float>(i) / static_cast<float>(segments);
        m.positions.emplace_back(std::cos(a), std::sin(a), 0.0f);
        m.uvs.emplace_back(1.0f, static_cast<float>(i) / static_cast<float>(segments));
    }
    for (int i = 0; i < segments; ++i) {
        const auto centre = static_cast<unsigned>(m.positions.size());
        m.positions.emplace_back(0.0f, 0.0f, 0.0f);
        m.uvs.emplace_back(0.0f, (static_cast<float>(i) + 0.5f) / static_cast<float>(segments));
        m.triangles.emplace_back(centre, static_cast<unsigned>(i), static_cast<unsigned>(i + 1));
    }
    return m;
}

TriangleMesh sphere(const glm::vec3& center, float radius, int slices = 64, int stacks = 32) {
    TriangleMesh m;
    for (int j = 0; j <= stacks; ++j) {
        const float theta = k_pi * static_cast<float>(j) / static_cast<float>(stacks);
        for (int i = 0; i <= slices; ++i) { // column `slices` repeats column 0 with u = 1
            const float phi = 2.0f * k_pi * static_cast<float>(i % slices) / static_cast<float>(slices);
            const glm::vec3 d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                              std::cos(theta));
            m.positions.push_back(center + radius * d);
            m.normals.push_back(d); // the sphere's own, as Mitsuba's analytic sphere shades
            m.uvs.emplace_back(static_cast<float>(i) / static_cast<float>(slices),
                               theta / k_pi); // Mitsuba's sphere uv
        }
    }
    auto at = [&](int i, int j) { return static_cast<unsigned>(j * (slices + 1) + i); };
    for (int j = 0; j < stacks; ++j)
        for (int i = 0; i < slices; ++i) {
            // outward: theta grows downward from the +z pole, phi counter-clockwise
            if (j > 0) m.triangles.emplace_back(at(i, j), at(i, j + 1), at(i + 1, j));
            if (j + 1 < stacks) m.triangles.emplace_back(at(i + 1, j), at(i, j + 1), at(i + 1, j + 1));
        }
    return m;
}

} // namespace

TriangleMesh shape_mesh(const Shape& shape, const std::string& scene_path) {
    TriangleMesh m;
    switch (shape.type) {
    case ShapeType::obj:
    case ShapeType::ply:
        try {
            m = load_mesh(shape.filename);
        } catch (const Error& e) { // the mesh's message names the file; add the scene's line
            throw Error(scene_path + ":" + std::to_string(shape.line) + ": " + e.what());
        }
        break;
    case ShapeType::rectangle: m = rectangle(); break;
    case ShapeType::cube: m = cube(); break;
    case ShapeType::disk: m = disk(); break;
    case ShapeType::sphere: m = sphere(shape.center, shape.radius); break;
    }
    m.source = scene_path + ":" + std::to_string(shape.line) +
               (shape.filename.empty() ? "" : " (" + shape.filename + ")");
    for (glm::vec3& p : m.positions) p = glm::vec3(shape.to_world * glm::vec4(p, 1.0f));
    // A mirroring transform reverses the winding; flip_normals reverses it once more.
    const bool mirrored = glm::determinant(glm::mat3(shape.to_world)) < 0.0f;
    if (mirrored != shape.flip_normals)
        for (glm::uvec3& t : m.triangles) std::swap(t.y, t.z);
    validate_mesh(m);
    // Shading normals (vertex_normals.h): the file's or the sphere's, moved as normals are (by
    // to_world's inverse transpose, which agrees with the winding above), else derived.
    const bool file_mesh = shape.type == ShapeType::obj || shape.type == ShapeType::ply;
    if (shape.face_normals || (!file_mesh && shape.type != ShapeType::sphere)) {
        m.normals.clear();
    } else if (!m.normals.empty()) {
        const glm::mat3 normal_matrix = glm::transpose(glm::inverse(glm::mat3(shape.to_world)));
        const float sign = shape.flip_normals ? -1.0f : 1.0f;
        for (glm::vec3& n : m.normals) n = sign * glm::normalize(normal_matrix * n);
    } else {
        for (const glm::dvec3& n : derived_normals(m.positions, m.triangles))
            m.normals.emplace_back(n);
        m.normals_derived = true;
    }
    return m;
}

} // namespace tandem
