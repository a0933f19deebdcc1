// `tandem optimize` config: parsing and validation.
#include "core/inverse/optimize_config.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <set>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "core/inverse/control_variate.h"
#include "core/inverse/loss.h"
#include "core/inverse/restir.h"
#include "core/io/atomic_file.h"
#include "core/render/boundary_guide.h"
#include "core/render/schedule.h"
#include "runtime/error.h"

namespace tandem {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

/// Resolves `p` relative to the directory of `base` unless it is absolute.
std::string relative_to(const std::string& base, const std::string& p) {
    const fs::path path(p);
    if (path.is_absolute()) return p;
    return (fs::path(base).parent_path() / path).lexically_normal().string();
}

void check_keys(const std::string& where, const json& j, const std::set<std::string>& known) {
    if (!j.is_object()) throw Error(where + ": expected a JSON object");
    for (auto it = j.begin(); it != j.end(); ++it)
        if (!known.count(it.key())) {
            std::string list;
            for (const std::string& k : known)
                list += (list.empty() ? "" : ", ") + k;
            throw Error(where + ": unknown key '" + it.key() + "' (known: " + list + ")");
        }
}

std::vector<std::pair<std::string, std::string>> read_defines(const std::string& where,
                                                              const json& j) {
    std::vector<std::pair<std::string, std::string>> out;
    if (!j.is_object()) throw Error(where + ": 'defines' must be an object of name: value");
    for (auto it = j.begin(); it != j.end(); ++it) {
        if (it.value().is_string())
            out.emplace_back(it.key(), it.value().get<std::string>());
        else if (it.value().is_number())
            out.emplace_back(it.key(), it.value().dump());
        else
            throw Error(where + ": define '" + it.key() + "' must be a string or number");
    }
    return out;
}

/// A JSON number as T, checked first: nlohmann converts numbers with a plain cast, which for a
/// value outside T's range (1e300 as an int, 1e40 as a float) is undefined behaviour, and which
/// silently wraps a negative integer into an unsigned one or truncates 2.5 to 2.
template <class T> T number(const std::string& where, const std::string& key, const json& v) {
    static_assert(sizeof(T) <= 4, "the range checks compare in 64 bits");
    const auto fail = [&](const char* why) {
        throw Error(where + ": '" + key + "' " + why + " (" + v.dump() + ")");
    };
    if (!v.is_number()) fail("has the wrong type");
    if constexpr (std::is_integral_v<T>) {
        if (!v.is_number_integer()) fail("must be an integer");
        const bool fits =
            v.is_number_unsigned()
                ? v.get<std::uint64_t>() <= std::uint64_t(std::numeric_limits<T>::max())
                : v.get<std::int64_t>() >= std::int64_t(std::numeric_limits<T>::min()) &&
                      v.get<std::int64_t>() <= std::int64_t(std::numeric_limits<T>::max());
        if (!fits) fail("is out of range");
        return static_cast<T>(v.get<std::int64_t>());
    } else {
        const double d = v.get<double>();
        if (!(std::fabs(d) <= double(std::numeric_limits<T>::max()))) fail("is out of range");
        return static_cast<T>(d);
    }
}

template <class T> T get(const std::string& where, const json& j, const char* key, T fallback) {
    if (!j.contains(key)) return fallback;
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
        return number<T>(where, key, j.at(key));
    } else {
        try {
            return j.at(key).get<T>();
        } catch (const json::exception&) {
            throw Error(where + ": '" + key + "' has the wrong type (" + j.at(key).dump() + ")");
        }
    }
}

} // namespace

std::optional<SecondaryReuseConfig> secondary_reuse_config(const std::string& where,
                                                           const json& b) {
    if (b.is_boolean())
        return b.get<bool>() ? std::optional<SecondaryReuseConfig>(SecondaryReuseConfig{})
                             : std::nullopt;
    if (!b.is_object()) throw Error(where + " must be true, false or an object");
    check_keys(where, b,
               {"candidates", "neighbours", "m_cap", "cell", "visibility", "receiver", "floor"});
    SecondaryReuseConfig c;
    c.candidates = get<int>(where, b, "candidates", c.candidates);
    c.neighbours = get<int>(where, b, "neighbours", c.neighbours);
    c.m_cap = get<float>(where, b, "m_cap", c.m_cap);
    c.cell = get<float>(where, b, "cell", c.cell);
    c.visibility = get<bool>(where, b, "visibility", c.visibility);
    c.receiver = get<bool>(where, b, "receiver", c.receiver);
    c.floor = get<float>(where, b, "floor", c.floor);
    validate_secondary_reuse(c, where);
    return c;
}

OptimizeConfig load_optimize_config(const std::string& path) {
    OptimizeConfig c;
    c.path = path;
    json j;
    try {
        // A key given twice in one object is an error: nlohmann's parser would keep the last
        // silently, and a config edited by hand can repeat a key it means to change.
        std::vector<std::set<std::string>> keys; // one set per object being read
        j = json::parse(read_file(path), [&](int, json::parse_event_t event, json& parsed) {
            if (event == json::parse_event_t::object_start) keys.emplace_back();
            if (event == json::parse_event_t::object_end) keys.pop_back();
            if (event == json::parse_event_t::key &&
                !keys.back().insert(parsed.get<std::string>()).second)
                throw Error(path + ": key '" + parsed.get<std::string>() +
                            "' is given twice in one object");
            return true;
        });
    } catch (const json::exception& e) {
        // e.what() is "[json.exception.parse_error.101] parse error at line L, column C: ...",
        // or, for a number beyond a double, "[json.exception.out_of_range.406] number overflow
        // parsing '1e400'": the message without its bracketed id
        const std::string what = e.what();
        const std::size_t at = what.rfind("] ", what.find(' '));
        throw Error(path +
                    ": malformed JSON: " + (at == std::string::npos ? what : what.substr(at + 2)));
    }
    check_keys(path, j,
               {"scene", "defines", "target", "params", "optimizer", "beta1", "beta2", "epsilon",
                "iterations", "spp", "spp_grad", "spp_primary", "spp_secondary", "secondary_guide",
                "loss", "seed",
                "checkpoint_every",
                "image_error_spp", "cv", "cv_variance", "restir", "views", "batch"});
    if (!j.contains("scene")) throw Error(path + ": 'scene' is required");
    c.scene = relative_to(path, get<std::string>(path, j, "scene", ""));
    if (j.contains("defines")) c.defines = read_defines(path, j["defines"]);

    if (!j.contains("target"))
        throw Error(path + ": 'target' is required ({\"scene\": FILE, \"spp\": N}, or "
                           "{\"images\": [FILE, ...]} with one image per sensor)");
    const json& t = j["target"];
    check_keys(path + ": target", t, {"image", "images", "masks", "scene", "defines", "spp"});
    if (int(t.contains("image")) + int(t.contains("images")) + int(t.contains("scene")) != 1)
        throw Error(path + ": target needs exactly one of 'scene', 'images' and 'image'");
    auto files = [&](const char* key) {
        const std::string where = path + ": target." + key;
        if (!t[key].is_array() || t[key].empty())
            throw Error(where + " must be a list of file names, one per sensor");
        std::vector<std::string> out;
        for (const json& f : t[key]) {
            if (!f.is_string()) throw Error(where + " must be a list of file names");
            out.push_back(relative_to(path, f.get<std::string>()));
        }
        return out;
    };
    if (t.contains("image")) // one sensor's: the images form with one file
        c.target_images = {relative_to(path, get<std::string>(path, t, "image", ""))};
    if (t.contains("images")) c.target_images = files("images");
    if (t.contains("masks")) {
        if (c.target_images.empty())
            throw Error(path + ": target.masks go with target.images (a photograph's mask)");
        c.target_masks = files("masks");
        if (c.target_masks.size() != c.target_images.size())
            throw Error(path + ": target.masks has " + std::to_string(c.target_masks.size()) +
                        " files, target.images " + std::to_string(c.target_images.size()));
    }
    if (!c.target_images.empty())
        for (const char* key : {"defines", "spp"})
            if (t.contains(key))
                throw Error(path + ": target." + key + " is a target scene's; the target is images");
    if (t.contains("scene"))
        c.target_scene = relative_to(path, get<std::string>(path, t, "scene", ""));
    if (t.contains("defines")) c.target_defines = read_defines(path + ": target", t["defines"]);
    c.target_spp = get<int>(path, t, "spp", c.target_spp);

    if (!j.contains("params") || !j["params"].is_object() || j["params"].empty())
        throw Error(path +
                    ": 'params' must name at least one parameter: {\"NAME\": {\"lr\": 0.01}}");
    for (auto it = j["params"].begin(); it != j["params"].end(); ++it) {
        const std::string where = path + ": params." + it.key();
        check_keys(where, it.value(), {"lr", "init", "upsample", "large_steps"});
        OptimizedParam p;
        p.name = it.key();
        p.lr = get<float>(where, it.value(), "lr", p.lr);
        if (!(p.lr > 0.0f) || !std::isfinite(p.lr)) throw Error(where + ": 'lr' must be positive");
        if (it.value().contains("init")) {
            const json& init = it.value()["init"];
            if (init.is_number()) {
                p.init = {number<float>(where, "init", init)};
            } else if (init.is_array()) {
                for (const json& v : init)
                    p.init.push_back(number<float>(where, "init", v));
            }
            if (p.init.size() != 1 && p.init.size() != 3)
                throw Error(where + ": 'init' must be a number or an [r, g, b] triple");
        }
        if (it.value().contains("large_steps")) {
            p.large_steps = number<float>(where, "large_steps", it.value()["large_steps"]);
            if (!(p.large_steps > 0.0) || !std::isfinite(p.large_steps))
                throw Error(where + ": 'large_steps' must be a positive lambda (Mitsuba's default: 19)");
        }
        if (it.value().contains("upsample")) {
            const json& up = it.value()["upsample"];
            if (!up.is_array() || up.empty())
                throw Error(where + ": 'upsample' must be a list of iterations, e.g. [100, 400]");
            for (const json& v : up) {
                const int i = number<int>(where, "upsample", v);
                if (i < 1 || (!p.upsample.empty() && i <= p.upsample.back()))
                    throw Error(where + ": 'upsample' must list increasing iterations >= 1");
                p.upsample.push_back(i);
            }
        }
        c.params.push_back(p);
    }
    c.optimizer = get<std::string>(path, j, "optimizer", c.optimizer);
    if (c.optimizer != "adam" && c.optimizer != "sgd")
        throw Error(path + ": 'optimizer' must be \"adam\" or \"sgd\"");
    if (c.optimizer == "sgd")
        for (const char* key : {"beta1", "beta2", "epsilon"})
            if (j.contains(key))
                throw Error(path + ": '" + key + "' is Adam's; 'optimizer' is \"sgd\"");
    c.beta1 = get<float>(path, j, "beta1", c.beta1);
    c.beta2 = get<float>(path, j, "beta2", c.beta2);
    c.epsilon = get<float>(path, j, "epsilon", c.epsilon);
    if (!(c.beta1 >= 0.0f && c.beta1 < 1.0f && c.beta2 >= 0.0f && c.beta2 < 1.0f &&
          c.epsilon > 0.0f))
        throw Error(path + ": need 0 <= beta1, beta2 < 1 and epsilon > 0");
    c.iterations = get<int>(path, j, "iterations", c.iterations);
    c.spp = get<int>(path, j, "spp", c.spp);
    c.spp_grad = get<int>(path, j, "spp_grad", c.spp);
    c.boundary.primary = get<int>(path, j, "spp_primary", c.spp_grad);
    c.boundary.secondary = get<int>(path, j, "spp_secondary", c.spp_grad);
    if (c.boundary.primary < 0 || c.boundary.secondary < 0)
        throw Error(path + ": 'spp_primary' and 'spp_secondary' must be at least 0 (0: the term "
                           "left out)");
    c.boundary.guide = secondary_guide_mode(
        get<std::string>(path, j, "secondary_guide", "auto"), path + ": 'secondary_guide'");
    c.loss = get<std::string>(path, j, "loss", c.loss);
    try {
        loss_kind(c.loss); // validates
    } catch (const Error& e) {
        throw Error(path + ": " + e.what());
    }
    if (c.loss == "mean") throw Error(path + ": the mean loss has no target; use l1, l2 or rl2");
    c.seed = get<std::uint32_t>(path, j, "seed", c.seed);
    c.checkpoint_every = get<int>(path, j, "checkpoint_every", c.checkpoint_every);
    c.image_error_spp = get<int>(path, j, "image_error_spp", c.image_error_spp);
    c.cv = get<std::string>(path, j, "cv", c.cv);
    c.cv_variance = get<std::string>(path, j, "cv_variance", c.cv_variance);
    try {
        cv_mode(c.cv);
        cv_variance(c.cv_variance);
    } catch (const Error& e) {
        throw Error(path + ": " + e.what());
    }
    if (j.contains("restir")) {
        const std::string where = path + ": restir";
        const json& r = j["restir"];
        check_keys(where, r,
                   {"adjoint", "primal", "candidates", "temporal", "spatial", "m_cap", "burn_in",
                    "visibility", "normal_cos", "depth_rel", "direct", "boundary"});
        RestirConfig rc;
        rc.adjoint = get<bool>(where, r, "adjoint", rc.adjoint);
        rc.primal = get<bool>(where, r, "primal", rc.primal);
        if (rc.primal && c.cv != "none")
            throw Error(where +
                        ": 'primal': true needs \"cv\": \"none\" (the control variate's "
                        "two states share their paths; docs/restir.md), not \"" +
                        c.cv + "\"");
        rc.candidates = get<int>(where, r, "candidates", rc.candidates);
        rc.temporal = get<bool>(where, r, "temporal", rc.temporal);
        rc.spatial = get<int>(where, r, "spatial", rc.spatial);
        rc.m_cap = get<float>(where, r, "m_cap", rc.m_cap);
        rc.burn_in = get<int>(where, r, "burn_in", rc.burn_in);
        rc.visibility = get<bool>(where, r, "visibility", rc.visibility);
        rc.normal_cos = get<float>(where, r, "normal_cos", rc.normal_cos);
        rc.depth_rel = get<float>(where, r, "depth_rel", rc.depth_rel);
        const std::string direct =
            get<std::string>(where, r, "direct", restir_direct_name(rc.direct));
        try {
            rc.direct = restir_direct(direct);
        } catch (const Error& e) {
            throw Error(where + ": " + e.what());
        }
        validate_restir_config(rc, where);
        if (rc.adjoint || rc.primal) c.restir = rc;
        if (r.contains("boundary")) c.boundary_reuse = secondary_reuse_config(where + ": boundary", r["boundary"]);
    }
    if (j.contains("views")) {
        const json& v = j["views"];
        const std::string where = path + ": views";
        if (v.is_string()) {
            if (v.get<std::string>() != "all")
                throw Error(where + " must be \"all\" or a list of sensors (indices or ids)");
        } else if (v.is_array() && !v.empty()) {
            for (const json& k : v) {
                if (k.is_number_unsigned()) {
                    // a sensor index is an int; a larger one would wrap in a plain cast
                    const std::uint64_t index = k.get<std::uint64_t>();
                    if (index > std::uint64_t(std::numeric_limits<int>::max()))
                        throw Error(where + ": sensor index " + std::to_string(index) +
                                    " is out of range");
                    c.views.push_back(std::to_string(index));
                } else if (k.is_string()) {
                    c.views.push_back(k.get<std::string>());
                } else {
                    throw Error(where + ": a sensor is an index (0, 1, ...) or an id");
                }
            }
        } else {
            throw Error(where + " must be \"all\" or a non-empty list of sensors");
        }
    }
    if (j.contains("batch")) {
        c.batch = get<int>(path, j, "batch", 0);
        if (c.batch < 1) throw Error(path + ": 'batch' must be at least 1 (views per iteration)");
    }
    for (const auto& [name, v] : {std::pair<const char*, int>{"iterations", c.iterations},
                                  {"spp", c.spp},
                                  {"spp_grad", c.spp_grad},
                                  {"checkpoint_every", c.checkpoint_every},
                                  {"image_error_spp", c.image_error_spp},
                                  {"target.spp", c.target_spp}})
        if (v < 1) throw Error(path + ": '" + name + "' must be at least 1");
    // The command line's limit on samples per pixel (tandem render --spp), so that a typo of a
    // few extra zeros is an error, not a run that never ends.
    constexpr int k_max_spp = 1 << 20;
    for (const auto& [name, v] : {std::pair<const char*, int>{"spp", c.spp},
                                  {"spp_grad", c.spp_grad},
                                  {"spp_primary", c.boundary.primary},
                                  {"spp_secondary", c.boundary.secondary},
                                  {"image_error_spp", c.image_error_spp},
                                  {"target.spp", c.target_spp}})
        if (v > k_max_spp)
            throw Error(path + ": '" + name + "' is " + std::to_string(v) + "; at most " +
                        std::to_string(k_max_spp));
    if (c.boundary_reuse &&
        std::none_of(c.params.begin(), c.params.end(), [](const OptimizedParam& p) {
            const std::string suffix = ".vertex_positions";
            return p.name.size() > suffix.size() &&
                   p.name.compare(p.name.size() - suffix.size(), suffix.size(), suffix) == 0;
        }))
        throw Error(path + ": restir.boundary reuses the boundary term of shape gradients, and no "
                           "vertex_positions parameter is optimized");
    for (const OptimizedParam& p : c.params)
        if (!p.upsample.empty() && p.upsample.back() >= c.iterations)
            throw Error(path + ": params." + p.name + ": 'upsample' lists iteration " +
                        std::to_string(p.upsample.back()) + ", not before the last (" +
                        std::to_string(c.iterations) + ")");
    return c;
}

} // namespace tandem
