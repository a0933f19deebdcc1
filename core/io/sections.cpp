// Files of named, checksummed sections.
#include "core/io/sections.h"

#include <algorithm>

#include "core/io/binary.h"
#include "core/io/digest.h"

namespace tandem {

namespace {

constexpr const char* k_index = "index";

void put_section(std::string& out, const std::string& name, const std::string& payload) {
    const std::size_t start = out.size();
    put_string(out, name);
    put_bytes<std::uint64_t>(out, payload.size());
    out += payload;
    put_bytes<std::uint64_t>(out, digest(out.data() + start, out.size() - start));
}

/// A section's name for messages: the index's (trusted once the index is verified), else what the
/// file holds if it is printable.
std::string quoted(const std::string& name) {
    const bool printable =
        !name.empty() && name.size() <= 64 &&
        std::all_of(name.begin(), name.end(), [](char c) { return c >= 0x20 && c < 0x7f; });
    return printable ? " ('" + name + "')" : "";
}

} // namespace

void SectionWriter::add(std::string name, std::string payload) {
    if (name == k_index) throw Error("a section may not be named 'index'");
    for (const auto& s : m_sections)
        if (s.first == name) throw Error("two sections named '" + name + "'");
    m_sections.emplace_back(std::move(name), std::move(payload));
}

std::string SectionWriter::bytes(const char (&magic)[8]) const {
    std::string index;
    put_bytes<std::uint32_t>(index, std::uint32_t(m_sections.size()));
    for (const auto& s : m_sections)
        put_string(index, s.first);
    std::string out(magic, sizeof(magic));
    put_section(out, k_index, index);
    for (const auto& [name, payload] : m_sections)
        put_section(out, name, payload);
    return out;
}

SectionReader::SectionReader(std::string path, std::string data)
    : m_path(std::move(path)), m_data(std::move(data)) {
    const std::string_view all(m_data);
    std::size_t pos = 8;
    std::size_t expected = 1; // the index, then what it lists
    std::vector<std::string> listed;
    for (std::size_t k = 0; k < expected; ++k) {
        const std::string known = k == 0 ? std::string(k_index) : listed[k - 1];
        const std::string label = k == 0 ? std::string("its index (section 0)")
                                         : "section " + std::to_string(k) + " of " +
                                               std::to_string(expected - 1) + quoted(known);
        const auto damaged = [&](const std::string& what) {
            return DamagedFile(m_path + ": " + label + " " + what);
        };
        if (pos == all.size() && k == 0) throw DamagedFile(m_path + ": no sections (truncated)");
        if (pos == all.size())
            throw DamagedFile(m_path + ": truncated after section " + std::to_string(k - 1) +
                              " of " + std::to_string(expected - 1) + " (" +
                              std::to_string(expected - k) + " more expected)");
        const std::size_t start = pos;
        std::string name;
        std::uint64_t length = 0;
        try {
            name = take_string(all, pos, m_path);
            length = take_bytes<std::uint64_t>(all, pos, m_path);
        } catch (const Error&) {
            throw damaged("is truncated");
        }
        if (length > all.size() - pos || all.size() - pos - length < 8)
            // a damaged length, or a file cut short: the checksum cannot be found
            throw damaged(length > all.size() ? "is damaged or truncated (its length is past the "
                                                "file's end)"
                                              : "is truncated");
        const std::string_view payload = all.substr(pos, length);
        pos += length;
        const std::uint64_t stored = take_bytes<std::uint64_t>(all, pos, m_path);
        if (digest(all.data() + start, pos - 8 - start) != stored)
            throw damaged("is damaged (checksum mismatch)");
        if (name != known)
            throw damaged("is named '" + name + "' where the index says '" + known + "'");
        if (k == 0) {
            std::size_t at = 0;
            const std::string where = m_path + ", its index";
            const auto n = take_bytes<std::uint32_t>(payload, at, where);
            for (std::uint32_t i = 0; i < n; ++i)
                listed.push_back(take_string(payload, at, where));
            expected += n;
            continue;
        }
        m_names.push_back(name);
        m_payloads.push_back(payload);
    }
    if (pos != all.size())
        throw DamagedFile(m_path + ": " + std::to_string(all.size() - pos) +
                          " bytes after its last section (damaged)");
}

bool SectionReader::has(const std::string& name) const {
    return std::find(m_names.begin(), m_names.end(), name) != m_names.end();
}

std::string_view SectionReader::payload(const std::string& name) const {
    const auto it = std::find(m_names.begin(), m_names.end(), name);
    if (it == m_names.end()) throw Error(m_path + ": no section '" + name + "'");
    return m_payloads[std::size_t(it - m_names.begin())];
}

std::string SectionReader::where(const std::string& name) const {
    return m_path + ", section '" + name + "'";
}

} // namespace tandem
