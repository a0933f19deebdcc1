// `tandem params SCENE.xml [-D name=value]... [--json]`: the scene's differentiable parameters.
#include <cmath>
#include <iomanip>
#include <iostream>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "core/scene/params.h"
#include "core/scene/render_scene.h"
#include "runtime/error.h"

namespace tandem::cli {

namespace {

/// Min, mean and max of a parameter's values.
void summary(const std::vector<float>& v, const Parameter& p, float* lo, float* mean, float* hi) {
    double sum = 0;
    *lo = v[p.offset];
    *hi = v[p.offset];
    for (std::size_t i = p.offset; i < p.offset + p.size; ++i) {
        *lo = std::min(*lo, v[i]);
        *hi = std::max(*hi, v[i]);
        sum += v[i];
    }
    *mean = static_cast<float>(sum / double(p.size));
}


} // namespace

void add_params_command(CLI::App& app, GlobalOptions&) {
    CLI::App* cmd = app.add_subcommand("params", "List a scene's differentiable parameters");
    auto scene = std::make_shared<std::string>();
    auto defines = std::make_shared<std::vector<std::string>>();
    auto json = std::make_shared<bool>(false);
    cmd->add_option("scene", *scene, "scene file")->required()->check(CLI::ExistingFile);
    cmd->add_option("-D", *defines, "override a <default>: name=value (repeatable)");
    cmd->add_flag("--json", *json, "print JSON");
    cmd->callback([scene, defines, json] {
        const SceneDesc desc = load_scene(*scene, parse_defines(*defines));
        const RenderScene rs = build_render_scene(desc);
        const ParamRegistry& reg = rs.params;
        const std::vector<float>& v = reg.values();
        nlohmann::json out = nlohmann::json::array();
        for (const Parameter& p : reg.parameters()) {
            float lo, mean, hi;
            summary(v, p, &lo, &mean, &hi);
            if (*json) {
                nlohmann::json j = {{"name", p.name},
                                    {"kind", parameter_kind_name(p.kind)},
                                    {"offset", p.offset},
                                    {"size", p.size},
                                    {"lower", p.lower},
                                    {"upper", std::isinf(p.upper) ? nlohmann::json("inf")
                                                                  : nlohmann::json(p.upper)}};
                if (p.kind == Parameter::Kind::volume)
                    j["summary"] = {{"width", p.width},   {"height", p.height},
                                    {"depth", p.depth},   {"channels", p.channels},
                                    {"min", lo},          {"mean", mean},
                                    {"max", hi}};
                else if (p.kind == Parameter::Kind::vertices)
                    j["summary"] = {{"vertices", p.width}, {"min", lo}, {"mean", mean}, {"max", hi}};
                else if (p.kind == Parameter::Kind::texture)
                    j["summary"] = {{"width", p.width},
                                    {"height", p.height},
                                    {"min", lo},
                                    {"mean", mean},
                                    {"max", hi}};
                else
                    j["value"] =
                        std::vector<float>(v.begin() + p.offset, v.begin() + p.offset + p.size);
                out.push_back(j);
                continue;
            }
            std::cout << std::left << std::setw(32) << p.name << std::setw(9) << parameter_kind_name(p.kind)
                      << std::setw(8) << p.size;
            if (p.kind == Parameter::Kind::volume)
                std::cout << p.width << "x" << p.height << "x" << p.depth << " voxels of "
                          << p.channels << ", min " << lo << ", mean " << mean << ", max " << hi;
            else if (p.kind == Parameter::Kind::texture)
                std::cout << p.width << "x" << p.height << " texels, min " << lo << ", mean "
                          << mean << ", max " << hi;
            else if (p.kind == Parameter::Kind::vertices)
                std::cout << p.width << " vertices, coordinates min " << lo << ", mean " << mean
                          << ", max " << hi;
            else
                for (std::size_t i = p.offset; i < p.offset + p.size; ++i)
                    std::cout << v[i] << " ";
            std::cout << " in [" << p.lower << ", " << p.upper << "]\n";
        }
        if (*json) std::cout << out.dump(2) << std::endl;
    });
}

} // namespace tandem::cli
