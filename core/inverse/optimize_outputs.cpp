// The files of `tandem optimize` besides its metrics and checkpoints.
#include "core/inverse/optimize_outputs.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/inverse/optimize.h"
#include "core/inverse/streams.h"
#include "core/io/atomic_file.h"
#include "core/io/image_io.h"
#include "core/io/vertex_io.h"

namespace tandem {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// A file name for a parameter: its name with anything but [A-Za-z0-9._-] replaced by '_'.
std::string file_name(const std::string& name) {
    std::string out = name;
    for (char& ch : out)
        if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '-' && ch != '_')
            ch = '_';
    return out;
}

/// Whether two scene paths name one file (the same string where either is missing).
bool same_file(const std::string& a, const std::string& b) {
    std::error_code ec;
    const bool same = fs::equivalent(a, b, ec);
    return ec ? a == b : same;
}

} // namespace

StartValues start_values(const OptimizeConfig& c, const ParamRegistry& reg) {
    StartValues s;
    s.values = reg.values();
    s.lr.assign(reg.size(), 0.0f);
    for (const OptimizedParam& p : c.params) {
        const Parameter& q = [&]() -> const Parameter& {
            try {
                return reg.find(p.name);
            } catch (const Error& e) {
                throw Error(c.path + ": params: " + e.what());
            }
        }();
        s.optimized.push_back(&q);
        std::fill_n(s.lr.begin() + q.offset, q.size, p.lr);
        if (p.init.size() == 1) std::fill_n(s.values.begin() + q.offset, q.size, p.init[0]);
        if (p.init.size() == 3) {
            if (q.kind == Parameter::Kind::scalar)
                throw Error(c.path + ": params." + p.name + ": a scalar takes one 'init' value");
            for (std::size_t i = 0; i < q.size; ++i)
                s.values[q.offset + i] = p.init[i % 3];
        }
        for (std::size_t i = q.offset; i < q.offset + q.size; ++i)
            if (!(s.values[i] >= q.lower && s.values[i] <= q.upper)) {
                std::ostringstream m;
                m << c.path << ": params." << p.name << ": "
                  << (p.init.empty() ? "the scene's value " : "'init' ") << s.values[i]
                  << " is outside the range it is optimized in, [" << q.lower << ", " << q.upper
                  << "]" << (p.init.empty() ? ": give an 'init' inside it" : "");
                throw Error(m.str());
            }
    }
    if (s.values.empty()) s.values.resize(1), s.lr.resize(1); // the state's buffers hold >= 1
    return s;
}

std::vector<unsigned> view_sensors(const Session& session, const OptimizeConfig& c) {
    std::vector<unsigned> out;
    if (c.views.empty()) {
        for (unsigned k = 0; k < session.sensors(); ++k) out.push_back(k);
        return out;
    }
    for (const std::string& key : c.views) {
        unsigned k = 0;
        try {
            k = session.sensor(key);
        } catch (const Error& e) {
            throw Error(c.path + ": views: " + e.what());
        }
        if (std::find(out.begin(), out.end(), k) != out.end())
            throw Error(c.path + ": views: sensor " + std::to_string(k) + " is listed twice");
        out.push_back(k);
    }
    return out;
}

std::vector<ViewTarget> load_targets(Session& session, const OptimizeConfig& c,
                                     const std::vector<unsigned>& sensors,
                                     const std::vector<const Parameter*>& optimized,
                                     std::vector<float>* reference_values) {
    const RenderScene& scene = session.scene();
    std::vector<ViewTarget> targets;
    auto film = [&](unsigned k) {
        const std::string& id = scene.sensors.at(k).id;
        return "sensor " + std::to_string(k) + (id.empty() ? "" : " ('" + id + "')");
    };
    if (!c.target_images.empty()) {
        if (c.target_images.size() != session.sensors())
            throw Error(c.path + ": target.images has " + std::to_string(c.target_images.size()) +
                        " image" + (c.target_images.size() == 1 ? "" : "s") + ", the scene has " +
                        std::to_string(session.sensors()) + " sensor" +
                        (session.sensors() == 1 ? "" : "s") + " (one image per sensor, in order)");
        for (unsigned k : sensors) {
            const std::string mask = c.target_masks.empty() ? "" : c.target_masks.at(k);
            TargetImage t = read_target_image(c.target_images.at(k), mask, session.width(k),
                                              session.height(k), film(k));
            targets.push_back(ViewTarget{k, std::move(t.rgb), std::move(t.mask)});
        }
        return targets;
    }
    // The same file with the same defines is the same scene: its target is rendered on the
    // session's device scene, whose kernels render without reservoirs what a scene of its own
    // (render_features, RESTIR=0) does, bit for bit (tests/core/inverse/test_restir.cpp).
    const bool own = same_file(c.target_scene, c.scene) && c.target_defines == c.defines;
    std::unique_ptr<Session> other;
    if (!own) {
        other = std::make_unique<Session>(session.context(), session.library(), c.target_scene,
                                          c.target_defines);
        if (other->sensors() != session.sensors())
            throw Error(c.target_scene + ": the target scene has " +
                        std::to_string(other->sensors()) + " sensors, the scene " +
                        std::to_string(session.sensors()));
        for (unsigned k = 0; k < session.sensors(); ++k)
            if (other->width(k) != session.width(k) || other->height(k) != session.height(k))
                throw Error(c.target_scene + ": the film of the target scene's " + film(k) +
                            " differs from the scene's");
    }
    const ParamRegistry& target_params = own ? scene.params : other->scene().params;
    for (unsigned k : sensors) {
        RenderOptions ro;
        ro.spp = c.target_spp;
        ro.seed = view_seed(stream_seed(c.seed, 0, Stream::target), k);
        targets.push_back(ViewTarget{
            k, own ? session.render_image(target_params.values(), ro, k).rgb
                   : other->render_image(ro, k).rgb, {}});
    }
    for (const Parameter* p : optimized) {
        const Parameter& q = target_params.find(p->name);
        if (q.size != p->size)
            throw Error(c.target_scene + ": parameter " + p->name + " has " +
                        std::to_string(q.size) + " values, the scene's has " +
                        std::to_string(p->size));
        reference_values->insert(reference_values->end(), target_params.values().begin() + q.offset,
                                 target_params.values().begin() + q.offset + q.size);
    }
    return targets;
}

std::string iteration_name(const char* prefix, int it) {
    std::ostringstream s;
    s << prefix << std::setw(4) << std::setfill('0') << it << ".exr";
    return s.str();
}

void write_parameters(const std::string& out_dir, const std::vector<const Parameter*>& optimized,
                      const std::vector<float>& values) {
    const fs::path out(out_dir);
    json pj = json::object();
    for (const Parameter* p : optimized) {
        if (p->kind == Parameter::Kind::texture) {
            const std::vector<float> texels(values.begin() + p->offset,
                                            values.begin() + p->offset + p->size);
            const std::string base = file_name(p->name);
            write_image((out / (base + ".exr")).string(), p->width, p->height, texels);
            write_image((out / (base + ".png")).string(), p->width, p->height, texels);
            pj[p->name] = {{"texture", base + ".exr"}, {"width", p->width}, {"height", p->height}};
        } else {
            pj[p->name] = std::vector<float>(values.begin() + p->offset,
                                             values.begin() + p->offset + p->size);
        }
    }
    write_file_atomic((out / "params.json").string(), pj.dump(2) + "\n");
}

void write_meshes(const std::string& out, int iteration, const std::vector<const Parameter*>& optimized,
                  const RenderScene& scene, ParamState& state) {
    std::vector<float> theta;
    for (const Parameter* p : optimized) {
        if (p->kind != Parameter::Kind::vertices) continue;
        if (theta.empty()) theta = state.theta().download();
        const MeshShape& s = scene.mesh_shape(*p);
        std::vector<glm::vec3> positions(s.vertex_count);
        for (unsigned i = 0; i < s.vertex_count; ++i)
            positions[i] = glm::vec3(theta[p->offset + 3 * i], theta[p->offset + 3 * i + 1],
                                     theta[p->offset + 3 * i + 2]);
        const fs::path dir = fs::path(out) / "meshes";
        std::error_code ec;
        fs::create_directories(dir, ec);
        if (ec) throw Error(dir.string() + ": cannot create the folder: " + ec.message());
        std::string name = iteration_name((file_name(p->name) + "_iter_").c_str(), iteration);
        name.replace(name.size() - 4, 4, ".ply");
        write_vertex_ply((dir / name).string(), positions, scene.shape_triangles(s), {}, "");
    }
}

std::string optimize_summary_json(const OptimizeSummary& s, const std::string& out_dir) {
    return nlohmann::json{{"iterations", s.iterations_done},
                          {"loss", s.final_loss},
                          {"param_error", s.param_error},
                          {"image_error", s.image_error},
                          {"seconds", s.seconds},
                          {"primal_seconds", s.primal_seconds},
                          {"adjoint_seconds", s.adjoint_seconds},
                          {"restir_seconds", s.restir_seconds},
                          {"other_seconds", s.other_seconds},
                          {"alpha_mean", s.alpha_mean},
                          {"guards", s.guards},
                          {"cv_plan", s.cv_plan},
                          {"cv_variance", s.cv_variance},
                          {"restir", s.restir},
                          {"checkpoints", s.checkpoints},
                          {"checkpoint_seconds", s.checkpoint_seconds},
                          {"inputs_changed", s.inputs_changed},
                          {"ranks", s.ranks},
                          {"exchange_wait_seconds", s.exchanges.wait_seconds},
                          {"exchange_seconds", s.exchanges.exchange_seconds},
                          {"exchange_bytes", s.exchanges.bytes},
                          {"out", out_dir}}
        .dump(2);
}

std::string reuse_notes(const OptimizeConfig& c) {
    std::ostringstream notes;
    if (c.restir) notes << restir_note(*c.restir);
    if (const auto& r = c.boundary_reuse)
        notes << "tandem optimize: the secondary boundary term reuses light vertices across "
                 "iterations (" << r->candidates << " candidates, " << r->neighbours
              << " neighbours per cell, one set of reservoirs in world space for every view)\n";
    return notes.str();
}

std::string restir_note(const RestirConfig& r) {
    std::ostringstream notes;
    const char* where = r.adjoint && r.primal ? "the adjoint's and the primal's first vertex "
                                                "(independent chains)"
                        : r.primal            ? "the primal's first vertex"
                                              : "the adjoint's first vertex";
    notes << "tandem optimize: ReSTIR reuses light samples at " << where << " (" << r.candidates
          << " candidates, temporal " << (r.temporal ? "on" : "off") << ", " << r.spatial
          << " spatial, visibility " << (r.visibility ? "on" : "off") << "); deeper vertices"
          << (r.primal ? (r.adjoint ? "" : " and the adjoint") : " and the primal image")
          << " sample lights as before\n";
    return notes.str();
}

std::string geometry_note(DeviceScene& scene, int it) {
    const std::string report = scene.take_geometry_report();
    if (report.empty()) return "";
    return "tandem optimize: iteration " + std::to_string(it + 1) + ": " + report + "\n";
}

std::string non_finite_note(const std::vector<const Parameter*>& optimized,
                            const std::vector<float>& values) {
    std::size_t at = 0;
    for (const Parameter* p : optimized) {
        for (std::size_t k = 0; k < p->size; ++k)
            if (!std::isfinite(values[at + k]))
                return p->name + ": " +
                       (p->kind == Parameter::Kind::vertices
                            ? "vertex " + std::to_string(k / 3) + " is not finite"
                            : "element " + std::to_string(k) + " is not finite");
        at += p->size;
    }
    return "";
}

} // namespace tandem
