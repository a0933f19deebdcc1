// Plain binary records in a byte string (checkpoints): values appended as their bytes, and read
// back with a bounds check that names the file.
#pragma once

#include <cstring>
#include <string>
#include <string_view>

#include "runtime/error.h"

namespace tandem {

/// Appends the bytes of v (trivially copyable) to out.
template <class T> void put_bytes(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

/// Appends a string as its length (u32) and bytes.
inline void put_string(std::string& out, const std::string& s) {
    put_bytes<std::uint32_t>(out, std::uint32_t(s.size()));
    out += s;
}

/// Reads a T at data[pos] and advances pos. Throws Error "WHERE: truncated" when fewer than
/// sizeof(T) bytes are left (`where` names the file, and the section of it).
template <class T> T take_bytes(std::string_view data, std::size_t& pos, const std::string& where) {
    if (pos > data.size() || sizeof(T) > data.size() - pos) throw Error(where + ": truncated");
    T v;
    std::memcpy(&v, data.data() + pos, sizeof(T));
    pos += sizeof(T);
    return v;
}

/// Reads what put_string() wrote.
inline std::string take_string(std::string_view data, std::size_t& pos, const std::string& where) {
    const auto n = take_bytes<std::uint32_t>(data, pos, where);
    if (n > data.size() - pos) throw Error(where + ": truncated");
    std::string s(data.substr(pos, n));
    pos += n;
    return s;
}

} // namespace tandem
