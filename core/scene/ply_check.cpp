// A structural check of PLY files before Assimp reads them.
#include "core/scene/ply_check.h"

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <vector>

#include "runtime/error.h"

namespace tandem {

namespace {

struct Property {
    int size = 0;       ///< bytes of a value (binary), 0 for none
    int count_size = 0; ///< a list: bytes of its count, else 0
    bool count_signed = false;
};

struct Element {
    std::string name;
    std::uint64_t count = 0;
    std::vector<Property> props;
    int line = 0;
};

/// Bytes of a PLY scalar type, 0 if `t` is none; `is_signed`, `is_int` describe it.
int type_size(const std::string& t, bool* is_int = nullptr, bool* is_signed = nullptr) {
    struct Type {
        const char* names[2];
        int size;
        bool integer, sign;
    };
    static const Type types[] = {
        {{"char", "int8"}, 1, true, true},       {{"uchar", "uint8"}, 1, true, false},
        {{"short", "int16"}, 2, true, true},     {{"ushort", "uint16"}, 2, true, false},
        {{"int", "int32"}, 4, true, true},       {{"uint", "uint32"}, 4, true, false},
        {{"float", "float32"}, 4, false, true}, {{"double", "float64"}, 8, false, true}};
    for (const Type& type : types)
        if (t == type.names[0] || t == type.names[1]) {
            if (is_int) *is_int = type.integer;
            if (is_signed) *is_signed = type.sign;
            return type.size;
        }
    return 0;
}

class Checker {
public:
    Checker(const std::string& path, const std::string& data) : m_path(path), m_data(data) {}

    /// Checks the file; returns the offset of the body and whether it is binary.
    PlyBody run() {
        header();
        const PlyBody body{m_pos, m_format != "ascii"};
        if (m_format == "ascii")
            ascii_body();
        else
            binary_body(m_format == "binary_big_endian");
        return body;
    }

private:
    [[noreturn]] void fail(const std::string& what) const {
        throw Error(m_path + ": cannot load mesh: " + what);
    }
    [[noreturn]] void fail_line(int line, const std::string& what) const {
        fail("PLY header line " + std::to_string(line) + ": " + what);
    }

    void header() {
        int line = 0;
        for (;;) {
            const std::size_t end = m_data.find('\n', m_pos);
            if (end == std::string::npos) fail("the PLY header has no end_header line");
            std::string text = m_data.substr(m_pos, end - m_pos);
            m_pos = end + 1;
            ++line;
            if (!text.empty() && text.back() == '\r') text.pop_back();
            std::istringstream in(text);
            std::vector<std::string> t;
            for (std::string s; in >> s;)
                t.push_back(s);
            if (line == 1) {
                if (text != "ply") fail("not a PLY file (the first line is not 'ply')");
                continue;
            }
            if (t.empty()) fail_line(line, "empty line");
            if (t[0] == "comment" || t[0] == "obj_info") continue;
            if (t[0] == "end_header" && t.size() == 1) break;
            if (t[0] == "format") {
                if (!m_format.empty()) fail_line(line, "a second format line");
                if (t.size() != 3 || t[2] != "1.0" ||
                    (t[1] != "ascii" && t[1] != "binary_little_endian" &&
                     t[1] != "binary_big_endian"))
                    fail_line(line, "unsupported format '" + text + "'");
                m_format = t[1];
            } else if (t[0] == "element") {
                if (m_format.empty()) fail_line(line, "an element before the format line");
                char* stop = nullptr;
                const unsigned long long n =
                    t.size() == 3 ? std::strtoull(t[2].c_str(), &stop, 10) : 0;
                if (t.size() != 3 || t[2][0] == '-' || *stop != '\0' || n > UINT32_MAX)
                    fail_line(line, "expected 'element NAME COUNT', got '" + text + "'");
                m_elements.push_back({t[1], n, {}, line});
            } else if (t[0] == "property") {
                if (m_elements.empty()) fail_line(line, "a property before any element");
                Property p;
                bool count_int = false;
                if (t.size() == 5 && t[1] == "list") {
                    p.count_size = type_size(t[2], &count_int, &p.count_signed);
                    p.size = type_size(t[3]);
                    if (!count_int || p.size == 0)
                        fail_line(line, "unknown list types in '" + text + "'");
                } else if (t.size() == 3 && t[1] != "list") {
                    p.size = type_size(t[1]);
                    if (p.size == 0) fail_line(line, "unknown type in '" + text + "'");
                } else {
                    fail_line(line, "expected 'property TYPE NAME' or 'property list COUNT_TYPE "
                                    "TYPE NAME', got '" + text + "'");
                }
                m_elements.back().props.push_back(p);
            } else {
                fail_line(line, "unexpected '" + text + "'");
            }
        }
        if (m_format.empty()) fail("the PLY header has no format line");
    }

    /// Assimp aborts (an assertion) on a face without vertices.
    static bool makes_faces(const Element& e) { return e.name == "face" || e.name == "tristrips"; }
    [[noreturn]] void empty_face(const Element& e, std::uint64_t i) const {
        fail("element '" + e.name + "' " + std::to_string(i) + " has an empty vertex list");
    }

    [[noreturn]] void short_body(const Element& e, std::uint64_t i) const {
        fail("the PLY data ends inside element '" + e.name + "' " + std::to_string(i) + " of " +
             std::to_string(e.count));
    }

    void binary_body(bool big_endian) {
        for (const Element& e : m_elements) {
            if (e.props.empty()) continue;
            bool fixed = true;
            std::uint64_t row = 0;
            for (const Property& p : e.props) {
                fixed = fixed && p.count_size == 0;
                row += std::uint64_t(p.size);
            }
            const std::uint64_t left = m_data.size() - m_pos;
            if (fixed) { // no lists: one size check
                if (e.count > left / row) short_body(e, left / row);
                m_pos += e.count * row;
                continue;
            }
            for (std::uint64_t i = 0; i < e.count; ++i) // each instance holds at least one byte
                for (const Property& p : e.props) {
                    std::uint64_t n = 1;
                    if (p.count_size != 0) {
                        if (std::uint64_t(p.count_size) > m_data.size() - m_pos) short_body(e, i);
                        n = read_count(p, big_endian);
                        if (n == 0 && makes_faces(e)) empty_face(e, i);
                        m_pos += p.count_size;
                    }
                    if (n > (m_data.size() - m_pos) / std::uint64_t(p.size)) short_body(e, i);
                    m_pos += n * p.size;
                }
        }
    }

    /// The list count at m_pos; fails on a negative one.
    std::uint64_t read_count(const Property& p, bool big_endian) const {
        unsigned char b[4] = {};
        std::memcpy(b, m_data.data() + m_pos, p.count_size);
        std::uint32_t u = 0;
        for (int k = 0; k < p.count_size; ++k)
            u |= std::uint32_t(b[big_endian ? p.count_size - 1 - k : k]) << (8 * k);
        if (p.count_signed && (u >> (8 * p.count_size - 1)) & 1u)
            fail("a negative list count in the PLY data");
        return u;
    }

    /// ASCII: one instance per line (blank lines skipped), each with at least the values the
    /// header declares, numbers, list counts non-negative integers.
    void ascii_body() {
        for (const Element& e : m_elements) {
            if (e.props.empty()) continue;
            for (std::uint64_t i = 0; i < e.count; ++i) {
                const char* p = next_line(e, i);
                for (const Property& prop : e.props) {
                    std::uint64_t n = 1;
                    if (prop.count_size != 0) {
                        if (*p == '\n' || *p == '\0')
                            fail("element '" + e.name + "' " + std::to_string(i) +
                                 ": fewer values than the header declares");
                        char* end = nullptr;
                        const long long c = std::strtoll(p, &end, 10);
                        if (end == p || !ends_token(end) || c < 0)
                            fail("element '" + e.name + "' " + std::to_string(i) +
                                 ": a list count must be a non-negative integer");
                        n = static_cast<std::uint64_t>(c);
                        if (n == 0 && makes_faces(e)) empty_face(e, i);
                        p = skip_blanks(end);
                    }
                    for (std::uint64_t k = 0; k < n; ++k) {
                        if (*p == '\n' || *p == '\0')
                            fail("element '" + e.name + "' " + std::to_string(i) +
                                 ": fewer values than the header declares");
                        char* end = nullptr;
                        std::strtod(p, &end);
                        if (end == p || !ends_token(end))
                            fail("element '" + e.name + "' " + std::to_string(i) +
                                 ": a value is not a number");
                        p = skip_blanks(end);
                    }
                }
            }
        }
    }

    static bool ends_token(const char* c) {
        return *c == ' ' || *c == '\t' || *c == '\r' || *c == '\n' || *c == '\0';
    }
    static const char* skip_blanks(const char* c) {
        while (*c == ' ' || *c == '\t' || *c == '\r')
            ++c;
        return c;
    }
    /// The first value of the next non-blank line, m_pos moved past that line.
    const char* next_line(const Element& e, std::uint64_t i) {
        for (;;) {
            if (m_pos >= m_data.size()) short_body(e, i);
            std::size_t end = m_data.find('\n', m_pos);
            if (end == std::string::npos) end = m_data.size();
            const char* first = skip_blanks(m_data.c_str() + m_pos);
            m_pos = end + 1;
            if (first != m_data.c_str() + end) return first;
        }
    }

    const std::string& m_path;
    const std::string& m_data;
    std::size_t m_pos = 0;
    std::string m_format;
    std::vector<Element> m_elements;
};

} // namespace

PlyBody check_ply(const std::string& path, const std::string& data) {
    return Checker(path, data).run();
}

std::string ply_for_assimp(const std::string& data, const PlyBody& body) {
    const std::size_t at = body.offset;
    const bool lf_only = at >= 1 && data[at - 1] == '\n' && !(at >= 2 && data[at - 2] == '\r');
    if (!body.binary || at >= data.size() || data[at] != '\n' || !lf_only) return {};
    return data.substr(0, at - 1) + "\r\n" + data.substr(at);
}

} // namespace tandem
