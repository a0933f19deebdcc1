// Files of named, checksummed sections (checkpoints): damage anywhere in them (a flipped bit, a
// truncation, a zeroed block) is found and named before any of their content is used.
//
//   file    := magic (8 bytes) index section*
//   index   := a section named "index" whose payload is the count (u32) and names of the
//              sections after it
//   section := name length (u32), name, payload length (u64), payload,
//              XXH3-64 (core/io/digest.h) of the bytes before it in the section
//
// The index, checked first, names the sections even when one of them is damaged, and tells a
// truncation at a section boundary from a whole file.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "runtime/error.h"

namespace tandem {

/// A file whose bytes are not what was written: a section failing its checksum, a truncation,
/// bytes after the end. Callers that can fall back to an older copy catch it; its what() names
/// the file and the section.
class DamagedFile : public Error {
public:
    using Error::Error;
};

/// Collects sections, then lays out the file's bytes.
class SectionWriter {
public:
    /// Appends a section. Names are unique and not "index".
    void add(std::string name, std::string payload);
    /// magic, the index, then the sections in the order they were added.
    std::string bytes(const char (&magic)[8]) const;

private:
    std::vector<std::pair<std::string, std::string>> m_sections;
};

/// Verifies every section of a file's bytes, then hands out their payloads.
class SectionReader {
public:
    /// `data`: the whole file at `path` (for messages), past its 8-byte magic, which the caller
    /// checks. Throws DamagedFile "PATH: section K of N ('NAME') is damaged (checksum mismatch)",
    /// "PATH: truncated in section ...", "PATH: truncated after section ..." or "PATH: ... bytes
    /// after its last section".
    SectionReader(std::string path, std::string data);

    const std::vector<std::string>& names() const { return m_names; }
    bool has(const std::string& name) const;
    /// The payload of section `name`; throws Error naming the file if there is none.
    std::string_view payload(const std::string& name) const;
    /// "PATH, section 'NAME'": where a payload's own reader reports what it finds wrong.
    std::string where(const std::string& name) const;

private:
    std::string m_path, m_data;
    std::vector<std::string> m_names;
    std::vector<std::string_view> m_payloads;
};

} // namespace tandem
