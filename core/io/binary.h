// Plain binary records in a byte string (checkpoints): values appended as their bytes, and read
// back with a bounds check that names the file.
#pragma once

#include <cstring>
#include <string>

#include "runtime/error.h"

namespace tandem {

/// Appends the bytes of v (trivially copyable) to out.
template <class T> void put_bytes(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

/// Reads a T at data[pos] and advances pos. Throws Error "PATH: truncated checkpoint" when fewer
/// than sizeof(T) bytes are left.
template <class T> T take_bytes(const std::string& data, std::size_t& pos, const std::string& path) {
    if (sizeof(T) > data.size() - pos) throw Error(path + ": truncated checkpoint");
    T v;
    std::memcpy(&v, data.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
}

} // namespace tandem
