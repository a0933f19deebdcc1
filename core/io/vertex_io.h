// Per-vertex arrays on disk: a mesh with per-vertex values as PLY properties, and NumPy's .npy.
#pragma once

#include <string>
#include <vector>

#include <glm/vec3.hpp>

namespace tandem {

/// Writes the mesh (world-space `positions`, `triangles` as vertex index triples) to a binary
/// little-endian PLY at `path`, atomically, with three float properties per vertex named
/// `PREFIX_x`, `PREFIX_y`, `PREFIX_z` from `values` (3 per vertex): e.g. a gradient, as
/// grad_x grad_y grad_z; no values and an empty prefix: the mesh alone. Throws Error naming the
/// file on failure.
void write_vertex_ply(const std::string& path, const std::vector<glm::vec3>& positions,
                      const std::vector<unsigned>& triangles, const std::vector<float>& values,
                      const std::string& prefix);

/// Writes `values` as a float32 NumPy array of shape (rows, cols) to `path` (.npy, format 1.0),
/// atomically. Throws Error naming the file on failure.
void write_npy(const std::string& path, const std::vector<float>& values, std::size_t rows,
               std::size_t cols);

} // namespace tandem
