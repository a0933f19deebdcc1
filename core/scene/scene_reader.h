// Private to the scene loader (scene.cpp): typed, consuming access to the properties and children
// of one parsed XML object, so that whatever a plugin leaves unread is an error naming it.
#pragma once

#include <algorithm>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "core/scene/scene.h"
#include "runtime/error.h"

namespace tandem::scene_detail {

using xml::Node;
using xml::Property;
using xml::PropKind;

inline const char* kind_name(PropKind k) {
    switch (k) {
    case PropKind::float_:
        return "float";
    case PropKind::integer:
        return "integer";
    case PropKind::boolean:
        return "boolean";
    case PropKind::string:
        return "string";
    case PropKind::rgb:
        return "rgb";
    case PropKind::spectrum:
        return "spectrum";
    case PropKind::point:
        return "point";
    case PropKind::vector:
        return "vector";
    case PropKind::transform:
        return "transform";
    }
    return "?";
}

inline std::string describe(const Node& n) {
    if (n.tag == "ref") return "<ref id=\"" + n.id + "\">";
    return "<" + n.tag + (n.type.empty() ? "" : " type=\"" + n.type + "\"") + ">";
}

/// Typed, consuming access to one object's properties and children.
class Reader {
public:
    /// `path`: the scene file, for messages "PATH:LINE: ...".
    Reader(const std::string& path, const Node& n)
        : m_path(path), m_n(n), m_prop_used(n.props.size()), m_child_used(n.children.size()) {}

    const Node& node() const { return m_n; }
    [[noreturn]] void fail(int line, const std::string& what) const {
        throw Error(m_path + ":" + std::to_string(line) + ": " + what);
    }

    /// The property `name` (marked read), or nullptr. Throws if its kind is not in `kinds`.
    const Property* get(const std::string& name, std::initializer_list<PropKind> kinds) {
        for (std::size_t i = 0; i < m_n.props.size(); ++i) {
            const Property& p = m_n.props[i];
            if (p.name != name) continue;
            if (std::find(kinds.begin(), kinds.end(), p.kind) == kinds.end()) {
                std::string want;
                for (PropKind k : kinds)
                    want += std::string(want.empty() ? "" : " or ") + "<" + kind_name(k) + ">";
                fail(p.line, describe(m_n) + ": property '" + name + "' must be " + want +
                                 ", not <" + kind_name(p.kind) + ">");
            }
            m_prop_used[i] = true;
            return &p;
        }
        return nullptr;
    }
    float get_float(const std::string& name, float def) {
        const Property* p = get(name, {PropKind::float_, PropKind::integer});
        return !p ? def : p->kind == PropKind::integer ? float(p->i) : p->f;
    }
    int get_int(const std::string& name, int def) {
        const Property* p = get(name, {PropKind::integer});
        return p ? p->i : def;
    }
    bool get_bool(const std::string& name, bool def) {
        const Property* p = get(name, {PropKind::boolean});
        return p ? p->b : def;
    }
    std::string get_string(const std::string& name, const std::string& def) {
        const Property* p = get(name, {PropKind::string});
        return p ? p->s : def;
    }
    glm::vec3 get_rgb(const std::string& name, glm::vec3 def) {
        const Property* p = get(name, {PropKind::rgb, PropKind::spectrum, PropKind::float_});
        return !p ? def : p->kind == PropKind::float_ ? glm::vec3(p->f) : p->v;
    }
    glm::mat4 get_transform(const std::string& name) {
        const Property* p = get(name, {PropKind::transform});
        return p ? p->m : glm::mat4(1.0f);
    }
    /// Child objects (and refs) with one of the given tags, whatever their name, marked read.
    std::vector<const Node*> children(std::initializer_list<const char*> tags) {
        std::vector<const Node*> out;
        for (std::size_t i = 0; i < m_n.children.size(); ++i)
            for (const char* t : tags)
                if (m_n.children[i].tag == t) {
                    m_child_used[i] = true;
                    out.push_back(&m_n.children[i]);
                }
        return out;
    }
    /// The child object or ref with name="name", marked read, or nullptr.
    const Node* named_child(const std::string& name) {
        for (std::size_t i = 0; i < m_n.children.size(); ++i)
            if (m_n.children[i].name == name) {
                m_child_used[i] = true;
                return &m_n.children[i];
            }
        return nullptr;
    }
    /// Throws on the first property or child that no get()/children() call read.
    void finish() const {
        for (std::size_t i = 0; i < m_n.props.size(); ++i)
            if (!m_prop_used[i])
                fail(m_n.props[i].line,
                     describe(m_n) + ": unsupported property '" + m_n.props[i].name + "'");
        for (std::size_t i = 0; i < m_n.children.size(); ++i)
            if (!m_child_used[i]) {
                const Node& c = m_n.children[i];
                fail(c.line, describe(m_n) + ": unexpected " + describe(c) +
                                 (c.name.empty() ? "" : " with name=\"" + c.name + "\"") +
                                 " inside it");
            }
    }

private:
    const std::string& m_path;
    const Node& m_n;
    std::vector<bool> m_prop_used, m_child_used;
};

/// Throws Error "FILE:LINE: ..." unless `r`'s object is of plugin type `type`.
inline void require_type(const Reader& r, const char* type) {
    if (r.node().type != type)
        r.fail(r.node().line, describe(r.node()) + ": unsupported " + r.node().tag + " type '" +
                                  r.node().type + "' (supported: " + type + ")");
}

/// The sensors a scene-level <sensor> stands for (scene_sensors.cpp): itself, or a batch's
/// nested sensors, each with the node that declares it (for its id), in order.
/// `medium`, given a <medium> or <ref> child of a sensor, returns the medium's index.
std::vector<std::pair<Camera, const Node*>>
read_sensor(const std::string& path, const Node& n,
            const std::function<int(const Node&)>& medium);

/// The medium a <medium> tag describes (scene_media.cpp); grid files are resolved against `dir`,
/// the scene's folder.
Medium read_medium(const std::string& path, const std::filesystem::path& dir, const Node& n);

} // namespace tandem::scene_detail
