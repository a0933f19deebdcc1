// Mesh loading through Assimp, and validation.
#include "core/scene/mesh.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <glm/common.hpp>
#include <glm/exponential.hpp>
#include <glm/geometric.hpp>

#include "core/io/atomic_file.h"
#include "core/scene/ply_check.h"
#include "runtime/error.h"

namespace tandem {

namespace {

/// True if the file's first line is "ply" (Assimp detects PLY by this too).
bool starts_as_ply(const std::string& path) {
    char head[5] = {};
    std::ifstream(path, std::ios::binary).read(head, sizeof head);
    return std::memcmp(head, "ply\n", 4) == 0 || std::memcmp(head, "ply\r\n", 5) == 0;
}

} // namespace

Bounds TriangleMesh::bounds() const {
    Bounds b;
    for (const glm::uvec3& t : triangles)
        for (int k = 0; k < 3; ++k) b.extend(positions[t[k]]);
    for (const Sphere& s : spheres) {
        b.extend(s.center - glm::vec3(s.radius));
        b.extend(s.center + glm::vec3(s.radius));
    }
    for (const Disk& d : disks) {
        const glm::vec3 half = disk_half_extent(d);
        b.extend(d.center - half);
        b.extend(d.center + half);
    }
    return b;
}

std::vector<unsigned> weld_by_position(const glm::vec3* p, std::size_t n) {
    std::vector<unsigned> order(n), weld(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<unsigned>(i);
    const auto key = [&](unsigned i) { return std::array<float, 3>{p[i].x, p[i].y, p[i].z}; };
    std::stable_sort(order.begin(), order.end(),
                     [&](unsigned a, unsigned b) { return key(a) < key(b); });
    for (std::size_t k = 0; k < n; ++k)
        weld[order[k]] = k > 0 && key(order[k]) == key(order[k - 1]) ? weld[order[k - 1]] : order[k];
    return weld;
}

glm::vec3 disk_half_extent(const Disk& d) {
    return glm::sqrt(d.x_axis * d.x_axis + d.y_axis * d.y_axis);
}

void validate_mesh(const TriangleMesh& mesh) {
    if (mesh.primitive_count() == 0) throw Error(mesh.source + ": mesh has no triangles");
    auto finite = [](const glm::vec3& v) {
        return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
    };
    for (std::size_t i = 0; i < mesh.disks.size(); ++i) {
        const Disk& d = mesh.disks[i];
        if (!(finite(d.center) && finite(d.x_axis) && finite(d.y_axis) &&
              glm::dot(d.x_axis, d.x_axis) > 0.0f && glm::dot(d.y_axis, d.y_axis) > 0.0f))
            throw Error(mesh.source + ": disk " + std::to_string(i) +
                        " needs a finite centre and finite, non-zero axes");
    }
    for (std::size_t i = 0; i < mesh.spheres.size(); ++i) {
        const Sphere& s = mesh.spheres[i];
        if (!(std::isfinite(s.center.x) && std::isfinite(s.center.y) && std::isfinite(s.center.z) &&
              s.radius > 0.0f && std::isfinite(s.radius)))
            throw Error(mesh.source + ": sphere " + std::to_string(i) +
                        " needs a finite centre and a positive, finite radius");
    }
    const std::size_t n = mesh.positions.size();
    std::vector<char> used(n, 0);
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
        for (int k = 0; k < 3; ++k) {
            const unsigned idx = mesh.triangles[i][k];
            if (idx >= n)
                throw Error(mesh.source + ": triangle " + std::to_string(i) + " references vertex " +
                            std::to_string(idx) + " of " + std::to_string(n));
            used[idx] = 1;
        }
    for (std::size_t v = 0; v < n; ++v) {
        const glm::vec3& p = mesh.positions[v];
        if (used[v] && !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)))
            throw Error(mesh.source + ": vertex " + std::to_string(v) + " has a non-finite coordinate (" +
                        std::to_string(p.x) + ", " + std::to_string(p.y) + ", " +
                        std::to_string(p.z) + ")");
    }
}

TriangleMesh load_mesh(const std::string& path) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw Error(path + ": mesh file not found");
    if (std::filesystem::is_directory(path, ec)) throw Error(path + ": is a directory, not a mesh");
    if (std::filesystem::file_size(path, ec) == 0) throw Error(path + ": mesh file is empty");
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    // Assimp's PLY importer crashes or hangs on malformed headers and short bodies: check first
    // whatever Assimp would read as PLY (by its extension or its first line)
    std::string patched_ply; // the file as Assimp must read it, when that differs (ply_for_assimp)
    if (ext == ".ply" || starts_as_ply(path)) {
        const std::string data = read_file(path);
        patched_ply = ply_for_assimp(data, check_ply(path, data));
    }

    Assimp::Importer importer;
    // Keep the file's vertices and triangle order: no vertex joining, no degenerate removal, so
    // primitive ids match the input and degenerate triangles reach the BVH as they are.
    importer.SetPropertyInteger(AI_CONFIG_PP_SBP_REMOVE, aiPrimitiveType_POINT | aiPrimitiveType_LINE);
    // Two steps: read and validate, then triangulate. Assimp's triangulation asserts (and so
    // aborts the process) when a mesh says it holds polygons and none has more than three
    // vertices, as its PLY reader's empty faces did (ply_for_assimp; found by fuzz/fuzz_mesh.cpp).
    // In between, faces without indices are rejected and each mesh's primitive types are set
    // from its faces, so no reader's slip can reach that assertion.
    const aiScene* scene =
        patched_ply.empty()
            ? importer.ReadFile(path, aiProcess_ValidateDataStructure)
            : importer.ReadFileFromMemory(patched_ply.data(), patched_ply.size(),
                                          aiProcess_ValidateDataStructure, "ply");
    auto assimp_error = [&] {
        const std::string why = one_line(importer.GetErrorString());
        return Error(path + ": cannot load mesh: " + (why.empty() ? "unknown Assimp error" : why));
    };
    if (!scene) throw assimp_error();
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        // the importer owns the scene and its post-processing steps change it in place
        aiMesh* am = const_cast<aiMesh*>(scene->mMeshes[m]);
        unsigned types = 0;
        for (unsigned f = 0; f < am->mNumFaces; ++f) {
            const unsigned n = am->mFaces[f].mNumIndices;
            if (n == 0)
                throw Error(path + ": malformed mesh: face " + std::to_string(f) + " has no vertices");
            types |= n == 1 ? aiPrimitiveType_POINT
                            : (n == 2 ? aiPrimitiveType_LINE
                                      : (n == 3 ? aiPrimitiveType_TRIANGLE : aiPrimitiveType_POLYGON));
        }
        am->mPrimitiveTypes = types;
    }
    scene = importer.ApplyPostProcessing(aiProcess_Triangulate | aiProcess_SortByPType);
    if (!scene) throw assimp_error();
    TriangleMesh mesh;
    mesh.source = path;
    const bool flip_v = ext == ".obj";
    bool all_uvs = true, all_normals = true;
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* am = scene->mMeshes[m];
        if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        all_uvs = all_uvs && am->HasTextureCoords(0);
        all_normals = all_normals && am->HasNormals();
    }
    for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
        const aiMesh* am = scene->mMeshes[m];
        if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        const auto base = static_cast<unsigned>(mesh.positions.size());
        for (unsigned v = 0; v < am->mNumVertices; ++v) {
            mesh.positions.emplace_back(am->mVertices[v].x, am->mVertices[v].y, am->mVertices[v].z);
            if (all_uvs) {
                const aiVector3D& t = am->mTextureCoords[0][v];
                mesh.uvs.emplace_back(t.x, flip_v ? 1.0f - t.y : t.y);
            }
            if (all_normals) {
                const glm::vec3 n(am->mNormals[v].x, am->mNormals[v].y, am->mNormals[v].z);
                const float len = glm::length(n);
                if (!(len > 0.0f) || !std::isfinite(len))
                    throw Error(path + ": vertex " + std::to_string(mesh.positions.size() - 1) +
                                " has a zero or non-finite normal");
                mesh.normals.push_back(n / len);
            }
        }
        for (unsigned f = 0; f < am->mNumFaces; ++f) {
            const aiFace& face = am->mFaces[f];
            if (face.mNumIndices != 3) continue;
            mesh.triangles.emplace_back(base + face.mIndices[0], base + face.mIndices[1],
                                        base + face.mIndices[2]);
        }
    }
    validate_mesh(mesh);
    return mesh;
}

} // namespace tandem
