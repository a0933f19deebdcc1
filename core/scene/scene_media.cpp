// Mitsuba 3 XML, second pass: participating media (`homogeneous`, `heterogeneous`), their phase
// functions (`isotropic`, `hg`) and volumes (`constvolume`, `gridvolume`).
#include <cmath>
#include <filesystem>

#include <glm/matrix.hpp>

#include "core/scene/scene.h"
#include "core/scene/scene_reader.h"
#include "runtime/error.h"

namespace tandem::scene_detail {

namespace {

struct Media {
    const std::string& m_path;
    const std::filesystem::path& m_dir;

    [[noreturn]] void fail(int line, const std::string& what) const {
        throw Error(m_path + ":" + std::to_string(line) + ": " + what);
    }

    /// A grid file, relative to the scene's folder, that must exist.
    std::string grid_file(Reader& r) {
        const Property* p = r.get("filename", {PropKind::string});
        if (!p) fail(r.node().line, describe(r.node()) + ": missing property 'filename'");
        std::filesystem::path f(p->s);
        if (f.is_relative()) f = m_dir / f;
        f = f.lexically_normal();
        std::error_code ec;
        if (!std::filesystem::is_regular_file(f, ec))
            fail(p->line, describe(r.node()) + ": filename '" + p->s + "' not found (" +
                              f.string() + ")");
        return f.string();
    }

    /// A nested <volume name=...>: constvolume (`value`) or gridvolume (`filename`, `to_world`,
    /// `use_grid_bbox`; filter_type trilinear and wrap_mode clamp, Mitsuba's defaults, only).
    VolumeInput volume(const Node& n, bool grid_allowed) {
        Reader r(m_path, n);
        VolumeInput v;
        v.line = n.line;
        if (n.type == "constvolume") {
            v.value = r.get_rgb("value", glm::vec3(1.0f));
        } else if (n.type == "gridvolume") {
            if (!grid_allowed)
                fail(n.line, describe(n) + ": a homogeneous medium takes constant values only "
                                           "(use type=\"heterogeneous\" for a grid)");
            v.grid = true;
            v.filename = grid_file(r);
            v.to_world = r.get_transform("to_world");
            if (r.get_bool("use_grid_bbox", false))
                fail(n.line, describe(n) + ": use_grid_bbox is not supported (place the grid "
                                           "with to_world)");
            const std::string filter = r.get_string("filter_type", "trilinear");
            if (filter != "trilinear")
                fail(n.line, describe(n) + ": filter_type '" + filter +
                                 "' is not supported (trilinear)");
            const std::string wrap = r.get_string("wrap_mode", "clamp");
            if (wrap != "clamp")
                fail(n.line, describe(n) + ": wrap_mode '" + wrap + "' is not supported (clamp)");
            r.get_bool("raw", false); // linear values either way: no sRGB decoding of densities
            if (std::abs(glm::determinant(glm::mat3(v.to_world))) == 0.0f)
                fail(n.line, describe(n) + ": to_world is singular");
        } else {
            fail(n.line, describe(n) + ": unsupported volume type '" + n.type +
                             "' (supported: constvolume, gridvolume)");
        }
        r.finish();
        return v;
    }

    /// Property `name` of medium reader r: a float, rgb or spectrum, or a nested <volume>.
    VolumeInput input(Reader& r, const char* name, glm::vec3 def, bool grid_allowed) {
        const Node* child = r.named_child(name);
        const Property* p = r.get(name, {PropKind::rgb, PropKind::spectrum, PropKind::float_});
        if (child && p) fail(child->line, describe(r.node()) + ": '" + name + "' is given twice");
        if (child) {
            if (child->tag != "volume")
                fail(child->line, describe(r.node()) + ": '" + name + "' must be a value or a "
                                                                      "<volume>");
            return volume(*child, grid_allowed);
        }
        VolumeInput v;
        v.value = !p ? def : p->kind == PropKind::float_ ? glm::vec3(p->f) : p->v;
        v.line = p ? p->line : r.node().line;
        return v;
    }

    Medium medium(const Node& n) {
        Reader r(m_path, n);
        Medium m;
        m.id = n.id;
        m.line = n.line;
        if (n.type == "homogeneous")
            m.type = MediumType::homogeneous;
        else if (n.type == "heterogeneous")
            m.type = MediumType::heterogeneous;
        else
            fail(n.line, describe(n) + ": unsupported medium type '" + n.type +
                             "' (supported: homogeneous, heterogeneous)");
        const bool grids = m.type == MediumType::heterogeneous;
        m.sigma_t = input(r, "sigma_t", glm::vec3(1.0f), grids);
        m.albedo = input(r, "albedo", glm::vec3(0.75f), grids);
        m.scale = r.get_float("scale", 1.0f);
        if (!(m.scale >= 0.0f && std::isfinite(m.scale)))
            fail(n.line, describe(n) + ": scale must be finite and >= 0");
        if (!r.get_bool("sample_emitters", true))
            fail(n.line, describe(n) + ": sample_emitters=false is not supported");
        r.get_bool("has_spectral_extinction", true); // RGB extinction is always supported
        for (const VolumeInput* v : {&m.sigma_t, &m.albedo}) {
            if (v->grid) continue;
            const char* what = v == &m.sigma_t ? "sigma_t" : "albedo";
            for (int c = 0; c < 3; ++c)
                if (!(v->value[c] >= 0.0f && std::isfinite(v->value[c])))
                    fail(v->line, describe(n) + ": " + what + " must be finite and >= 0");
            if (v == &m.albedo && std::max({v->value.x, v->value.y, v->value.z}) > 1.0f)
                fail(v->line, describe(n) + ": albedo must be in [0, 1]");
        }
        const std::vector<const Node*> phases = r.children({"phase"});
        if (phases.size() > 1) fail(phases[1]->line, describe(n) + ": more than one <phase>");
        if (!phases.empty()) {
            Reader pr(m_path, *phases[0]);
            if (phases[0]->type == "isotropic") {
                m.phase = PhaseType::isotropic;
            } else if (phases[0]->type == "hg") {
                m.phase = PhaseType::hg;
                m.g = pr.get_float("g", 0.8f); // Mitsuba's default
                if (!(m.g > -1.0f && m.g < 1.0f))
                    fail(phases[0]->line, "<phase type=\"hg\">: g must be in (-1, 1)");
            } else {
                fail(phases[0]->line, "<phase type=\"" + phases[0]->type +
                                          "\">: unsupported phase type (supported: isotropic, "
                                          "hg)");
            }
            pr.finish();
        }
        r.finish();
        return m;
    }
};

} // namespace

Medium read_medium(const std::string& path, const std::filesystem::path& dir, const Node& n) {
    return Media{path, dir}.medium(n);
}

} // namespace tandem::scene_detail
