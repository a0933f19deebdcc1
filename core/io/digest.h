// Content digests: XXH3-64 (Debian's libxxhash) of bytes and of whole files. Checkpoints carry
// one per section to detect damage, and a run records one per input file to notice a change.
// Not cryptographic: they detect accidents (flipped bits, truncation, an edited file), not an
// adversary.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace tandem {

/// XXH3-64 of `size` bytes at `data` (seed 0).
std::uint64_t digest(const void* data, std::size_t size);
inline std::uint64_t digest(const std::string& bytes) {
    return digest(bytes.data(), bytes.size());
}

/// XXH3-64 of the whole file at `path`, read in blocks (a mesh or texture of any size). Equals
/// digest() of its contents. Throws Error naming the file when it cannot be read.
std::uint64_t digest_file(const std::string& path);

/// 16 lowercase hex digits.
std::string digest_hex(std::uint64_t d);

} // namespace tandem
