// Fuzzes the checkpoint reader of `tandem optimize --resume` (load_checkpoint: the sections and
// their checksums, the recorded inputs, ParamState::load) on a real parameter state: the setup of
// fuzz/assets/checkpoint (config.json and scene.xml, a 4x4 film with the control variate's
// per-pixel state) on an OpenCL device ($TANDEM_DEVICE or the default: PoCL here), created once per
// process. The seed corpus holds checkpoints that `tandem optimize config.json` wrote there, so
// inputs carry this setup's inputs. Every checksum must hold for the reader to go past the
// sections: mutations that keep them (libFuzzer's dictionary-free ones rarely do) reach the rest.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>

#include "core/inverse/checkpoint.h"
#include "core/inverse/gradient_step.h"
#include "core/inverse/optimize_config.h"
#include "core/scene/render_scene.h"
#include "core/scene/scene.h"
#include "fuzz/fuzz_common.h"
#include "runtime/context.h"

namespace {

struct Setup {
    std::unique_ptr<tandem::Context> ctx;
    tandem::OptimizeConfig config;
    tandem::RenderScene scene;
    tandem::RunInputs inputs;
};

Setup* g_setup = nullptr;

} // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    try {
        // The inputs are read from the config's own folder, as the run that wrote the seeds did;
        // then back (libFuzzer reads the corpus folders after this).
        const std::filesystem::path cwd = std::filesystem::current_path();
        std::filesystem::current_path(TANDEM_FUZZ_ASSETS "/checkpoint");
        auto* s = new Setup;
        s->config = tandem::load_optimize_config("config.json");
        s->scene = tandem::build_render_scene(tandem::load_scene(s->config.scene, s->config.defines));
        s->inputs = tandem::run_inputs(s->scene, s->config);
        std::filesystem::current_path(cwd);
        s->ctx = std::make_unique<tandem::Context>(
            tandem::Context::create({}, tandem::tuning_from_environment()));
        g_setup = s;
    } catch (const std::exception& e) { // tandem::Error, std::filesystem::filesystem_error
        std::fprintf(stderr, "fuzz_checkpoint: set-up failed: %s\n", e.what());
        std::exit(1);
    }
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    Setup& s = *g_setup;
    const std::string path = tandem::fuzz::write_input(data, size, "checkpoint.bin");
    // The state that run_optimization restores into: the scene's parameters, and what
    // GradientStep::attach registers for the config's control variate (its per-pixel state).
    tandem::ParamState state(*s.ctx, s.scene.params);
    if (s.config.cv != "none")
        state.add_buffer(tandem::GradientStep::k_cv_state,
                         3 * std::size_t(s.scene.camera.width) * s.scene.camera.height,
                         tandem::gpu::cv_state_zero());
    tandem::fuzz::expect_load_or_error(
        [&] { tandem::load_checkpoint(path, s.inputs, s.config.path, false, state); });
    return 0;
}
