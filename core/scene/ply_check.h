// A structural check of PLY files before Assimp reads them. Assimp 5.2's PLY importer reads past
// its buffer (SIGSEGV), loops forever or aborts on headers it does not understand and on bodies
// shorter than the header says (found by fuzz/fuzz_mesh.cpp); the check turns every such file into
// a one-line error first.
#pragma once

#include <cstddef>
#include <string>

namespace tandem {

/// Where a checked PLY file's body starts (the byte after the end_header line), and its format.
struct PlyBody {
    std::size_t offset = 0;
    bool binary = false;
};

/// Checks `data`, the contents of the PLY file `path`: a header of the PLY specification (the
/// line "ply", a format line "format ascii|binary_little_endian|binary_big_endian 1.0", comment
/// and obj_info lines, "element NAME COUNT", "property TYPE NAME", "property list COUNT_TYPE
/// TYPE NAME" after an element, and "end_header"), then a body that holds every element the
/// header declares: numbers in ASCII, enough bytes in binary, with list counts that are
/// non-negative integers, and not 0 in a face. Throws Error "PATH: cannot load mesh: ..." naming the header line or
/// the element that is wrong.
PlyBody check_ply(const std::string& path, const std::string& data);

/// Assimp 5.2's PLY reader skips a 0x0A byte that follows an end_header line ended by a bare
/// line feed, so binary data that begins with that byte (the low byte of a little-endian first
/// value, 1 file in 256) is read one byte late: every value shifts, and a face list can come out
/// empty, on which its triangulation aborts. After "end_header\r\n" it reads the same data right.
/// Returns `data` with that line ending where the file needs it, else "" (read the file as it is).
std::string ply_for_assimp(const std::string& data, const PlyBody& body);

} // namespace tandem
