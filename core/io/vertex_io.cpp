// Per-vertex arrays on disk. Written here, not through a library: Assimp's PLY exporter has no
// per-vertex properties of the caller's, and Debian packages no C++ writer of NumPy's .npy; both
// formats are a text header and little-endian records (the PLY specification; NumPy's
// "NEP 1: A simple file format for NumPy arrays").
#include "core/io/vertex_io.h"

#include <cstring>

#include "core/io/atomic_file.h"
#include "runtime/error.h"

namespace tandem {

namespace {

template <class T> void append(std::string& out, T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    out.append(b, sizeof(T)); // little-endian hosts only (x86, ARM): the formats' order
}

} // namespace

void write_vertex_ply(const std::string& path, const std::vector<glm::vec3>& positions,
                      const std::vector<unsigned>& triangles, const std::vector<float>& values,
                      const std::string& prefix) {
    if (values.empty() != prefix.empty())
        throw Error(path + ": vertex properties need both values and a name prefix");
    if (!values.empty() && values.size() != 3 * positions.size())
        throw Error(path + ": " + std::to_string(values.size()) + " values for " +
                    std::to_string(positions.size()) + " vertices");
    std::string out = "ply\nformat binary_little_endian 1.0\ncomment written by tandem\n";
    out += "element vertex " + std::to_string(positions.size()) + "\n";
    out += "property float x\nproperty float y\nproperty float z\n";
    if (!values.empty())
        for (const char* c : {"x", "y", "z"}) out += "property float " + prefix + "_" + c + "\n";
    out += "element face " + std::to_string(triangles.size() / 3) + "\n";
    out += "property list uchar uint vertex_indices\nend_header\n";
    for (std::size_t i = 0; i < positions.size(); ++i) {
        append(out, positions[i].x);
        append(out, positions[i].y);
        append(out, positions[i].z);
        if (!values.empty())
            for (int c = 0; c < 3; ++c) append(out, values[3 * i + c]);
    }
    for (std::size_t t = 0; t + 2 < triangles.size(); t += 3) {
        append(out, static_cast<unsigned char>(3));
        for (int c = 0; c < 3; ++c) append(out, static_cast<std::uint32_t>(triangles[t + c]));
    }
    write_file_atomic(path, out);
}

void write_npy(const std::string& path, const std::vector<float>& values, std::size_t rows,
               std::size_t cols) {
    if (values.size() != rows * cols)
        throw Error(path + ": " + std::to_string(values.size()) + " values for shape (" +
                    std::to_string(rows) + ", " + std::to_string(cols) + ")");
    std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" +
                         std::to_string(rows) + ", " + std::to_string(cols) + "), }";
    // magic, version 1.0, header length; the header padded with spaces to a multiple of 64
    const std::size_t unpadded = 10 + header.size() + 1;
    header.append((64 - unpadded % 64) % 64, ' ');
    header += '\n';
    std::string out = "\x93NUMPY";
    out += '\x01';
    out += '\x00';
    append(out, static_cast<std::uint16_t>(header.size()));
    out += header;
    for (float v : values) append(out, v);
    write_file_atomic(path, out);
}

} // namespace tandem
