// A structural check of PLY files before Assimp reads them. Assimp 5.2's PLY importer reads past
// its buffer (SIGSEGV), loops forever or aborts on headers it does not understand and on bodies
// shorter than the header says (found by fuzz/fuzz_mesh.cpp); the check turns every such file into
// a one-line error first.
#pragma once

#include <string>

namespace tandem {

/// Checks `data`, the contents of the PLY file `path`: a header of the PLY specification (the
/// line "ply", a format line "format ascii|binary_little_endian|binary_big_endian 1.0", comment
/// and obj_info lines, "element NAME COUNT", "property TYPE NAME", "property list COUNT_TYPE
/// TYPE NAME" after an element, and "end_header"), then a body that holds every element the
/// header declares: numbers in ASCII, enough bytes in binary, with list counts that are
/// non-negative integers, and not 0 in a face. Throws Error "PATH: cannot load mesh: ..." naming the header line or
/// the element that is wrong.
void check_ply(const std::string& path, const std::string& data);

} // namespace tandem
