// `tandem grad SCENE.xml --param NAME [--param NAME]... [--spp N] [--spp-grad N] [--seed S]
//  [--loss mean|l1|l2|rl2] [--ref FILE] [--out-grad FILE.exr] [-D name=value]... [--json]
//  [--restir [--restir-burn-in B]]`: the PRB gradient of an image loss with respect to scene
// parameters, optionally with light samples resampled by ReSTIR at the adjoint's first vertex.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "core/inverse/session.h"
#include "core/render/boundary_guide.h"
#include "core/io/atomic_file.h"
#include "core/io/image_io.h"
#include "core/io/vertex_io.h"
#include "core/io/volume_io.h"
#include "runtime/error.h"

namespace tandem::cli {

namespace {

struct GradArgs {
    std::string scene, loss = "mean", ref, out_grad;
    std::vector<std::string> params, defines;
    int spp = 0, spp_grad = 0, spp_primary = -1, spp_secondary = -1;
    bool light_pairs = false;
    std::string secondary_guide = "auto";
    unsigned seed = 0;
    bool json = false;
    std::string sensor = "0";
    bool restir = false;
    int restir_burn_in = RestirConfig().burn_in;
    std::string restir_direct = restir_direct_name(RestirConfig().direct);
    std::string restir_visibility = "on";
};

struct Summary {
    double min = 0, max = 0, mean = 0, norm = 0;
    std::size_t nonzero = 0;
};

Summary summarize(const float* g, std::size_t n) {
    Summary s;
    s.min = s.max = g[0];
    double sum = 0, sum2 = 0;
    for (std::size_t i = 0; i < n; ++i) {
        s.min = std::min<double>(s.min, g[i]);
        s.max = std::max<double>(s.max, g[i]);
        sum += g[i];
        sum2 += double(g[i]) * g[i];
        s.nonzero += g[i] != 0.0f;
    }
    s.mean = sum / double(n);
    s.norm = std::sqrt(sum2);
    return s;
}

} // namespace

void add_grad_command(CLI::App& app, GlobalOptions& global) {
    CLI::App* cmd = app.add_subcommand(
        "grad", "Gradient of an image loss with respect to scene parameters (PRB)");
    auto a = std::make_shared<GradArgs>();
    cmd->add_option("scene", a->scene, "scene file")->required()->check(CLI::ExistingFile);
    cmd->add_option("--param", a->params, "parameter name (see `tandem params`); repeatable")
        ->required();
    cmd->add_option("-D", a->defines, "override a <default>: name=value (repeatable)");
    cmd->add_option("--spp", a->spp,
                    "samples per pixel of the primal render, of every view (default: the first "
                    "chosen sensor's sampler)")
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--spp-grad", a->spp_grad,
                    "samples per pixel of the adjoint pass (default: --spp)")
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--spp-primary", a->spp_primary,
                    "shape gradients: edge samples per pixel of the primary boundary term "
                    "(silhouettes in view; default: --spp-grad; 0 leaves it out)")
        ->check(CLI::Range(0, 1 << 20));
    cmd->add_option("--spp-secondary", a->spp_secondary,
                    "shape gradients: edge samples per pixel of the secondary boundary term "
                    "(shadows and reflections; default: --spp-grad; 0 leaves it out)")
        ->check(CLI::Range(0, 1 << 20));
    cmd->add_option("--secondary-guide", a->secondary_guide,
                    "shape gradients: guide the secondary term's directions toward the receivers' "
                    "glossy lobes (auto: where a surface is roughconductor or roughplastic)")
        ->check(CLI::IsMember({"auto", "on", "off"}))
        ->capture_default_str();
    cmd->add_flag("--light-pairs", a->light_pairs,
                  "shape gradients: half the secondary samples aim at (edge, light) pairs whose "
                  "edge may be a silhouette seen from the light (two area lights or more; "
                  "docs/method.md, 'Light pairs')");
    cmd->add_option("--seed", a->seed,
                    "random seed (the primal and adjoint passes use independent streams of it)")
        ->capture_default_str();
    cmd->add_option("--loss", a->loss, "mean (no reference), l1, l2 or rl2")->capture_default_str();
    cmd->add_option("--ref", a->ref,
                    "reference image (the film's size), for l1, l2 and rl2; with --sensor all, "
                    "NAME_K.EXT for sensor K");
    cmd->add_option("--sensor", a->sensor,
                    "the sensor whose loss is differentiated: its index or id; 'all': the sum of "
                    "every sensor's loss")
        ->capture_default_str();
    cmd->add_option("--out-grad", a->out_grad,
                    "write the gradient of a texture parameter as an image (.exr), of a "
                    "medium's grid as a grid volume (.vol), or of a mesh's vertex positions as "
                    "the mesh with grad_x/y/z vertex properties (.ply) or a (V, 3) array (.npy)");
    cmd->add_option("--device", global.device, "OpenCL device: index or name substring");
    cmd->add_flag("--restir", a->restir,
                  "reuse light samples at the adjoint's first vertex (ReSTIR, at this fixed "
                  "theta: burn-in passes, then the adjoint)");
    cmd->add_option("--restir-burn-in", a->restir_burn_in,
                    "resampling passes before the adjoint, with --restir")
        ->check(CLI::Range(0, 1 << 16))
        ->capture_default_str();
    cmd->add_option("--restir-direct", a->restir_direct,
                    "the share of the first vertex's direct light reservoirs estimate, with "
                    "--restir: all (where NEE can sample it), mis (NEE's MIS share), auto (all at "
                    "diffuse surfaces, mis elsewhere)")
        ->check(CLI::IsMember({"auto", "all", "mis"}))
        ->capture_default_str();
    cmd->add_option("--restir-visibility", a->restir_visibility,
                    "with --restir: whether the reservoirs' targets include visibility (off: the "
                    "paths trace it; shape gradients need off)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    cmd->add_flag("--json", a->json, "print JSON");
    cmd->callback([a, &global] {
        if (!a->restir && a->restir_burn_in != RestirConfig().burn_in)
            throw Error("--restir-burn-in needs --restir");
        if (!a->restir && a->restir_direct != restir_direct_name(RestirConfig().direct))
            throw Error("--restir-direct needs --restir");
        if (!a->restir && a->restir_visibility != "on")
            throw Error("--restir-visibility needs --restir");
        const unsigned loss = loss_kind(a->loss);
        if (loss != LOSS_MEAN && a->ref.empty())
            throw Error("--loss " + a->loss + " needs a reference image (--ref FILE)");
        if (loss == LOSS_MEAN && !a->ref.empty())
            throw Error("--ref is read only by --loss l1, l2 or rl2 (the mean loss has none)");
        const auto ends_with = [&](const char* ext) {
            const std::size_t n = std::strlen(ext);
            return a->out_grad.size() > n &&
                   a->out_grad.compare(a->out_grad.size() - n, n, ext) == 0;
        };
        const bool grad_volume = ends_with(".vol");
        const bool grad_vertices = ends_with(".ply") || ends_with(".npy");
        if (!a->out_grad.empty() && !grad_volume && !grad_vertices)
            check_signed_image_output(a->out_grad); // before the work
        if (grad_vertices) check_output_file(a->out_grad);
        const SceneDesc desc = load_scene(a->scene, parse_defines(a->defines));
        RenderScene loaded = build_render_scene(desc);
        std::vector<const Parameter*> params;
        for (const std::string& name : a->params)
            params.push_back(&loaded.params.find(name));
        const Parameter::Kind out_kind = grad_volume     ? Parameter::Kind::volume
                                         : grad_vertices ? Parameter::Kind::vertices
                                                         : Parameter::Kind::texture;
        if (!a->out_grad.empty() && (params.size() != 1 || params[0]->kind != out_kind))
            throw Error(grad_volume     ? "--out-grad FILE.vol needs exactly one grid parameter"
                        : grad_vertices ? "--out-grad FILE.ply or FILE.npy needs exactly one "
                                          "NAME.vertex_positions parameter"
                                        : "--out-grad needs exactly one texture parameter (or a "
                                          ".vol file for one grid parameter, a .ply or .npy file "
                                          "for one mesh's vertex positions)");
        const std::vector<unsigned> sensors = chosen_sensors(desc.sensors, a->sensor);
        const bool several = a->sensor == "all" && desc.sensors.size() > 1;
        std::vector<ViewTarget> targets;
        for (unsigned k : sensors) {
            const Camera& c = desc.sensors[k];
            targets.push_back(ViewTarget{
                k,
                loss == LOSS_MEAN ? std::vector<float>()
                                  : read_film_image(sensor_path(a->ref, k, several), "reference",
                                                    unsigned(c.width), unsigned(c.height)),
                {}});
        }

        Context ctx = Context::create(global.device, global.tuning);
        SessionOptions options;
        options.restir = a->restir;
        Session session(ctx, KernelLibrary::from_tuning(global.tuning), std::move(loaded), options);
        session.set_boundary_samples(
            {a->spp_primary, a->spp_secondary,
             secondary_guide_mode(a->secondary_guide, "--secondary-guide"), a->light_pairs});
        const RenderScene& scene = session.scene(); // `params` point into it still
        const int spp = a->spp > 0 ? a->spp : scene.sensors[sensors.front()].spp;
        // one gradient of every chosen view takes one spp: say so where their samplers differ
        for (unsigned k : sensors)
            if (a->spp == 0 && scene.sensors[k].spp != spp) {
                std::cerr << "tandem grad: the sensors' samplers differ (sensor " << k << ": "
                          << scene.sensors[k].spp << " spp); every view renders sensor "
                          << sensors.front() << "'s " << spp << " (--spp sets it)\n";
                break;
            }
        const int spp_grad = a->spp_grad > 0 ? a->spp_grad : spp;
        RestirConfig restir;
        restir.burn_in = a->restir_burn_in;
        restir.direct = restir_direct(a->restir_direct);
        restir.visibility = a->restir_visibility == "on";
        if (a->restir && restir_unsupported(scene).empty()) // else grad() says why not
            std::cerr << "tandem grad: ReSTIR resamples the light sample of each adjoint path's "
                         "first vertex (" << restir.burn_in << " burn-in passes at this theta); "
                         "deeper vertices and the primal image sample lights as before\n";
        ctx.set_stage_timing(true);
        const Session::GradResult result =
            session.grad(loss, std::move(targets), params, spp, spp_grad, a->seed,
                         a->restir ? std::optional<RestirConfig>(restir) : std::nullopt);
        const float value = result.loss;
        const std::vector<StageTime> stages = ctx.stage_times();
        const StepTimes times = StepTimes::from(stages);
        const std::vector<float>& grad = result.gradient;
        const std::uint64_t guards = session.device_scene().read_guards();
        const int exponent = session.state().gradient().exponent.download()[0];

        nlohmann::json out = {{"loss", a->loss},
                              {"loss_value", value},
                              {"spp", spp},
                              {"spp_grad", spp_grad},
                              {"seed", a->seed},
                              {"primal_seconds", times.primal},
                              {"adjoint_seconds", times.adjoint},
                              {"restir_seconds", stage_seconds(stages, "restir")},
                              {"guards", guards},
                              {"reproducible", ctx.device().reproducible()},
                              {"gradient_scale_exponent", exponent},
                              {"parameters", nlohmann::json::array()}};
        if (!a->json)
            std::cout << a->loss << " loss " << value << " (" << spp << " spp primal, " << spp_grad
                      << " spp adjoint)\n";
        for (const Parameter* p : params) {
            const float* g = grad.data() + p->offset;
            nlohmann::json j = {{"name", p->name}, {"size", p->size}};
            if (p->is_array()) {
                const Summary s = summarize(g, p->size);
                j["kind"] = parameter_kind_name(p->kind);
                j["width"] = p->width;
                j["height"] = p->height;
                if (p->kind == Parameter::Kind::volume) {
                    j["depth"] = p->depth;
                    j["channels"] = p->channels;
                }
                if (p->kind == Parameter::Kind::vertices) {
                    // the derivative of a rigid shift: the sum over the vertices
                    double t[3] = {0, 0, 0};
                    for (std::size_t i = 0; i < p->size; ++i) t[i % 3] += g[i];
                    j["translation"] = {t[0], t[1], t[2]};
                    if (!a->json)
                        std::cout << p->name << ": translation " << t[0] << " " << t[1] << " "
                                  << t[2] << "\n";
                }
                j["summary"] = {{"min", s.min},
                                {"max", s.max},
                                {"mean", s.mean},
                                {"l2_norm", s.norm},
                                {"nonzero", s.nonzero}};
                if (!a->json)
                    std::cout << p->name << ": " << parameter_kind_name(p->kind) << " " << p->width
                              << "x" << p->height
                              << ", gradient min " << s.min << ", mean " << s.mean << ", max "
                              << s.max << ", L2 norm " << s.norm << ", " << s.nonzero << " of "
                              << p->size << " nonzero\n";
            } else {
                j["kind"] = parameter_kind_name(p->kind);
                j["gradient"] = std::vector<float>(g, g + p->size);
                if (!a->json) {
                    std::cout << p->name << ":";
                    for (std::size_t i = 0; i < p->size; ++i)
                        std::cout << " " << g[i];
                    std::cout << "\n";
                }
            }
            out["parameters"].push_back(j);
        }
        if (desc.sensors.size() > 1) out["sensors"] = sensors; // whose losses were summed
        if (a->restir)
            out["restir"] = {{"candidates", restir.candidates},
                             {"temporal", restir.temporal},
                             {"spatial", restir.spatial},
                             {"m_cap", restir.m_cap},
                             {"burn_in", restir.burn_in},
                             {"visibility", restir.visibility},
                             {"normal_cos", restir.normal_cos},
                             {"depth_rel", restir.depth_rel},
                             {"direct", restir_direct_name(restir.direct)}};
        if (!a->out_grad.empty()) {
            const Parameter& p = *params[0];
            std::vector<float> g(grad.begin() + p.offset, grad.begin() + p.offset + p.size);
            if (grad_volume) {
                VolumeGrid v; // in the unit cube: the grid's own placement is the scene's
                v.width = p.width;
                v.height = p.height;
                v.depth = p.depth;
                v.channels = p.channels;
                v.values = std::move(g);
                write_volume(a->out_grad, v);
            } else if (grad_vertices) {
                const std::size_t n = p.size / 3;
                if (ends_with(".npy")) {
                    write_npy(a->out_grad, g, n, 3);
                } else { // the mesh as it is now, with the gradient as vertex properties
                    const MeshShape& shape = scene.mesh_shape(p);
                    const std::vector<float> xyz = session.value(p);
                    std::vector<glm::vec3> positions(n);
                    for (std::size_t i = 0; i < n; ++i)
                        positions[i] = {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
                    write_vertex_ply(a->out_grad, positions, scene.shape_triangles(shape), g, "grad");
                }
            } else {
                write_image(a->out_grad, p.width, p.height, g);
            }
            out["out_grad"] = a->out_grad;
        }
        std::cerr << shape_gradient_gaps(scene, params);
        if (guards)
            std::cerr
                << "warning: " << guards
                << " non-finite samples, saturated gradient contributions or wrapped gradient "
                   "sums were dropped or clamped\n";
        if (a->json) std::cout << out.dump(2) << std::endl;
    });
}

} // namespace tandem::cli
