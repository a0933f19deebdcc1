// `tandem render SCENE.xml [-D name=value]... [--spp N] [--seed S] [--out FILE] [--json]`.
#include <filesystem>
#include <iostream>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "core/inverse/session.h"
#include "core/io/image_io.h"
#include "core/render/features.h"
#include "runtime/error.h"

namespace tandem::cli {

namespace {

struct RenderArgs {
    std::string scene;
    std::vector<std::string> out{"render.exr"};
    std::vector<std::string> defines;
    int spp = 0;
    unsigned seed = 0;
    std::string sensor = "0";
    bool json = false, print_features = false;
};

} // namespace

std::vector<std::pair<std::string, std::string>> parse_defines(const std::vector<std::string>& ds) {
    std::vector<std::pair<std::string, std::string>> out;
    for (const std::string& d : ds) {
        const std::size_t eq = d.find('=');
        if (eq == std::string::npos || eq == 0) throw Error("-D " + d + ": expected name=value");
        out.emplace_back(d.substr(0, eq), d.substr(eq + 1));
    }
    return out;
}

std::vector<unsigned> chosen_sensors(const std::vector<Camera>& sensors, const std::string& key) {
    std::vector<unsigned> out;
    if (key == "all")
        for (unsigned k = 0; k < sensors.size(); ++k) out.push_back(k);
    else
        out.push_back(static_cast<unsigned>(find_sensor(sensors, key)));
    return out;
}

std::string sensor_path(const std::string& path, unsigned k, bool several) {
    if (!several) return path;
    const std::filesystem::path p(path);
    return (p.parent_path() / (p.stem().string() + "_" + std::to_string(k) + p.extension().string()))
        .string();
}

void draw_progress(int done, int total, const char* unit) {
    const int width = 40, filled = total > 0 ? width * done / total : width;
    std::cerr << "\r[" << std::string(filled, '#') << std::string(width - filled, ' ') << "] "
              << done << "/" << total << " " << unit << (done == total ? "\n" : "") << std::flush;
}

void add_render_command(CLI::App& app, GlobalOptions& global) {
    CLI::App* cmd = app.add_subcommand("render", "Render a scene (Mitsuba 3 XML subset)");
    auto args = std::make_shared<RenderArgs>();
    cmd->add_option("scene", args->scene, "scene file")->required()->check(CLI::ExistingFile);
    cmd->add_option("-D", args->defines, "override a <default>: name=value (repeatable)");
    cmd->add_option("--spp", args->spp, "samples per pixel (default: the scene's sampler)")
        ->check(CLI::Range(1, 1 << 20));
    cmd->add_option("--seed", args->seed, "random seed")->capture_default_str();
    cmd->add_option("--sensor", args->sensor,
                    "the sensor to render: its index in file order or its id; 'all' renders "
                    "every one, into NAME_K.EXT")
        ->capture_default_str();
    cmd->add_option("--out", args->out,
                    "output image (.exr: linear float; .png: sRGB 8-bit); repeat for several")
        ->capture_default_str();
    cmd->add_option("--device", global.device, "OpenCL device: index or name substring");
    cmd->add_flag("--json", args->json, "print timing and statistics as JSON");
    cmd->add_flag("--print-features", args->print_features,
                  "print the kernel build options for this scene and exit");
    cmd->callback([args, &global] {
        for (const std::string& path : args->out) check_image_output(path); // before the work
        const SceneDesc desc = load_scene(args->scene, parse_defines(args->defines));
        const std::vector<unsigned> sensors = chosen_sensors(desc.sensors, args->sensor);
        const bool several = args->sensor == "all" && desc.sensors.size() > 1;
        RenderScene scene = build_render_scene(desc);
        Context ctx = Context::create(global.device, global.tuning);
        if (args->print_features) {
            const BuildFlags features = forward_render_features(scene, ctx);
            std::cout << "features:";
            for (const auto& [name, value] : features.flags())
                std::cout << " " << name << "=" << value;
            std::cout << "\nbuild options: " << base_build_options(ctx.device(), ctx.tuning()) << " "
                      << features.options() << "\n";
            return;
        }
        SessionOptions forward;
        forward.kernels = SessionOptions::Kernels::forward;
        Session session(ctx, KernelLibrary::from_tuning(global.tuning), std::move(scene), forward);
        RenderOptions opt;
        opt.spp = args->spp;
        opt.seed = args->seed;
        if (isatty(STDERR_FILENO) && !args->json)
            opt.progress = [](int done, int total) { draw_progress(done, total, "spp"); };
        ctx.set_stage_timing(args->json); // kernel_seconds
        nlohmann::json views = nlohmann::json::array();
        for (unsigned k : sensors) {
            const RenderResult r = session.render_image(opt, k); // the scene's parameter values
            std::vector<std::string> outs;
            for (const std::string& path : args->out) {
                outs.push_back(sensor_path(path, k, several));
                write_image(outs.back(), r.width, r.height, r.rgb);
            }
            const double sps = double(r.width) * r.height * r.spp / r.seconds;
            if (args->json) {
                views.push_back(nlohmann::json{{"sensor", k},
                                               {"seconds", r.seconds},
                                               {"kernel_seconds", r.kernel_seconds},
                                               {"samples_per_second", sps},
                                               {"width", r.width},
                                               {"height", r.height},
                                               {"spp", r.spp},
                                               {"nan_guards", r.nan_guards},
                                               {"reproducible", ctx.device().reproducible()},
                                               {"outputs", outs}});
            } else {
                std::cout << CLI::detail::join(outs, ", ") << ": " << r.width << "x" << r.height
                          << ", " << r.spp << " spp in " << r.seconds << " s (" << sps / 1e6
                          << " M samples/s)"
                          << (r.nan_guards ? ", " + std::to_string(r.nan_guards) +
                                                 " non-finite samples dropped"
                                           : "")
                          << "\n";
            }
        }
        // one sensor: its object, as ever; several: one object per sensor
        if (args->json) std::cout << (several ? views : views[0]).dump(2) << std::endl;
    });
}

} // namespace tandem::cli
