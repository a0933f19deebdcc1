// Checkpoints of `tandem optimize`: everything needed to resume bit-identically, in checksummed
// sections (core/io/sections.h), with the previous checkpoint kept beside the newest, and a record
// of the run's inputs that a resume compares with its own.
//
// The parameter state saves itself generically (core/inverse/param_state.h); this adds the run's
// progress, its metrics and its inputs. Sections: "run" (iterations done, guards), "inputs",
// "metrics" (the rows but their wall-clock seconds), "clock" (every wall-clock field, so that two
// runs of the same trajectory differ in this section only), "state" and one "state:NAME" per
// state buffer.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/inverse/metrics.h"
#include "core/inverse/optimize_config.h"
#include "core/inverse/param_state.h"
#include "core/scene/render_scene.h"

namespace tandem {

/// What a run's trajectory depends on: the settings that shape it (the config's keys and the
/// scene's parameter layout, as text) and the content of every input file. A resume from a
/// checkpoint whose inputs differ would continue another problem.
struct RunInputs {
    struct Setting {
        std::string key, value;
    };
    struct File {
        std::string path;     ///< as the run found it, for messages
        std::uint64_t digest; ///< XXH3-64 of its bytes (core/io/digest.h)
    };
    std::vector<File> files;
    std::vector<Setting> settings;
};

/// The scene file and every file it references, then the target image, or the target scene and
/// its files, each once, with the digests of their content read now.
std::vector<RunInputs::File> input_files(const OptimizeConfig& config);

/// The inputs of `config` optimizing `scene`: the digests of the scene file and every file it
/// references, of the target image, or of the target scene and its files (read now), and the
/// settings. Not among them: what a run may change on resume without changing its trajectory
/// (iterations, checkpoint_every, image_error_spp, the paths by which the files are found).
RunInputs run_inputs(const RenderScene& scene, const OptimizeConfig& config);

/// A fingerprint of a run that starts at iteration `start` of `inputs` (their files' digests):
/// the processes of one run compare theirs (Ranks::agree).
std::uint64_t run_fingerprint(const RunInputs& inputs, int start);

/// Empty when `now` is `saved`; otherwise one line naming the first difference: the first file
/// whose content changed, or that a run reads now and did not then, or else the first setting
/// of `config_path` that changed, with its old and new values.
std::string first_change(const RunInputs& saved, const RunInputs& now,
                         const std::string& config_path);

struct CheckpointProgress {
    int iterations_done = 0;
    double seconds = 0.0; ///< optimization seconds so far
    std::vector<MetricsRow> rows;
    std::uint64_t guards = 0; ///< samples, gradient contributions and sums dropped so far (guards)
};

/// The checkpoints of one output folder: checkpoint.bin, the newest, and checkpoint.prev.bin,
/// the one before it, which a resume falls back to when the newest is damaged.
class Checkpoints {
public:
    explicit Checkpoints(const std::string& folder);
    const std::string& newest() const { return m_newest; }
    const std::string& previous() const { return m_previous; }

    /// Writes `state`, `progress` and `inputs` as the newest checkpoint, atomically (a temporary,
    /// flushed, renamed). With `keep_previous`, the checkpoint it replaces becomes the previous
    /// one (a hard link renamed into place first, so that a kill at any point leaves a newest
    /// checkpoint); without, any previous one goes (it belongs to another run). Blocks for the
    /// downloads.
    void save(const RunInputs& inputs, const ParamState& state, const CheckpointProgress& progress,
              bool keep_previous) const;

    /// What resume() found.
    struct Resumed {
        CheckpointProgress progress;
        std::string file;    ///< the checkpoint restored
        std::string changed; ///< with `force`: the inputs' first change it resumed over; else ""
        std::string damaged; ///< the damaged newest checkpoint it fell back from; else ""
        std::string notice;  ///< one line for the log when it did not restore the newest; else ""
    };
    /// Restores `state` from the newest checkpoint whose checksums hold: the newest, or if it is
    /// damaged (DamagedFile) the previous one (Resumed::damaged and notice say so). Returns false
    /// when there is no checkpoint. Throws Error naming the file when the checkpoints are damaged
    /// both, of another format, or from a run whose inputs differ (first_change()), unless
    /// `force`, which resumes over changed inputs and says so in Resumed::changed. Changes no
    /// file: see set_aside().
    bool resume(const RunInputs& inputs, const std::string& config_path, bool force,
                ParamState& state, Resumed& out) const;
    /// After resume() fell back from a damaged newest checkpoint, and the caller has checked all it
    /// checks: renames it to checkpoint.bin.damaged, so that no later save keeps it as a previous
    /// one. Throws Error naming it when it cannot.
    void set_aside(const Resumed& resumed) const;

private:
    std::string m_newest, m_previous;
};

/// Restores `state` from the one checkpoint file at `path` (Checkpoints::resume() tries the newest,
/// then the previous one, through it): every checksum is verified, then the inputs compared with
/// `now`, then the state's layout, before anything is restored. Throws DamagedFile when the file is
/// damaged, Error naming the first changed input (unless `force`) or another mismatch.
Checkpoints::Resumed load_checkpoint(const std::string& path, const RunInputs& now,
                                     const std::string& config_path, bool force,
                                     ParamState& state);

/// A checkpoint file read and verified, without restoring anything: what `tandem checkpoint`
/// prints. Throws DamagedFile (core/io/sections.h) or Error naming the file.
struct CheckpointSummary {
    int iterations_done = 0;
    struct Section {
        std::string name;
        std::size_t bytes;
        std::uint64_t digest; ///< of its payload
    };
    std::vector<Section> sections;
    RunInputs inputs;
};
CheckpointSummary inspect_checkpoint(const std::string& path);

} // namespace tandem
