// Checkpoints of `tandem optimize`.
#include "core/inverse/checkpoint.h"

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "core/io/atomic_file.h"
#include "core/io/binary.h"
#include "core/io/digest.h"
#include "core/io/sections.h"
#include "core/scene/scene.h"
#include "runtime/error.h"

namespace tandem {

namespace fs = std::filesystem;

namespace {

/// Version 5: checksummed sections (core/io/sections.h). Version 4 was one unchecked record.
constexpr char k_magic[8] = {'T', 'N', 'D', 'M', 'C', 'K', 'P', '5'};

std::string text(const std::vector<std::pair<std::string, std::string>>& defines) {
    std::string s;
    for (const auto& [k, v] : defines)
        s += (s.empty() ? "" : ",") + k + '=' + v;
    return s;
}

/// The settings that shape the trajectory, as key and value.
std::vector<RunInputs::Setting> settings(const RenderScene& scene, const OptimizeConfig& c) {
    std::vector<RunInputs::Setting> out;
    const auto set = [&](const std::string& key, const auto& value) {
        std::ostringstream s;
        s << std::setprecision(9) << value;
        out.push_back({key, s.str()});
    };
    set("defines", text(c.defines));
    if (!c.target_scene.empty()) { // a target image is an input file
        set("target.defines", text(c.target_defines));
        set("target.spp", c.target_spp);
    }
    set("optimizer", c.optimizer);
    set("beta1", c.beta1);
    set("beta2", c.beta2);
    set("epsilon", c.epsilon);
    set("spp", c.spp);
    set("spp_grad", c.spp_grad);
    set("loss", c.loss);
    set("seed", c.seed);
    set("cv", c.cv);
    set("cv_variance", c.cv_variance);
    if (c.restir) { // a run without reservoirs has none of these
        const RestirConfig& r = *c.restir;
        set("restir.adjoint", r.adjoint);
        set("restir.primal", r.primal);
        set("restir.candidates", r.candidates);
        set("restir.temporal", r.temporal);
        set("restir.spatial", r.spatial);
        set("restir.m_cap", r.m_cap);
        set("restir.burn_in", r.burn_in);
        set("restir.visibility", r.visibility);
        set("restir.normal_cos", r.normal_cos);
        set("restir.depth_rel", r.depth_rel);
        set("restir.direct", restir_direct_name(r.direct));
    }
    if (c.boundary_reuse) { // likewise
        const SecondaryReuseConfig& b = *c.boundary_reuse;
        set("restir.boundary.candidates", b.candidates);
        set("restir.boundary.neighbours", b.neighbours);
        set("restir.boundary.m_cap", b.m_cap);
        set("restir.boundary.cell", b.cell);
        set("restir.boundary.visibility", b.visibility);
        set("restir.boundary.receiver", b.receiver);
        set("restir.boundary.floor", b.floor);
    }
    for (const OptimizedParam& p : c.params) {
        set("params." + p.name + ".lr", p.lr);
        std::ostringstream init;
        init << std::setprecision(9);
        for (float v : p.init)
            init << (init.tellp() > 0 ? "," : "") << v;
        set("params." + p.name + ".init", init.str());
    }
    // What the scene files decide, which a change of this version's loader could change too.
    for (const Parameter& p : scene.params.parameters())
        set("scene.parameter." + p.name, std::to_string(p.size) + " values");
    if (scene.sensors.size() > 1) { // the views and their order (a scene with one has one)
        std::string views;
        for (const std::string& v : c.views) views += (views.empty() ? "" : ",") + v;
        set("views", views.empty() ? "all" : views);
        set("batch", c.batch == 0 ? "all" : std::to_string(c.batch));
    }
    std::string films; // every sensor's, in order
    for (const gpu::DeviceCamera& cam : scene.cameras)
        films += (films.empty() ? "" : ",") + std::to_string(cam.width) + "x" +
                 std::to_string(cam.height);
    set("scene.film", films);
    set("scene.geometry", std::to_string(scene.infos.size()) + " triangles, " +
                              std::to_string(scene.emissive.size()) + " emissive, " +
                              std::to_string(scene.delta_lights.size()) + " delta lights" +
                              (scene.has_env ? ", environment" : ""));
    return out;
}

std::string encode(const RunInputs& in) {
    std::string out;
    put_bytes<std::uint32_t>(out, std::uint32_t(in.files.size()));
    for (const RunInputs::File& f : in.files) {
        put_string(out, f.path);
        put_bytes(out, f.digest);
    }
    put_bytes<std::uint32_t>(out, std::uint32_t(in.settings.size()));
    for (const RunInputs::Setting& s : in.settings) {
        put_string(out, s.key);
        put_string(out, s.value);
    }
    return out;
}

RunInputs decode_inputs(const SectionReader& in) {
    const std::string where = in.where("inputs");
    const std::string_view data = in.payload("inputs");
    std::size_t at = 0;
    RunInputs r;
    const auto files = take_bytes<std::uint32_t>(data, at, where);
    for (std::uint32_t i = 0; i < files; ++i) {
        RunInputs::File f;
        f.path = take_string(data, at, where);
        f.digest = take_bytes<std::uint64_t>(data, at, where);
        r.files.push_back(std::move(f));
    }
    const auto settings = take_bytes<std::uint32_t>(data, at, where);
    for (std::uint32_t i = 0; i < settings; ++i) {
        RunInputs::Setting s;
        s.key = take_string(data, at, where);
        s.value = take_string(data, at, where);
        r.settings.push_back(std::move(s));
    }
    return r;
}

/// The file's sections, verified; throws DamagedFile or Error naming the file. The magic is outside
/// every checksum: a format byte that is not this version's, on a file whose sections all verify as
/// this version's, is a damaged byte (one flipped bit turns '5' into '4'), not another version.
SectionReader read_checkpoint(const std::string& path) {
    std::string data = read_file(path);
    const std::size_t version = sizeof(k_magic) - 1;
    if (data.size() < sizeof(k_magic) || std::memcmp(data.data(), k_magic, version) != 0)
        throw DamagedFile(path + ": not a Tandem checkpoint (or its first bytes are damaged)");
    const char format = data[version];
    if (format == k_magic[version]) return SectionReader(path, std::move(data));
    try {
        (void)SectionReader(path, data);
    } catch (const DamagedFile&) {
        if (format >= '1' && format <= '9')
            throw Error(path + ": a checkpoint of another Tandem version (format " +
                        std::string(1, format) + ", this one reads " +
                        std::string(1, k_magic[version]) + ")");
        throw DamagedFile(path + ": its format byte is damaged");
    }
    throw DamagedFile(path + ": its format byte is damaged (the sections after it are whole)");
}

/// The progress sections ("run", "metrics", "clock") of a verified checkpoint.
CheckpointProgress decode_progress(const SectionReader& in) {
    CheckpointProgress p;
    std::string where = in.where("run");
    std::string_view data = in.payload("run");
    std::size_t at = 0;
    p.iterations_done = take_bytes<std::int32_t>(data, at, where);
    p.guards = take_bytes<std::uint64_t>(data, at, where);

    where = in.where("metrics");
    data = in.payload("metrics");
    at = 0;
    const auto rows = take_bytes<std::uint64_t>(data, at, where);
    for (std::uint64_t i = 0; i < rows; ++i) {
        MetricsRow m;
        m.iteration = take_bytes<std::int32_t>(data, at, where);
        m.loss = take_bytes<float>(data, at, where);
        m.param_error = take_bytes<double>(data, at, where);
        m.image_error = take_bytes<double>(data, at, where);
        m.alpha_mean = take_bytes<double>(data, at, where);
        m.inputs_changed = take_bytes<std::uint8_t>(data, at, where) != 0;
        p.rows.push_back(m);
    }

    where = in.where("clock");
    data = in.payload("clock");
    at = 0;
    p.seconds = take_bytes<double>(data, at, where);
    for (MetricsRow& m : p.rows)
        m.seconds = take_bytes<double>(data, at, where);
    if (at != data.size())
        throw Error(where + ": " + std::to_string(rows) + " rows, not as many times");
    return p;
}

} // namespace

std::vector<RunInputs::File> input_files(const OptimizeConfig& c) {
    std::vector<std::string> files = scene_files(load_scene(c.scene, c.defines));
    for (const std::string& f : c.target_images) files.push_back(f);
    for (const std::string& f : c.target_masks) files.push_back(f);
    if (!c.target_scene.empty())
        for (const std::string& f : scene_files(load_scene(c.target_scene, c.target_defines)))
            files.push_back(f);
    std::vector<RunInputs::File> out;
    for (std::size_t i = 0; i < files.size(); ++i) // each once: the target may be the scene
        if (std::find(files.begin(), files.begin() + long(i), files[i]) == files.begin() + long(i))
            out.push_back({files[i], digest_file(files[i])});
    return out;
}

std::uint64_t run_fingerprint(const RunInputs& inputs, int start) {
    std::uint64_t h = std::uint64_t(start) * 0x9E3779B97F4A7C15ull;
    for (const RunInputs::File& f : inputs.files) h = (h ^ f.digest) * 0x100000001B3ull;
    return h;
}

RunInputs run_inputs(const RenderScene& scene, const OptimizeConfig& c) {
    RunInputs r;
    r.files = input_files(c);
    r.settings = settings(scene, c);
    return r;
}

std::string first_change(const RunInputs& saved, const RunInputs& now,
                         const std::string& config_path) {
    for (std::size_t i = 0; i < now.files.size(); ++i) {
        if (i >= saved.files.size())
            return now.files[i].path + ": an input the checkpoint's run did not read";
        if (now.files[i].digest != saved.files[i].digest)
            return now.files[i].path + ": changed since the checkpoint" +
                   (now.files[i].path == saved.files[i].path
                        ? std::string()
                        : " (where its run read " + saved.files[i].path + ")");
    }
    if (saved.files.size() > now.files.size())
        return saved.files[now.files.size()].path + ": an input of the checkpoint's run that " +
               "this one does not read";
    for (const RunInputs::Setting& s : now.settings) {
        std::string was = "(absent)";
        for (const RunInputs::Setting& t : saved.settings)
            if (t.key == s.key) was = t.value;
        if (was != s.value)
            return config_path + ": " + s.key + " changed since the checkpoint (" + was + " -> " +
                   s.value + ")";
    }
    for (const RunInputs::Setting& t : saved.settings) {
        bool found = false;
        for (const RunInputs::Setting& s : now.settings)
            found = found || s.key == t.key;
        if (!found)
            return config_path + ": " + t.key + " changed since the checkpoint (" + t.value +
                   " -> (absent))";
    }
    return {};
}

Checkpoints::Resumed load_checkpoint(const std::string& path, const RunInputs& now,
                                     const std::string& config_path, bool force,
                                     ParamState& state) {
    const SectionReader in = read_checkpoint(path); // every checksum, before anything else
    Checkpoints::Resumed r;
    r.file = path;
    r.changed = first_change(decode_inputs(in), now, config_path);
    if (!r.changed.empty() && !force)
        throw Error(r.changed + ": cannot resume " + path +
                    " (--force resumes anyway, and marks the rows after it in metrics.csv)");
    r.progress = decode_progress(in);
    state.load(in);
    return r;
}

Checkpoints::Checkpoints(const std::string& folder)
    : m_newest((fs::path(folder) / "checkpoint.bin").string()),
      m_previous((fs::path(folder) / "checkpoint.prev.bin").string()) {}

void Checkpoints::save(const RunInputs& inputs, const ParamState& state,
                       const CheckpointProgress& progress, bool keep_previous) const {
    SectionWriter out;
    std::string run;
    put_bytes<std::int32_t>(run, progress.iterations_done);
    put_bytes<std::uint64_t>(run, progress.guards);
    out.add("run", std::move(run));
    out.add("inputs", encode(inputs));
    std::string metrics, clock;
    put_bytes<std::uint64_t>(metrics, progress.rows.size());
    put_bytes(clock, progress.seconds);
    for (const MetricsRow& r : progress.rows) {
        put_bytes<std::int32_t>(metrics, r.iteration);
        put_bytes(metrics, r.loss);
        put_bytes(metrics, r.param_error);
        put_bytes(metrics, r.image_error);
        put_bytes(metrics, r.alpha_mean);
        put_bytes<std::uint8_t>(metrics, r.inputs_changed ? 1 : 0);
        put_bytes(clock, r.seconds);
    }
    out.add("metrics", std::move(metrics));
    out.add("clock", std::move(clock));
    state.save(out);
    std::error_code ec;
    // first, so that no kill leaves another run's checkpoint as this one's fallback
    if (!keep_previous && !fs::remove(m_previous, ec) && ec)
        throw Error(m_previous + ": cannot remove the checkpoint of the run before (" +
                    ec.message() + ")");
    write_file_atomic(m_newest, out.bytes(k_magic), keep_previous ? m_previous : std::string());
}

bool Checkpoints::resume(const RunInputs& inputs, const std::string& config_path, bool force,
                         ParamState& state, Resumed& out) const {
    const bool newest = fs::exists(m_newest), previous = fs::exists(m_previous);
    if (!newest && !previous) return false;
    if (!newest) { // removed by hand: the previous one is all there is
        out = load_checkpoint(m_previous, inputs, config_path, force, state);
        out.notice = "no " + m_newest + "; resuming from " + m_previous;
        return true;
    }
    try {
        out = load_checkpoint(m_newest, inputs, config_path, force, state);
        return true;
    } catch (const DamagedFile& damaged) {
        if (!previous) throw;
        try {
            out = load_checkpoint(m_previous, inputs, config_path, force, state);
        } catch (const Error& also) { // damaged too, or from other inputs
            throw Error(std::string(damaged.what()) + "; and the previous one: " + also.what());
        }
        out.damaged = m_newest;
        out.notice = std::string(damaged.what()) + "; resuming from " + m_previous +
                     " (iteration " + std::to_string(out.progress.iterations_done) +
                     "), the damaged one kept as " + m_newest + ".damaged";
        return true;
    }
}

void Checkpoints::set_aside(const Resumed& r) const {
    if (r.damaged.empty()) return;
    std::error_code ec;
    fs::rename(r.damaged, r.damaged + ".damaged", ec);
    if (ec) // else the next save would keep the damaged file as the previous one
        throw Error(r.damaged + ": cannot set the damaged checkpoint aside (" + ec.message() + ")");
}

CheckpointSummary inspect_checkpoint(const std::string& path) {
    const SectionReader in = read_checkpoint(path);
    CheckpointSummary s;
    s.iterations_done = decode_progress(in).iterations_done;
    s.inputs = decode_inputs(in);
    for (const std::string& name : in.names()) {
        const std::string_view p = in.payload(name);
        s.sections.push_back({name, p.size(), digest(p.data(), p.size())});
    }
    return s;
}

} // namespace tandem
