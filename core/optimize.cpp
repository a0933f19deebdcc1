// `tandem optimize`: the optimization loop, its config, metrics, checkpoints and outputs.
#include "core/optimize.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "core/atomic_file.h"
#include "core/image_io.h"
#include "core/inverse.h"
#include "core/plot.h"
#include "runtime/error.h"

namespace tandem {

namespace fs = std::filesystem;
using nlohmann::json;

// ---- config ----

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
            for (const std::string& k : known) list += (list.empty() ? "" : ", ") + k;
            throw Error(where + ": unknown key '" + it.key() + "' (known: " + list + ")");
        }
}

std::vector<std::pair<std::string, std::string>> read_defines(const std::string& where, const json& j) {
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

template <class T> T get(const std::string& where, const json& j, const char* key, T fallback) {
    if (!j.contains(key)) return fallback;
    try {
        return j.at(key).get<T>();
    } catch (const json::exception&) {
        throw Error(where + ": '" + key + "' has the wrong type (" + j.at(key).dump() + ")");
    }
}

} // namespace

OptimizeConfig load_optimize_config(const std::string& path) {
    OptimizeConfig c;
    c.path = path;
    json j;
    try {
        j = json::parse(read_file(path));
    } catch (const json::parse_error& e) {
        // e.what() is "[json.exception.parse_error.101] parse error at line L, column C: ..."
        std::string what = e.what();
        const std::size_t at = what.find("parse error");
        throw Error(path + ": malformed JSON: " + (at == std::string::npos ? what : what.substr(at)));
    }
    check_keys(path, j, {"scene", "defines", "target", "params", "optimizer", "beta1", "beta2",
                         "epsilon", "iterations", "spp", "spp_grad", "loss", "seed",
                         "checkpoint_every", "image_error_spp", "cv"});
    if (!j.contains("scene")) throw Error(path + ": 'scene' is required");
    c.scene = relative_to(path, get<std::string>(path, j, "scene", ""));
    if (j.contains("defines")) c.defines = read_defines(path, j["defines"]);

    if (!j.contains("target")) throw Error(path + ": 'target' is required ({\"image\": FILE} or {\"scene\": FILE, \"spp\": N})");
    const json& t = j["target"];
    check_keys(path + ": target", t, {"image", "scene", "defines", "spp"});
    if (t.contains("image") == t.contains("scene"))
        throw Error(path + ": target needs exactly one of 'image' and 'scene'");
    if (t.contains("image")) c.target_image = relative_to(path, get<std::string>(path, t, "image", ""));
    if (t.contains("scene")) c.target_scene = relative_to(path, get<std::string>(path, t, "scene", ""));
    if (t.contains("defines")) c.target_defines = read_defines(path + ": target", t["defines"]);
    c.target_spp = get<int>(path, t, "spp", c.target_spp);

    if (!j.contains("params") || !j["params"].is_object() || j["params"].empty())
        throw Error(path + ": 'params' must name at least one parameter: {\"NAME\": {\"lr\": 0.01}}");
    for (auto it = j["params"].begin(); it != j["params"].end(); ++it) {
        const std::string where = path + ": params." + it.key();
        check_keys(where, it.value(), {"lr", "init"});
        OptimizedParam p;
        p.name = it.key();
        p.lr = get<float>(where, it.value(), "lr", p.lr);
        if (!(p.lr > 0.0f) || !std::isfinite(p.lr)) throw Error(where + ": 'lr' must be positive");
        if (it.value().contains("init")) {
            const json& init = it.value()["init"];
            if (init.is_number())
                p.init = {init.get<float>()};
            else
                p.init = get<std::vector<float>>(where, it.value(), "init", {});
            if (p.init.size() != 1 && p.init.size() != 3)
                throw Error(where + ": 'init' must be a number or an [r, g, b] triple");
        }
        c.params.push_back(p);
    }
    c.optimizer = get<std::string>(path, j, "optimizer", c.optimizer);
    if (c.optimizer != "adam" && c.optimizer != "sgd")
        throw Error(path + ": 'optimizer' must be \"adam\" or \"sgd\"");
    c.beta1 = get<float>(path, j, "beta1", c.beta1);
    c.beta2 = get<float>(path, j, "beta2", c.beta2);
    c.epsilon = get<float>(path, j, "epsilon", c.epsilon);
    if (!(c.beta1 >= 0.0f && c.beta1 < 1.0f && c.beta2 >= 0.0f && c.beta2 < 1.0f && c.epsilon > 0.0f))
        throw Error(path + ": need 0 <= beta1, beta2 < 1 and epsilon > 0");
    c.iterations = get<int>(path, j, "iterations", c.iterations);
    c.spp = get<int>(path, j, "spp", c.spp);
    c.spp_grad = get<int>(path, j, "spp_grad", c.spp);
    c.loss = get<std::string>(path, j, "loss", c.loss);
    loss_kind(c.loss); // validates
    if (c.loss == "mean") throw Error(path + ": the mean loss has no target; use l1, l2 or rl2");
    c.seed = get<std::uint32_t>(path, j, "seed", c.seed);
    c.checkpoint_every = get<int>(path, j, "checkpoint_every", c.checkpoint_every);
    c.image_error_spp = get<int>(path, j, "image_error_spp", c.image_error_spp);
    c.cv = get<std::string>(path, j, "cv", c.cv);
    try {
        cv_mode(c.cv);
    } catch (const Error& e) {
        throw Error(path + ": " + e.what());
    }
    for (const auto& [name, v] : {std::pair<const char*, int>{"iterations", c.iterations},
                                  {"spp", c.spp}, {"spp_grad", c.spp_grad},
                                  {"checkpoint_every", c.checkpoint_every},
                                  {"image_error_spp", c.image_error_spp}, {"target.spp", c.target_spp}})
        if (v < 1) throw Error(path + ": '" + name + "' must be at least 1");
    return c;
}

// ---- the run ----

namespace {

struct MetricsRow {
    int iteration = 0;
    double seconds = 0.0;
    float loss = 0.0f;
    double param_error = -1.0, image_error = -1.0, alpha_mean = -1.0; ///< -1: not measured
};

/// FNV-1a over what a checkpoint must agree on to be resumed: the scene file and its defines, the
/// target, the scene's parameter layout, the film, and the settings that shape the trajectory.
std::uint64_t run_fingerprint(const RenderScene& scene, const OptimizeConfig& c) {
    std::ostringstream s;
    s << std::setprecision(9) << c.scene << ';';
    for (const auto& [k, v] : c.defines) s << k << '=' << v << ';';
    s << c.target_image << ';' << c.target_scene << ';' << c.target_spp << ';';
    for (const auto& [k, v] : c.target_defines) s << k << '=' << v << ';';
    for (const Parameter& p : scene.params.parameters()) s << p.name << ':' << p.size << ';';
    s << scene.camera.width << 'x' << scene.camera.height << ';' << c.optimizer << ';' << c.beta1
      << ';' << c.beta2 << ';' << c.epsilon << ';' << c.spp << ';' << c.spp_grad << ';' << c.loss
      << ';' << c.seed << ';' << c.cv << ';';
    for (const OptimizedParam& p : c.params) {
        s << p.name << '=' << p.lr;
        for (float v : p.init) s << ',' << v;
        s << ';';
    }
    std::uint64_t h = 1469598103934665603ull;
    for (unsigned char ch : s.str()) h = (h ^ ch) * 1099511628211ull;
    return h;
}

constexpr char k_magic[8] = {'T', 'N', 'D', 'M', 'C', 'K', 'P', '2'};

template <class T> void put(std::string& out, const T& v) {
    out.append(reinterpret_cast<const char*>(&v), sizeof(T));
}
template <class T> void put_vec(std::string& out, const std::vector<T>& v) {
    put<std::uint64_t>(out, v.size());
    out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

struct Reader {
    const std::string& data;
    const std::string& path;
    std::size_t pos = 0;
    template <class T> T get() {
        if (pos + sizeof(T) > data.size()) throw Error(path + ": truncated checkpoint");
        T v;
        std::memcpy(&v, data.data() + pos, sizeof(T));
        pos += sizeof(T);
        return v;
    }
    template <class T> std::vector<T> get_vec(std::size_t expected) {
        const auto n = get<std::uint64_t>();
        if (n != expected) throw Error(path + ": checkpoint holds " + std::to_string(n) +
                                       " values where this run has " + std::to_string(expected));
        if (pos + n * sizeof(T) > data.size()) throw Error(path + ": truncated checkpoint");
        std::vector<T> v(n);
        std::memcpy(v.data(), data.data() + pos, n * sizeof(T));
        pos += n * sizeof(T);
        return v;
    }
};

struct Checkpoint {
    int iterations_done = 0;
    unsigned optimizer_steps = 0;
    double seconds = 0.0;
    std::vector<float> params, m, v;
    std::vector<float> params_old;       ///< theta_n of the last iteration (control variate)
    std::vector<gpu::CvState> cv_state;  ///< per image element (control variate)
    std::vector<MetricsRow> rows;
};

void save_checkpoint(const std::string& path, std::uint64_t fingerprint, const Checkpoint& c) {
    std::string out(k_magic, sizeof(k_magic));
    put(out, fingerprint);
    put<std::int32_t>(out, c.iterations_done);
    put<std::uint32_t>(out, c.optimizer_steps);
    put(out, c.seconds);
    put_vec(out, c.params);
    put_vec(out, c.m);
    put_vec(out, c.v);
    put_vec(out, c.params_old);
    put_vec(out, c.cv_state);
    put<std::uint64_t>(out, c.rows.size());
    for (const MetricsRow& r : c.rows) {
        put<std::int32_t>(out, r.iteration);
        put(out, r.seconds);
        put(out, r.loss);
        put(out, r.param_error);
        put(out, r.image_error);
        put(out, r.alpha_mean);
    }
    write_file_atomic(path, out);
}

Checkpoint load_checkpoint(const std::string& path, std::uint64_t fingerprint, std::size_t count,
                           std::size_t cv_count) {
    if (!fs::exists(path)) throw Error(path + ": no checkpoint to resume from");
    const std::string data = read_file(path);
    if (data.size() < sizeof(k_magic) || std::memcmp(data.data(), k_magic, sizeof(k_magic)) != 0)
        throw Error(path + ": not a Tandem checkpoint");
    Reader r{data, path};
    r.pos = sizeof(k_magic);
    if (r.get<std::uint64_t>() != fingerprint)
        throw Error(path + ": the checkpoint is from another scene or optimization setup "
                           "(parameters, film, loss, seed, spp or learning rates differ)");
    Checkpoint c;
    c.iterations_done = r.get<std::int32_t>();
    c.optimizer_steps = r.get<std::uint32_t>();
    c.seconds = r.get<double>();
    c.params = r.get_vec<float>(count);
    c.m = r.get_vec<float>(count);
    c.v = r.get_vec<float>(count);
    c.params_old = r.get_vec<float>(cv_count ? count : 0);
    c.cv_state = r.get_vec<gpu::CvState>(cv_count);
    const auto rows = r.get<std::uint64_t>();
    for (std::uint64_t i = 0; i < rows; ++i) {
        MetricsRow m;
        m.iteration = r.get<std::int32_t>();
        m.seconds = r.get<double>();
        m.loss = r.get<float>();
        m.param_error = r.get<double>();
        m.image_error = r.get<double>();
        m.alpha_mean = r.get<double>();
        c.rows.push_back(m);
    }
    return c;
}

std::string metrics_csv(const std::vector<MetricsRow>& rows) {
    std::ostringstream s;
    s << "iteration,seconds,loss,param_error,image_error,alpha_mean\n" << std::setprecision(9);
    for (const MetricsRow& r : rows) {
        s << r.iteration << ',' << r.seconds << ',' << r.loss << ',';
        if (r.param_error >= 0.0) s << r.param_error;
        s << ',';
        if (r.image_error >= 0.0) s << r.image_error;
        s << ',';
        if (r.alpha_mean >= 0.0) s << r.alpha_mean;
        s << '\n';
    }
    return s.str();
}

void write_convergence_plot(const std::string& path, const std::vector<MetricsRow>& rows) {
    PlotSeries loss{"loss", {}, {}}, perr{"parameter RMSE", {}, {}}, ierr{"image RMSE", {}, {}};
    for (const MetricsRow& r : rows) {
        loss.x.push_back(r.iteration);
        loss.y.push_back(r.loss);
        if (r.param_error >= 0.0) perr.x.push_back(r.iteration), perr.y.push_back(r.param_error);
        if (r.image_error >= 0.0) ierr.x.push_back(r.iteration), ierr.y.push_back(r.image_error);
    }
    PlotOptions opt;
    opt.title = "convergence";
    opt.y_label = "error";
    write_plot(path, {loss, perr, ierr}, opt);
}

double rmse(const std::vector<float>& a, const std::vector<float>& b) {
    double s = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) s += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
    return a.empty() ? 0.0 : std::sqrt(s / double(a.size()));
}

/// A file name for a parameter: its name with anything but [A-Za-z0-9._-] replaced by '_'.
std::string file_name(const std::string& name) {
    std::string out = name;
    for (char& ch : out)
        if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '.' && ch != '-' && ch != '_') ch = '_';
    return out;
}

std::string iteration_name(const char* prefix, int it) {
    std::ostringstream s;
    s << prefix << std::setw(4) << std::setfill('0') << it << ".exr";
    return s.str();
}

} // namespace

OptimizeSummary run_optimization(Context& ctx, const KernelLibrary& lib, const OptimizeConfig& c,
                                 const OptimizeOptions& o) {
    const auto t_start = std::chrono::steady_clock::now();
    fs::create_directories(o.out_dir);
    const fs::path out(o.out_dir);
    const SceneDesc desc = load_scene(c.scene, c.defines);
    const RenderScene scene = build_render_scene(desc);
    const ParamRegistry& reg = scene.params;
    const std::size_t count = reg.size();

    // The optimized parameters: learning rates (0 elsewhere), ranges, start values.
    std::vector<float> values = reg.values(), lr(count, 0.0f);
    std::vector<const Parameter*> optimized;
    for (const OptimizedParam& p : c.params) {
        const Parameter& q = reg.find(p.name);
        optimized.push_back(&q);
        std::fill_n(lr.begin() + q.offset, q.size, p.lr);
        if (p.init.size() == 1) std::fill_n(values.begin() + q.offset, q.size, p.init[0]);
        if (p.init.size() == 3) {
            if (q.kind == Parameter::Kind::scalar)
                throw Error(c.path + ": params." + p.name + ": a scalar takes one 'init' value");
            for (std::size_t i = 0; i < q.size; ++i) values[q.offset + i] = p.init[i % 3];
        }
        for (std::size_t i = q.offset; i < q.offset + q.size; ++i)
            if (!(values[i] >= q.lower && values[i] <= q.upper))
                throw Error(c.path + ": params." + p.name + ": 'init' is outside [" +
                            std::to_string(q.lower) + ", " + std::to_string(q.upper) + "]");
    }

    Renderer renderer(ctx, lib, scene);
    const std::size_t pixels = std::size_t(scene.camera.width) * scene.camera.height;

    // The target, and the reference parameter values when it comes from a scene.
    std::vector<float> target, reference_values;
    if (!c.target_image.empty()) {
        int w = 0, h = 0;
        target = read_image(c.target_image, &w, &h, true);
        if (unsigned(w) != scene.camera.width || unsigned(h) != scene.camera.height)
            throw Error(c.target_image + ": the target is " + std::to_string(w) + "x" + std::to_string(h) +
                        ", the scene renders " + std::to_string(scene.camera.width) + "x" +
                        std::to_string(scene.camera.height));
    } else {
        const SceneDesc tdesc = load_scene(c.target_scene, c.target_defines);
        const RenderScene tscene = build_render_scene(tdesc);
        if (tscene.camera.width != scene.camera.width || tscene.camera.height != scene.camera.height)
            throw Error(c.target_scene + ": the target scene's film differs from the scene's");
        Renderer tr(ctx, lib, tscene);
        RenderOptions ro;
        ro.spp = c.target_spp;
        ro.seed = primal_seed(c.seed ^ 0x5bd1e995u, 0xFFFFFFFFu); // a stream no iteration uses
        target = tr.render(ro).rgb;
        for (const Parameter* p : optimized) {
            const Parameter& q = tscene.params.find(p->name);
            if (q.size != p->size)
                throw Error(c.target_scene + ": parameter " + p->name + " has " + std::to_string(q.size) +
                            " values, the scene's has " + std::to_string(p->size));
            reference_values.insert(reference_values.end(), tscene.params.values().begin() + q.offset,
                                    tscene.params.values().begin() + q.offset + q.size);
        }
    }
    write_image((out / "target.exr").string(), int(scene.camera.width), int(scene.camera.height), target);

    GradientStep step(ctx, lib, renderer, loss_kind(c.loss), target);
    std::string plan_reason;
    const CvMode plan = plan_cv(cv_mode(c.cv), optimized, &plan_reason);
    step.enable_cv(plan);
    std::cerr << "tandem optimize: " << plan_reason << "\n";
    Buffer<float> params_old(ctx, "parameters (previous state)", count);
    Optimizer optimizer(ctx, lib, c.optimizer == "adam" ? Optimizer::Method::adam : Optimizer::Method::sgd,
                        count, c.beta1, c.beta2, c.epsilon);
    Buffer<float>& params = renderer.parameters();
    Buffer<float> lr_buf(ctx, "learning rates", lr), lower(ctx, "lower bounds", reg.lower_bounds()),
        upper(ctx, "upper bounds", reg.upper_bounds());
    Buffer<float> eval_image(ctx, "evaluation image", 3 * pixels);

    const std::uint64_t fingerprint = run_fingerprint(scene, c);
    const std::string checkpoint_path = (out / "checkpoint.bin").string();
    std::vector<MetricsRow> rows;
    int start = 0;
    double seconds_before = 0.0;
    if (o.resume) {
        Checkpoint ck = load_checkpoint(checkpoint_path, fingerprint, count,
                                        plan == CvMode::none ? 0 : 3 * pixels);
        values = ck.params;
        optimizer.first_moment().upload(ck.m);
        optimizer.second_moment().upload(ck.v);
        optimizer.set_steps_taken(ck.optimizer_steps);
        start = ck.iterations_done;
        rows = ck.rows;
        seconds_before = ck.seconds;
        if (plan != CvMode::none) {
            params_old.upload(ck.params_old);
            step.cv_state().upload(ck.cv_state);
        }
    }
    params.upload(values);
    if (!o.resume) params_old.copy_from(params); // iteration 0: the old state is the new one

    auto optimized_values = [&](const std::vector<float>& all) {
        std::vector<float> v;
        for (const Parameter* p : optimized)
            v.insert(v.end(), all.begin() + p->offset, all.begin() + p->offset + p->size);
        return v;
    };
    const std::uint32_t eval_seed = primal_seed(c.seed ^ 0x68e31da4u, 0xFFFFFFFFu);

    OptimizeSummary summary;
    summary.cv_plan = plan_reason;
    const int end = o.until > 0 ? std::min(o.until, c.iterations) : c.iterations;
    step.warm_up(params); // kernel compilation is not part of any iteration's time
    optimizer.warm_up();
    double optimize_seconds = 0.0; // the iterations proper, without measurements and outputs
    for (int it = start; it < end; ++it) {
        const auto t0 = std::chrono::steady_clock::now();
        MetricsRow row;
        row.iteration = it + 1;
        const std::uint32_t sp = primal_seed(c.seed, std::uint32_t(it)), sa = adjoint_seed(c.seed, std::uint32_t(it));
        if (plan == CvMode::none) {
            row.loss = step.evaluate(params, sp, c.spp, sa, c.spp_grad);
        } else {
            row.loss = step.evaluate_cv(params, params_old, unsigned(it), sp, c.spp, sa, c.spp_grad);
            params_old.copy_from(params); // theta_n becomes the next iteration's old state
        }
        optimizer.step(params, step.gradient(), lr_buf, lower, upper);
        ctx.finish();
        const double iter_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        optimize_seconds += iter_seconds;

        // Measurements (not timed): parameter error, mean alpha, and every K iterations a re-render.
        std::vector<gpu::CvState> cv_now;
        if (plan != CvMode::none) {
            cv_now = step.cv_state().download();
            double sum = 0.0;
            for (const gpu::CvState& st : cv_now) sum += st.alpha;
            row.alpha_mean = sum / double(cv_now.size());
        }
        const std::vector<float> now = params.download();
        for (float v : now)
            if (!std::isfinite(v)) throw Error("iteration " + std::to_string(it + 1) + ": a parameter became non-finite");
        summary.primal_seconds += step.times().primal;
        summary.adjoint_seconds += step.times().adjoint;
        summary.other_seconds += iter_seconds - step.times().primal - step.times().adjoint;
        if (!reference_values.empty()) row.param_error = rmse(optimized_values(now), reference_values);
        const bool milestone = (it + 1) % c.checkpoint_every == 0 || it + 1 == end;
        if (milestone) {
            renderer.render_image(params, eval_seed, c.image_error_spp, eval_image);
            const std::vector<float> img = eval_image.download();
            row.image_error = rmse(img, target);
            write_image((out / iteration_name("iter_", it + 1)).string(), int(scene.camera.width),
                        int(scene.camera.height), img);
            if (plan != CvMode::none) {
                std::vector<float> alpha(cv_now.size()), var(cv_now.size());
                for (std::size_t i = 0; i < cv_now.size(); ++i) {
                    alpha[i] = cv_now[i].alpha;
                    var[i] = cv_now[i].var_cv;
                }
                write_image((out / iteration_name("alpha_", it + 1)).string(), int(scene.camera.width),
                            int(scene.camera.height), alpha);
                write_image((out / iteration_name("variance_", it + 1)).string(), int(scene.camera.width),
                            int(scene.camera.height), var);
            }
        }
        row.seconds = seconds_before + optimize_seconds;
        rows.push_back(row);
        write_file_atomic((out / "metrics.csv").string(), metrics_csv(rows));
        if (milestone) {
            Checkpoint ck;
            ck.iterations_done = it + 1;
            ck.optimizer_steps = optimizer.steps_taken();
            ck.seconds = row.seconds;
            ck.params = now;
            ck.m = optimizer.first_moment().download();
            ck.v = optimizer.second_moment().download();
            if (plan != CvMode::none) {
                ck.params_old = params_old.download();
                ck.cv_state = cv_now;
            }
            ck.rows = rows;
            save_checkpoint(checkpoint_path, fingerprint, ck);
            write_convergence_plot((out / "convergence.png").string(), rows);
        }
        if (o.progress) o.progress(it + 1, c.iterations, row.loss);
    }

    // Final parameters: values in params.json, textures as images.
    const std::vector<float> final_values = params.download();
    json pj = json::object();
    for (const Parameter* p : optimized) {
        if (p->kind == Parameter::Kind::texture) {
            const std::vector<float> texels(final_values.begin() + p->offset,
                                            final_values.begin() + p->offset + p->size);
            const std::string base = file_name(p->name);
            write_image((out / (base + ".exr")).string(), p->width, p->height, texels);
            write_image((out / (base + ".png")).string(), p->width, p->height, texels);
            pj[p->name] = {{"texture", base + ".exr"}, {"width", p->width}, {"height", p->height}};
        } else {
            pj[p->name] = std::vector<float>(final_values.begin() + p->offset,
                                             final_values.begin() + p->offset + p->size);
        }
    }
    write_file_atomic((out / "params.json").string(), pj.dump(2) + "\n");
    if (!rows.empty()) write_convergence_plot((out / "convergence.png").string(), rows);

    summary.iterations_done = end > start ? end : start;
    if (!rows.empty()) {
        summary.final_loss = rows.back().loss;
        summary.param_error = rows.back().param_error;
        summary.alpha_mean = rows.back().alpha_mean;
        for (const MetricsRow& r : rows)
            if (r.image_error >= 0.0) summary.image_error = r.image_error;
    }
    summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    return summary;
}

} // namespace tandem
