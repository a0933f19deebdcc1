// Checkpoints of `tandem optimize`.
#include "core/inverse/checkpoint.h"

#include <cstring>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "core/io/atomic_file.h"
#include "core/io/binary.h"
#include "runtime/error.h"

namespace tandem {

std::uint64_t run_fingerprint(const RenderScene& scene, const OptimizeConfig& c) {
    std::ostringstream s;
    s << std::setprecision(9) << c.scene << ';';
    for (const auto& [k, v] : c.defines)
        s << k << '=' << v << ';';
    s << c.target_image << ';' << c.target_scene << ';' << c.target_spp << ';';
    for (const auto& [k, v] : c.target_defines)
        s << k << '=' << v << ';';
    for (const Parameter& p : scene.params.parameters())
        s << p.name << ':' << p.size << ';';
    s << scene.camera.width << 'x' << scene.camera.height << ';' << c.optimizer << ';' << c.beta1
      << ';' << c.beta2 << ';' << c.epsilon << ';' << c.spp << ';' << c.spp_grad << ';' << c.loss
      << ';' << c.seed << ';' << c.cv << ';' << c.cv_variance << ';';
    if (c.restir) { // a run without reservoirs keeps its fingerprint
        const RestirConfig& r = *c.restir;
        s << "restir:" << r.candidates << ',' << r.temporal << ',' << r.spatial << ',' << r.m_cap
          << ',' << r.burn_in << ',' << r.visibility << ',' << r.normal_cos << ',' << r.depth_rel;
        // MIS, the only share before it was a choice, keeps the fingerprint of the checkpoints
        // written then
        if (r.direct != RestirDirect::mis) s << ',' << restir_direct_name(r.direct);
        // the adjoint's chain alone, the only one before the primal's, keeps them too
        if (r.primal) s << (r.adjoint ? ",primal+adjoint" : ",primal");
        s << ';';
        // reservoirs hold triangle and light indices: a checkpoint of another geometry or light
        // set must not be read into this one
        s << scene.infos.size() << ',' << scene.emissive.size() << ',' << scene.delta_lights.size()
          << ',' << scene.has_env << ';';
    }
    for (const OptimizedParam& p : c.params) {
        s << p.name << '=' << p.lr;
        for (float v : p.init)
            s << ',' << v;
        s << ';';
    }
    std::uint64_t h = 1469598103934665603ull;
    for (unsigned char ch : s.str())
        h = (h ^ ch) * 1099511628211ull;
    return h;
}

namespace {

/// Version 4: the parameter state as named buffers; the control variate's state is the 40-byte
/// CvState of the two variance forms (version 3 held the 32-byte one of the reference form).
constexpr char k_magic[8] = {'T', 'N', 'D', 'M', 'C', 'K', 'P', '4'};

} // namespace

void save_checkpoint(const std::string& path, std::uint64_t fingerprint, const ParamState& state,
                     const CheckpointProgress& progress) {
    std::string out(k_magic, sizeof(k_magic));
    put_bytes(out, fingerprint);
    put_bytes<std::int32_t>(out, progress.iterations_done);
    put_bytes(out, progress.seconds);
    state.save(out);
    put_bytes<std::uint64_t>(out, progress.rows.size());
    for (const MetricsRow& r : progress.rows) {
        put_bytes<std::int32_t>(out, r.iteration);
        put_bytes(out, r.seconds);
        put_bytes(out, r.loss);
        put_bytes(out, r.param_error);
        put_bytes(out, r.image_error);
        put_bytes(out, r.alpha_mean);
    }
    put_bytes<std::uint64_t>(out, progress.guards);
    write_file_atomic(path, out);
}

CheckpointProgress load_checkpoint(const std::string& path, std::uint64_t fingerprint,
                                   ParamState& state) {
    if (!std::filesystem::exists(path)) throw Error(path + ": no checkpoint to resume from");
    const std::string data = read_file(path);
    if (data.size() < sizeof(k_magic) ||
        std::memcmp(data.data(), k_magic, sizeof(k_magic) - 1) != 0)
        throw Error(path + ": not a Tandem checkpoint");
    if (data[sizeof(k_magic) - 1] != k_magic[sizeof(k_magic) - 1])
        throw Error(path + ": a checkpoint of another Tandem version (format " +
                    std::string(1, data[sizeof(k_magic) - 1]) + ", this one reads " +
                    std::string(1, k_magic[sizeof(k_magic) - 1]) + ")");
    std::size_t pos = sizeof(k_magic);
    if (take_bytes<std::uint64_t>(data, pos, path) != fingerprint)
        throw Error(path + ": the checkpoint is from another scene or optimization setup "
                           "(parameters, film, loss, seed, spp or learning rates differ)");
    CheckpointProgress p;
    p.iterations_done = take_bytes<std::int32_t>(data, pos, path);
    p.seconds = take_bytes<double>(data, pos, path);
    state.load(data, pos, path);
    const auto rows = take_bytes<std::uint64_t>(data, pos, path);
    for (std::uint64_t i = 0; i < rows; ++i) {
        MetricsRow m;
        m.iteration = take_bytes<std::int32_t>(data, pos, path);
        m.seconds = take_bytes<double>(data, pos, path);
        m.loss = take_bytes<float>(data, pos, path);
        m.param_error = take_bytes<double>(data, pos, path);
        m.image_error = take_bytes<double>(data, pos, path);
        m.alpha_mean = take_bytes<double>(data, pos, path);
        p.rows.push_back(m);
    }
    p.guards = take_bytes<std::uint64_t>(data, pos, path);
    if (pos != data.size()) throw Error(path + ": unexpected data after the checkpoint's end");
    return p;
}

} // namespace tandem
