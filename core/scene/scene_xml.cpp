// Mitsuba 3 XML, first pass: pugixml document -> xml::Node tree, with line numbers, <default>
// variables and $name substitution, typed property values and composed transforms.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <pugixml.hpp>

#include "core/scene/scene.h"
#include "runtime/error.h"

namespace tandem {

glm::mat4 look_at(const glm::vec3& origin, const glm::vec3& target, const glm::vec3& up) {
    const glm::vec3 dir = glm::normalize(target - origin);
    const glm::vec3 left = glm::normalize(glm::cross(up, dir));
    const glm::vec3 new_up = glm::cross(dir, left);
    glm::mat4 m(1.0f); // glm is column-major: m[c] is column c
    m[0] = glm::vec4(left, 0.f);
    m[1] = glm::vec4(new_up, 0.f);
    m[2] = glm::vec4(dir, 0.f);
    m[3] = glm::vec4(origin, 1.f);
    return m;
}

namespace xml {
namespace {

const char* const k_object_tags[] = {"integrator", "sensor",  "film",    "sampler",
                                     "rfilter",    "shape",   "bsdf",    "texture",
                                     "emitter",    "medium",  "phase",   "volume"};
const std::map<std::string, PropKind> k_property_tags = {{"float", PropKind::float_},
                                                         {"integer", PropKind::integer},
                                                         {"boolean", PropKind::boolean},
                                                         {"string", PropKind::string},
                                                         {"rgb", PropKind::rgb},
                                                         {"spectrum", PropKind::spectrum},
                                                         {"point", PropKind::point},
                                                         {"vector", PropKind::vector},
                                                         {"transform", PropKind::transform}};

bool is_object_tag(const std::string& tag) {
    return std::find(std::begin(k_object_tags), std::end(k_object_tags), tag) !=
           std::end(k_object_tags);
}

/// Mitsuba's coordinate_system(n).first (Duff et al. 2017): the `up` of a lookat without one.
glm::vec3 any_perpendicular(const glm::vec3& n) {
    const float sign = std::copysign(1.f, n.z);
    const float a = -1.f / (sign + n.z);
    return {1.f + sign * n.x * n.x * a, sign * n.x * n.y * a, -sign * n.x};
}

bool is_name_char(char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || c == '_';
}

class Parser {
public:
    Parser(std::string path, const std::vector<std::pair<std::string, std::string>>& defines)
        : m_path(std::move(path)) {
        for (const auto& [name, value] : defines) {
            m_vars[name] = value;
            m_defines.push_back(name);
        }
    }

    Node parse() {
        std::ifstream in(m_path, std::ios::binary);
        if (!in) throw Error(m_path + ": scene file not found or unreadable");
        std::stringstream ss;
        ss << in.rdbuf();
        m_text = ss.str();
        for (std::size_t i = 0; i < m_text.size(); ++i)
            if (m_text[i] == '\n') m_newlines.push_back(i);

        pugi::xml_document doc;
        const pugi::xml_parse_result r =
            doc.load_buffer(m_text.data(), m_text.size(), pugi::parse_default, pugi::encoding_utf8);
        if (!r) fail(line_at(r.offset), std::string("malformed XML: ") + r.description());
        const pugi::xml_node root = doc.document_element();
        if (std::string(root.name()) != "scene")
            fail(line_of(root),
                 "the root tag must be <scene>, not <" + std::string(root.name()) + ">");
        Node scene = parse_scene(root);
        check_defines();
        return scene;
    }

private:
    // ---- locations and errors ----
    int line_at(std::ptrdiff_t offset) const {
        return 1 + static_cast<int>(std::lower_bound(m_newlines.begin(), m_newlines.end(),
                                                     static_cast<std::size_t>(offset)) -
                                    m_newlines.begin());
    }
    int line_of(const pugi::xml_node& n) const { return line_at(n.offset_debug()); }
    [[noreturn]] void fail(int line, const std::string& what) const {
        throw Error(m_path + ":" + std::to_string(line) + ": " + what);
    }
    /// A define (-D name=value) must name a variable of the scene, one that a <default> declares
    /// or an attribute uses as $name, so that a misspelt name is an error, not silently ignored.
    void check_defines() const {
        std::set<std::string> known = m_defaults;
        known.insert(m_used.begin(), m_used.end());
        for (const std::string& name : m_defines) {
            if (known.count(name)) continue;
            std::string list;
            for (const std::string& k : known)
                list += (list.empty() ? "" : ", ") + k;
            throw Error(m_path + ": define '" + name + "' names no variable of the scene (" +
                        (list.empty() ? "it has none" : "it has: " + list) + ")");
        }
    }
    static std::string tag_of(const pugi::xml_node& e) {
        std::string s = "<" + std::string(e.name());
        for (const char* a : {"type", "name", "id"})
            if (const pugi::xml_attribute at = e.attribute(a))
                s += " " + std::string(a) + "=\"" + at.value() + "\"";
        return s + ">";
    }

    // ---- attributes, with $variable substitution ----
    void check_attributes(const pugi::xml_node& e, std::initializer_list<const char*> allowed) {
        for (const pugi::xml_attribute a : e.attributes()) {
            const bool ok = std::any_of(allowed.begin(), allowed.end(),
                                        [&](const char* n) { return std::string(n) == a.name(); });
            if (!ok) fail(line_of(e), tag_of(e) + ": unexpected attribute '" + a.name() + "'");
        }
    }
    std::string substitute(const pugi::xml_node& e, const pugi::xml_attribute& a) const {
        const std::string in = a.value();
        std::string out;
        for (std::size_t i = 0; i < in.size(); ++i) {
            if (in[i] != '$') {
                out += in[i];
                continue;
            }
            std::size_t j = i + 1;
            while (j < in.size() && is_name_char(in[j]))
                ++j;
            const std::string name = in.substr(i + 1, j - i - 1);
            m_used.insert(name);
            const auto it = m_vars.find(name);
            if (it == m_vars.end())
                fail(line_of(e), tag_of(e) + ": attribute '" + a.name() + "' uses undefined $" +
                                     name + (name.empty() ? " (a '$' without a name)" : ""));
            out += it->second;
            i = j - 1;
        }
        return out;
    }
    bool has(const pugi::xml_node& e, const char* name) const { return bool(e.attribute(name)); }
    std::string attr(const pugi::xml_node& e, const char* name) {
        const pugi::xml_attribute a = e.attribute(name);
        if (!a) fail(line_of(e), tag_of(e) + ": missing attribute '" + name + "'");
        return substitute(e, a);
    }
    std::string attr_or(const pugi::xml_node& e, const char* name, const std::string& def) {
        const pugi::xml_attribute a = e.attribute(name);
        return a ? substitute(e, a) : def;
    }

    // ---- numbers ----
    [[noreturn]] void bad_number(const pugi::xml_node& e, const char* attr_name,
                                 const std::string& s, const std::string& expected) const {
        fail(line_of(e), tag_of(e) + ": attribute '" + attr_name + "' must be " + expected +
                             ", got '" + s + "'");
    }
    float to_float(const pugi::xml_node& e, const char* attr_name, const std::string& s) const {
        const char* begin = s.c_str();
        char* end = nullptr;
        errno = 0;
        const float v = std::strtof(begin, &end);
        while (end && std::isspace(static_cast<unsigned char>(*end)))
            ++end;
        if (end == begin || *end != '\0' || errno == ERANGE || std::isnan(v))
            bad_number(e, attr_name, s, "a number");
        return v;
    }
    std::vector<float> to_floats(const pugi::xml_node& e, const char* attr_name,
                                 const std::string& s) const {
        std::string t = s;
        std::replace(t.begin(), t.end(), ',', ' ');
        std::istringstream ss(t);
        std::vector<float> out;
        for (std::string tok; ss >> tok;)
            out.push_back(to_float(e, attr_name, tok));
        return out;
    }
    glm::vec3 to_vec3(const pugi::xml_node& e, const char* attr_name, const std::string& s,
                      bool allow_single) const {
        const std::vector<float> v = to_floats(e, attr_name, s);
        if (v.size() == 3) return {v[0], v[1], v[2]};
        if (v.size() == 1 && allow_single) return glm::vec3(v[0]);
        bad_number(e, attr_name, s, allow_single ? "1 or 3 numbers" : "3 numbers");
    }
    /// `value="x, y, z"` (named) or separate x= y= z= attributes defaulting to `def`.
    glm::vec3 named_vector(const pugi::xml_node& e, const char* named, float def,
                           bool allow_single = false) {
        if (has(e, named)) {
            for (const char* c : {"x", "y", "z"})
                if (has(e, c))
                    fail(line_of(e), tag_of(e) + ": give either '" + named + "' or x/y/z");
            return to_vec3(e, named, attr(e, named), allow_single);
        }
        glm::vec3 v(def);
        const char* axes[] = {"x", "y", "z"};
        for (int k = 0; k < 3; ++k)
            if (has(e, axes[k])) v[k] = to_float(e, axes[k], attr(e, axes[k]));
        return v;
    }

    // ---- tags ----
    Node parse_scene(const pugi::xml_node& root) {
        check_attributes(root, {"version"});
        const std::string version = attr(root, "version");
        if (version.rfind("2.", 0) != 0 && version.rfind("3.", 0) != 0)
            fail(line_of(root), "<scene>: unsupported version '" + version + "' (need 2.x or 3.x)");
        Node n;
        n.tag = "scene";
        n.line = line_of(root);
        for (const pugi::xml_node c : root.children()) {
            if (c.type() == pugi::node_element && std::string(c.name()) == "default") {
                check_attributes(c, {"name", "value"});
                const std::string name = attr(c, "name"), value = attr(c, "value");
                if (name.empty() || !std::all_of(name.begin(), name.end(), is_name_char))
                    fail(line_of(c), tag_of(c) + ": invalid variable name '" + name + "'");
                if (!m_defaults.insert(name).second)
                    fail(line_of(c), tag_of(c) + ": variable '" + name + "' declared twice");
                m_vars.emplace(name, value); // a -D define wins over the default
                continue;
            }
            parse_child(c, n);
        }
        return n;
    }

    void parse_child(const pugi::xml_node& c, Node& parent) {
        if (c.type() == pugi::node_pcdata || c.type() == pugi::node_cdata)
            fail(line_of(c), "unexpected text inside <" + parent.tag + ">");
        if (c.type() != pugi::node_element) return; // comments, declarations
        const std::string tag = c.name();
        if (is_object_tag(tag)) {
            parent.children.push_back(parse_object(c));
        } else if (tag == "ref") {
            check_attributes(c, {"id", "name"});
            Node r;
            r.tag = "ref";
            r.line = line_of(c);
            r.id = attr(c, "id");
            r.name = attr_or(c, "name", "");
            parent.children.push_back(r);
        } else if (k_property_tags.count(tag)) {
            Property p = parse_property(c, k_property_tags.at(tag));
            for (const Property& q : parent.props)
                if (q.name == p.name)
                    fail(p.line, tag_of(c) + ": property '" + p.name + "' given twice (line " +
                                     std::to_string(q.line) + ")");
            parent.props.push_back(std::move(p));
        } else if (tag == "default") {
            fail(line_of(c), "<default> is only allowed directly inside <scene>");
        } else {
            fail(line_of(c), "unknown tag <" + tag + "> inside <" + parent.tag + ">");
        }
    }

    Node parse_object(const pugi::xml_node& e) {
        // Objects nest a few levels in any scene (shape > bsdf > texture); a bound keeps a
        // hostile file from exhausting the stack of this recursion and of Node's destructor.
        if (m_depth == k_max_depth)
            fail(line_of(e), tag_of(e) + ": objects nested more than " +
                                 std::to_string(k_max_depth) + " levels deep");
        ++m_depth;
        check_attributes(e, {"type", "id", "name"});
        Node n;
        n.tag = e.name();
        n.line = line_of(e);
        n.type = attr(e, "type");
        n.id = attr_or(e, "id", "");
        n.name = attr_or(e, "name", "");
        for (const pugi::xml_node c : e.children())
            parse_child(c, n);
        --m_depth;
        return n;
    }

    Property parse_property(const pugi::xml_node& e, PropKind kind) {
        Property p;
        p.kind = kind;
        p.line = line_of(e);
        if (kind != PropKind::transform)
            for (const pugi::xml_node c : e.children())
                if (c.type() == pugi::node_element || c.type() == pugi::node_pcdata)
                    fail(line_of(c), tag_of(e) + " cannot have content");
        if (kind == PropKind::point || kind == PropKind::vector) {
            check_attributes(e, {"name", "value", "x", "y", "z"});
            p.name = attr(e, "name");
            p.v = named_vector(e, "value", 0.f);
            return p;
        }
        if (kind == PropKind::transform) {
            check_attributes(e, {"name"});
            p.name = attr(e, "name");
            p.m = parse_transform(e);
            return p;
        }
        check_attributes(e, {"name", "value"});
        p.name = attr(e, "name");
        const std::string value = attr(e, "value");
        switch (kind) {
        case PropKind::float_:
            p.f = to_float(e, "value", value);
            break;
        case PropKind::integer: {
            const char* begin = value.c_str();
            char* end = nullptr;
            errno = 0;
            const long v = std::strtol(begin, &end, 10);
            if (end == begin || *end != '\0' || errno == ERANGE || v < INT32_MIN || v > INT32_MAX)
                bad_number(e, "value", value, "an integer");
            p.i = static_cast<int>(v);
            break;
        }
        case PropKind::boolean: {
            std::string low = value;
            for (char& ch : low)
                ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
            if (low != "true" && low != "false") bad_number(e, "value", value, "true or false");
            p.b = low == "true";
            break;
        }
        case PropKind::string:
            p.s = value;
            break;
        case PropKind::rgb:
            p.v = to_vec3(e, "value", value, true);
            break;
        case PropKind::spectrum: {
            const char* what = "a single number (only grey spectra are supported)";
            if (value.find(':') != std::string::npos) bad_number(e, "value", value, what);
            const std::vector<float> v = to_floats(e, "value", value);
            if (v.size() != 1) bad_number(e, "value", value, what);
            p.f = v[0];
            p.v = glm::vec3(v[0]);
            break;
        }
        default:
            break;
        }
        return p;
    }

    glm::mat4 parse_transform(const pugi::xml_node& t) {
        glm::mat4 m(1.0f);
        for (const pugi::xml_node e : t.children()) {
            if (e.type() == pugi::node_pcdata) fail(line_of(e), "unexpected text in <transform>");
            if (e.type() != pugi::node_element) continue;
            const std::string tag = e.name();
            glm::mat4 step(1.0f);
            if (tag == "translate") {
                check_attributes(e, {"x", "y", "z", "value"});
                step = glm::translate(glm::mat4(1.0f), named_vector(e, "value", 0.f));
            } else if (tag == "scale") {
                check_attributes(e, {"x", "y", "z", "value"});
                step = glm::scale(glm::mat4(1.0f), named_vector(e, "value", 1.f, true));
            } else if (tag == "rotate") {
                check_attributes(e, {"x", "y", "z", "value", "axis", "angle"});
                if (has(e, "value") && has(e, "axis"))
                    fail(line_of(e), "<rotate>: give either 'value' or 'axis'");
                const glm::vec3 axis = named_vector(e, has(e, "axis") ? "axis" : "value", 0.f);
                const float angle = to_float(e, "angle", attr(e, "angle"));
                if (glm::length(axis) == 0.f) fail(line_of(e), "<rotate>: the axis is zero");
                step = glm::rotate(glm::mat4(1.0f), glm::radians(angle), glm::normalize(axis));
            } else if (tag == "matrix") {
                check_attributes(e, {"value"});
                const std::string s = attr(e, "value");
                const std::vector<float> v = to_floats(e, "value", s);
                if (v.size() != 16 && v.size() != 9) bad_number(e, "value", s, "16 or 9 numbers");
                const int n = v.size() == 16 ? 4 : 3; // 3x3: the linear part of a 4x4
                for (int r = 0; r < n; ++r)
                    for (int c = 0; c < n; ++c)
                        step[c][r] = v[r * n + c];
            } else if (tag == "lookat") {
                check_attributes(e, {"origin", "target", "up"});
                const glm::vec3 o = to_vec3(e, "origin", attr(e, "origin"), false);
                const glm::vec3 tg = to_vec3(e, "target", attr(e, "target"), false);
                if (o == tg) fail(line_of(e), "<lookat>: origin and target are the same point");
                const glm::vec3 up = has(e, "up") ? to_vec3(e, "up", attr(e, "up"), false)
                                                  : any_perpendicular(glm::normalize(tg - o));
                if (glm::length(glm::cross(up, tg - o)) == 0.f)
                    fail(line_of(e), "<lookat>: 'up' is parallel to the view direction");
                step = look_at(o, tg, up);
            } else {
                fail(line_of(e), "unknown tag <" + tag + "> inside <transform>");
            }
            m = step * m;
        }
        return m;
    }

    static constexpr int k_max_depth = 64;
    int m_depth = 0; ///< objects open around the one being parsed

    std::string m_path, m_text;
    std::vector<std::size_t> m_newlines;
    std::map<std::string, std::string> m_vars;
    std::set<std::string> m_defaults;
    std::vector<std::string> m_defines;   ///< the names of the defines, in order
    mutable std::set<std::string> m_used; ///< the $names attributes use
};

} // namespace

Node parse_file(const std::string& path,
                const std::vector<std::pair<std::string, std::string>>& defines) {
    return Parser(path, defines).parse();
}

} // namespace xml
} // namespace tandem
