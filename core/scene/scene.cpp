// Mitsuba 3 XML, second pass: xml::Node tree -> SceneDesc. Each plugin reads its properties by
// name and kind; whatever it leaves unread is an error naming the property and its line.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "core/scene/scene.h"
#include "core/scene/scene_reader.h"
#include "runtime/error.h"

namespace tandem {
namespace {

using xml::Node;
using xml::Property;
using xml::PropKind;
using scene_detail::describe;
using scene_detail::Reader;
using scene_detail::require_type;

/// Conductor eta/k per RGB channel for Mitsuba's `material` names. Values: Tungsten's
/// ComplexIorData (github.com/tunabrain/tungsten, src/core/bsdfs/ComplexIorData.hpp), RGB
/// averages of the same measured spectra that Mitsuba ships (data/ior). "none" is Mitsuba's
/// perfect mirror (eta 0, k 1).
struct Metal {
    const char* name;
    glm::vec3 eta, k;
};
const Metal k_metals[] = {
    {"none", glm::vec3(0.f), glm::vec3(1.f)},
    {"Ag",
     {0.1552646489f, 0.1167232965f, 0.1383806959f},
     {4.8283433224f, 3.1222459278f, 2.1469504455f}},
    {"Al",
     {1.6574599595f, 0.8803689579f, 0.5212287346f},
     {9.2238691996f, 6.2695232477f, 4.8370012281f}},
    {"Au",
     {0.1431189557f, 0.3749570432f, 1.4424785571f},
     {3.9831604247f, 2.3857207478f, 1.6032152899f}},
    {"Cr",
     {4.3696828663f, 2.9167024892f, 1.6547005413f},
     {5.2064337956f, 4.2313645277f, 3.7549467933f}},
    {"Cu",
     {0.2004376970f, 0.9240334304f, 1.1022119527f},
     {3.9129485033f, 2.4528477015f, 2.1421879552f}},
};

/// Mitsuba's named indices of refraction (its dielectric plugin documentation).
const std::map<std::string, float> k_iors = {
    {"vacuum", 1.0f},      {"helium", 1.000036f},        {"hydrogen", 1.000132f},
    {"air", 1.000277f},    {"carbon dioxide", 1.00045f}, {"water", 1.3330f},
    {"acetone", 1.36f},    {"ethanol", 1.361f},          {"carbon tetrachloride", 1.461f},
    {"glycerol", 1.4729f}, {"benzene", 1.501f},          {"silicone oil", 1.52045f},
    {"bromine", 1.661f},   {"water ice", 1.31f},         {"fused quartz", 1.458f},
    {"pyrex", 1.470f},     {"acrylic glass", 1.49f},     {"polypropylene", 1.49f},
    {"bk7", 1.5046f},      {"sodium chloride", 1.544f},  {"amber", 1.55f},
    {"pet", 1.5750f},      {"diamond", 2.419f}};

class Builder {
public:
    explicit Builder(const std::string& path) : m_path(path) {
        m_scene.path = path;
        m_dir = std::filesystem::absolute(std::filesystem::path(path)).parent_path();
    }

    [[noreturn]] void fail(int line, const std::string& what) const {
        throw Error(m_path + ":" + std::to_string(line) + ": " + what);
    }

    SceneDesc build(const Node& root) {
        Reader r(m_path, root);
        bool have_integrator = false, have_sensor = false;
        for (const Node* c :
             r.children({"integrator", "sensor", "shape", "bsdf", "texture", "emitter", "medium"})) {
            if (c->tag == "integrator") {
                if (have_integrator) fail(c->line, "only one <integrator> is supported");
                have_integrator = true;
                integrator(*c);
            } else if (c->tag == "sensor") {
                if (!have_sensor) m_scene.sensors.clear(); // the default sensor gives way
                have_sensor = true;
                sensor(*c);
            } else if (c->tag == "shape") {
                shape(*c);
            } else if (c->tag == "bsdf") {
                add_bsdf(*c);
            } else if (c->tag == "texture") {
                add_texture(*c);
            } else if (c->tag == "medium") {
                if (c->id.empty())
                    fail(c->line, "<medium>: a medium at scene level needs an id (shapes and "
                                  "sensors refer to it)");
                add_medium(*c);
            } else {
                if (c->type == "area")
                    fail(c->line, "<emitter type=\"area\"> must be nested in a <shape>");
                add_emitter(*c);
            }
        }
        r.finish();
        return std::move(m_scene);
    }

private:
    // ---- ids and files ----
    struct Named {
        std::string tag;
        int index, line;
    };
    void define_id(const Node& n, int index) {
        if (n.id.empty()) return;
        const auto [it, fresh] = m_ids.emplace(n.id, Named{n.tag, index, n.line});
        if (!fresh)
            fail(n.line, describe(n) + ": duplicate id '" + n.id + "' (first used on line " +
                             std::to_string(it->second.line) + ")");
    }
    int resolve(const Node& ref, const char* tag) const {
        const auto it = m_ids.find(ref.id);
        if (it == m_ids.end())
            fail(ref.line, "<ref id=\"" + ref.id + "\">: unknown id '" + ref.id +
                               "' (ids must be defined before use)");
        if (it->second.tag != tag)
            fail(ref.line, "<ref id=\"" + ref.id + "\">: '" + ref.id + "' is a <" + it->second.tag +
                               ">, expected a <" + tag + ">");
        return it->second.index;
    }
    std::string existing_file(Reader& r, const std::string& name) {
        const Property* p = r.get(name, {PropKind::string});
        if (!p) fail(r.node().line, describe(r.node()) + ": missing property '" + name + "'");
        std::filesystem::path f(p->s);
        if (f.is_relative()) f = m_dir / f;
        f = f.lexically_normal();
        std::error_code ec;
        if (!std::filesystem::is_regular_file(f, ec))
            fail(p->line, describe(r.node()) + ": " + name + " '" + p->s + "' not found (" +
                              f.string() + ")");
        return f.string();
    }
    [[noreturn]] void unsupported(const Node& n, const char* supported) const {
        fail(n.line, describe(n) + ": unsupported " + n.tag + " type '" + n.type +
                         "' (supported: " + supported + ")");
    }

    // ---- integrator and sensor ----
    void integrator(const Node& n) {
        Reader r(m_path, n);
        if (n.type != "path" && n.type != "volpath" && n.type != "prbvolpath" && n.type != "prb")
            fail(n.line, describe(n) + ": unsupported integrator type '" + n.type +
                             "' (supported: path, prb, volpath, prbvolpath)");
        m_scene.integrator.type = n.type;
        m_scene.integrator.max_depth = r.get_int("max_depth", -1);
        m_scene.integrator.rr_depth = r.get_int("rr_depth", 5);
        if (m_scene.integrator.max_depth < -1) fail(n.line, "<integrator>: max_depth < -1");
        if (m_scene.integrator.rr_depth < 0) fail(n.line, "<integrator>: rr_depth < 0");
        r.finish();
    }

    /// A sensor at scene level: a perspective sensor, or a batch of them (scene_sensors.cpp).
    void sensor(const Node& n) {
        define_id(n, static_cast<int>(m_scene.sensors.size()));
        const auto medium = [this](const Node& c) { return medium_child(c); };
        for (auto& [camera, node] : scene_detail::read_sensor(m_path, n, medium)) {
            if (node != &n) define_id(*node, static_cast<int>(m_scene.sensors.size()));
            m_scene.sensors.push_back(std::move(camera));
        }
    }

    // ---- shapes ----
    void shape(const Node& n) {
        Reader r(m_path, n);
        Shape s;
        s.id = n.id;
        s.line = n.line;
        const std::map<std::string, ShapeType> types = {{"obj", ShapeType::obj},
                                                        {"ply", ShapeType::ply},
                                                        {"rectangle", ShapeType::rectangle},
                                                        {"cube", ShapeType::cube},
                                                        {"sphere", ShapeType::sphere},
                                                        {"disk", ShapeType::disk}};
        if (!types.count(n.type)) unsupported(n, "obj, ply, rectangle, cube, sphere, disk");
        s.type = types.at(n.type);
        if (s.type == ShapeType::obj || s.type == ShapeType::ply) {
            s.filename = existing_file(r, "filename");
            s.face_normals = r.get_bool("face_normals", false);
        }
        if (s.type == ShapeType::sphere) {
            const Property* c = r.get("center", {PropKind::point});
            if (c) s.center = c->v;
            s.radius = r.get_float("radius", 1.f);
            if (!(s.radius > 0.f)) fail(n.line, "<shape type=\"sphere\">: radius must be > 0");
        }
        s.to_world = r.get_transform("to_world");
        s.flip_normals = r.get_bool("flip_normals", false);

        std::vector<const Node*> bsdfs = r.children({"bsdf"});
        for (const Node* ref : r.children({"ref"}))
            if (ref->name.empty() || ref->name == "bsdf") bsdfs.push_back(ref);
        if (bsdfs.size() > 1) fail(bsdfs[1]->line, describe(n) + ": more than one bsdf");
        if (!bsdfs.empty())
            s.bsdf = bsdfs[0]->tag == "ref" ? resolve(*bsdfs[0], "bsdf") : add_bsdf(*bsdfs[0]);
        const std::vector<const Node*> emitters = r.children({"emitter"});
        if (emitters.size() > 1) fail(emitters[1]->line, describe(n) + ": more than one emitter");
        if (!emitters.empty()) {
            if (emitters[0]->type != "area")
                fail(emitters[0]->line,
                     describe(*emitters[0]) + ": only area emitters can be nested in a shape");
            s.emitter = add_emitter(*emitters[0]);
        }
        for (const Node* c : r.children({"medium", "ref"})) {
            if (c->tag == "ref" && (c->name.empty() || c->name == "bsdf")) continue; // the bsdf
            if (c->name != "interior" && c->name != "exterior")
                fail(c->line, describe(*c) + ": a medium of a shape is named \"interior\" or "
                                             "\"exterior\"" +
                                  (c->name.empty() ? "" : ", not \"" + c->name + "\""));
            int& side = c->name == "interior" ? s.interior : s.exterior;
            if (side >= 0) fail(c->line, describe(n) + ": more than one " + c->name + " medium");
            side = medium_child(*c);
        }
        r.finish();
        define_id(n, int(m_scene.shapes.size()));
        m_scene.shapes.push_back(s);
    }

    // ---- media ----
    int add_medium(const Node& n) {
        Medium m = scene_detail::read_medium(m_path, m_dir, n);
        define_id(n, int(m_scene.media.size()));
        m_scene.media.push_back(std::move(m));
        return int(m_scene.media.size()) - 1;
    }
    /// A medium nested in a shape or sensor, or a <ref> to one.
    int medium_child(const Node& c) {
        return c.tag == "ref" ? resolve(c, "medium") : add_medium(c);
    }

    // ---- emitters ----
    int add_emitter(const Node& n) {
        Reader r(m_path, n);
        Emitter e;
        e.id = n.id;
        e.line = n.line;
        const std::map<std::string, EmitterType> types = {{"area", EmitterType::area},
                                                          {"point", EmitterType::point},
                                                          {"spot", EmitterType::spot},
                                                          {"constant", EmitterType::constant},
                                                          {"envmap", EmitterType::envmap}};
        if (!types.count(n.type)) unsupported(n, "area, point, spot, constant, envmap");
        e.type = types.at(n.type);
        switch (e.type) {
        case EmitterType::area:
        case EmitterType::constant:
            e.radiance = r.get_rgb("radiance", e.radiance);
            break;
        case EmitterType::point: {
            e.intensity = r.get_rgb("intensity", e.intensity);
            const Property* pos = r.get("position", {PropKind::point});
            e.to_world = r.get_transform("to_world");
            if (pos && r.get("to_world", {PropKind::transform}))
                fail(pos->line, describe(n) + ": give either 'position' or 'to_world'");
            if (pos) e.to_world[3] = glm::vec4(pos->v, 1.f);
            break;
        }
        case EmitterType::spot:
            e.intensity = r.get_rgb("intensity", e.intensity);
            e.cutoff_angle = r.get_float("cutoff_angle", e.cutoff_angle);
            e.beam_width = r.get_float("beam_width", e.cutoff_angle * 0.75f);
            e.to_world = r.get_transform("to_world");
            if (!(e.cutoff_angle > 0.f && e.cutoff_angle <= 180.f))
                fail(n.line, describe(n) + ": cutoff_angle must be in (0, 180]");
            break;
        case EmitterType::envmap:
            e.scale = r.get_float("scale", 1.f);
            if (!(e.scale >= 0.f && std::isfinite(e.scale)))
                fail(n.line, describe(n) + ": scale must be finite and >= 0");
            e.filename = existing_file(r, "filename");
            e.to_world = r.get_transform("to_world");
            break;
        }
        r.finish();
        define_id(n, int(m_scene.emitters.size()));
        m_scene.emitters.push_back(e);
        return int(m_scene.emitters.size()) - 1;
    }

    // ---- bsdfs and textures ----
    int add_bsdf(const Node& n) {
        Bsdf b = make_bsdf(n);
        define_id(n, int(m_scene.bsdfs.size()));
        m_scene.bsdfs.push_back(b);
        return int(m_scene.bsdfs.size()) - 1;
    }

    Bsdf make_bsdf(const Node& n) {
        Reader r(m_path, n);
        if (n.type == "twosided") {
            const std::vector<const Node*> inner = r.children({"bsdf", "ref"});
            if (inner.size() != 1)
                fail(n.line, "<bsdf type=\"twosided\">: needs exactly one nested bsdf, has " +
                                 std::to_string(inner.size()));
            const Node& in = *inner[0];
            if (in.tag == "bsdf" && in.type == "twosided")
                fail(in.line, "<bsdf type=\"twosided\"> cannot wrap another twosided bsdf");
            if (in.tag == "bsdf" && !in.id.empty())
                fail(in.line,
                     describe(in) + ": a bsdf nested in a twosided bsdf cannot have an id");
            Bsdf b;
            if (in.tag == "ref") {
                const int shared = resolve(in, "bsdf");
                b = m_scene.bsdfs[static_cast<std::size_t>(shared)];
                if (b.shared_from < 0) b.shared_from = shared;
            } else {
                b = make_bsdf(in);
            }
            r.finish();
            b.twosided = true;
            b.id = n.id;
            b.line = n.line;
            return b;
        }
        Bsdf b;
        b.id = n.id;
        b.line = n.line;
        if (n.type == "null") {
            b.type = BsdfType::null;
            r.finish();
            return b;
        }
        const std::map<std::string, BsdfType> types = {{"diffuse", BsdfType::diffuse},
                                                       {"conductor", BsdfType::conductor},
                                                       {"roughconductor", BsdfType::roughconductor},
                                                       {"dielectric", BsdfType::dielectric},
                                                       {"roughplastic", BsdfType::roughplastic}};
        if (!types.count(n.type))
            unsupported(n,
                        "diffuse, conductor, roughconductor, dielectric, roughplastic, twosided, "
                        "null");
        b.type = types.at(n.type);
        const bool rough = b.type == BsdfType::roughconductor || b.type == BsdfType::roughplastic;
        if (rough) {
            b.alpha = r.get_float("alpha", b.alpha);
            if (!(b.alpha > 0.f && b.alpha <= 1.f))
                fail(n.line, describe(n) + ": alpha must be in (0, 1]");
            if (const Property* d = r.get("distribution", {PropKind::string}); d && d->s != "ggx")
                fail(d->line, describe(n) + ": distribution '" + d->s + "' is not supported (ggx)");
        }
        switch (b.type) {
        case BsdfType::null: // returned above
            break;
        case BsdfType::diffuse:
            b.reflectance = color(r, "reflectance", glm::vec3(0.5f));
            break;
        case BsdfType::conductor:
        case BsdfType::roughconductor: {
            b.specular_reflectance = color(r, "specular_reflectance", glm::vec3(1.f));
            const Property* mat = r.get("material", {PropKind::string});
            const Property* eta =
                r.get("eta", {PropKind::rgb, PropKind::spectrum, PropKind::float_});
            const Property* k = r.get("k", {PropKind::rgb, PropKind::spectrum, PropKind::float_});
            if (mat && (eta || k))
                fail(mat->line, describe(n) + ": give either 'material' or 'eta'/'k'");
            const std::string name = mat ? mat->s : "none";
            const Metal* m = nullptr;
            for (const Metal& cand : k_metals)
                if (name == cand.name) m = &cand;
            if (!m)
                fail(mat->line, describe(n) + ": unknown conductor material '" + name +
                                    "' (supported: none, Ag, Al, Au, Cr, Cu)");
            b.eta = eta ? (eta->kind == PropKind::float_ ? glm::vec3(eta->f) : eta->v) : m->eta;
            b.k = k ? (k->kind == PropKind::float_ ? glm::vec3(k->f) : k->v) : m->k;
            break;
        }
        case BsdfType::dielectric:
            b.specular_reflectance = color(r, "specular_reflectance", glm::vec3(1.f));
            b.int_ior = ior(r, "int_ior", 1.5046f);
            b.ext_ior = ior(r, "ext_ior", 1.000277f);
            break;
        case BsdfType::roughplastic:
            b.reflectance = color(r, "diffuse_reflectance", glm::vec3(0.5f));
            b.specular_reflectance = color(r, "specular_reflectance", glm::vec3(1.f));
            b.int_ior = ior(r, "int_ior", 1.49f);
            b.ext_ior = ior(r, "ext_ior", 1.000277f);
            b.nonlinear = r.get_bool("nonlinear", false);
            break;
        }
        r.finish();
        return b;
    }

    /// Mitsuba IOR input: a float, or a name from its table ("bk7", "water", ...).
    float ior(Reader& r, const char* name, float def) {
        const Property* p = r.get(name, {PropKind::float_, PropKind::integer, PropKind::string});
        if (!p) return def;
        if (p->kind != PropKind::string) return p->kind == PropKind::integer ? float(p->i) : p->f;
        if (!k_iors.count(p->s))
            fail(p->line, describe(r.node()) + ": unknown " + name + " material '" + p->s + "'");
        return k_iors.at(p->s);
    }

    /// A colour input: a property, or a nested texture / texture ref with name="name".
    ColorInput color(Reader& r, const char* name, glm::vec3 def) {
        ColorInput c;
        const bool has_prop = std::any_of(r.node().props.begin(), r.node().props.end(),
                                          [&](const Property& p) { return p.name == name; });
        const Node* child = r.named_child(name);
        if (child && has_prop)
            fail(child->line, describe(r.node()) + ": '" + name + "' is given twice");
        c.value = r.get_rgb(name, def);
        if (!child) return c;
        if (child->tag == "ref")
            c.texture = resolve(*child, "texture");
        else if (child->tag == "texture")
            c.texture = add_texture(*child);
        else
            fail(child->line,
                 describe(r.node()) + ": '" + name + "' must be a colour or a texture");
        return c;
    }

    int add_texture(const Node& n) {
        Reader r(m_path, n);
        Texture t;
        t.id = n.id;
        t.line = n.line;
        if (n.type == "bitmap") {
            t.kind = Texture::Kind::bitmap;
            t.filename = existing_file(r, "filename");
            t.srgb = !r.get_bool("raw", false);
            t.filter_type = r.get_string("filter_type", "bilinear");
            if (t.filter_type != "bilinear" && t.filter_type != "nearest")
                fail(r.get("filter_type", {PropKind::string})->line,
                     describe(n) + ": filter_type must be bilinear or nearest");
        } else if (n.type == "checkerboard") {
            t.kind = Texture::Kind::checkerboard;
            t.color0 = r.get_rgb("color0", t.color0);
            t.color1 = r.get_rgb("color1", t.color1);
        } else {
            unsupported(n, "bitmap, checkerboard");
        }
        // Mitsuba's Transform4f::extract(): the 2D part (x, y rows and columns, translation).
        const glm::mat4 m = r.get_transform("to_uv");
        t.to_uv =
            glm::mat3(m[0][0], m[0][1], 0.f, m[1][0], m[1][1], 0.f, m[3][0], m[3][1], m[3][3]);
        r.finish();
        define_id(n, int(m_scene.textures.size()));
        m_scene.textures.push_back(t);
        return int(m_scene.textures.size()) - 1;
    }

    std::string m_path;
    std::filesystem::path m_dir;
    SceneDesc m_scene;
    std::map<std::string, Named> m_ids;
};

} // namespace

SceneDesc load_scene(const std::string& path,
                     const std::vector<std::pair<std::string, std::string>>& defines) {
    const xml::Node root = xml::parse_file(path, defines);
    return Builder(path).build(root);
}

std::vector<std::string> scene_files(const SceneDesc& desc) {
    std::vector<std::string> files{desc.path};
    const auto add = [&](const std::string& f) {
        if (!f.empty() && std::find(files.begin(), files.end(), f) == files.end())
            files.push_back(f);
    };
    for (const Texture& t : desc.textures)
        add(t.filename);
    for (const Emitter& e : desc.emitters)
        add(e.filename);
    for (const Shape& s : desc.shapes)
        add(s.filename);
    for (const Medium& m : desc.media) {
        add(m.sigma_t.filename);
        add(m.albedo.filename);
    }
    return files;
}

} // namespace tandem
