// `tandem optimize` end to end on a tiny scene: outputs, bit-identical resume from a checkpoint,
// and the errors of a checkpoint from another run and of bad configs.
#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "core/io/atomic_file.h"
#include "core/io/image_io.h"
#include "core/inverse/metrics.h"
#include "core/inverse/optimize.h"
#include "runtime/error.h"
#include "support.h"

using namespace tandem;
namespace fs = std::filesystem;

namespace {

/// A fresh directory under the build's temp area.
std::string fresh_dir(const std::string& name) {
    const fs::path p = fs::temp_directory_path() / ("tandem-test-" + name);
    fs::remove_all(p);
    fs::create_directories(p);
    return p.string();
}

/// A config recovering the floor albedo of grad-delta.xml (16x16) from a flat start.
std::string write_config(const std::string& dir, const std::string& extra_param = "") {
    const std::string scene = std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/grad-delta.xml";
    nlohmann::json j = {{"scene", scene},
                        {"defines", {{"res", 16}}},
                        {"target", {{"scene", scene}, {"defines", {{"res", 16}}}, {"spp", 64}}},
                        {"params", {{"floor.reflectance", {{"lr", 0.05}, {"init", 0.2}}}}},
                        {"iterations", 6},
                        {"spp", 2},
                        {"spp_grad", 2},
                        {"loss", "l2"},
                        {"seed", 3},
                        {"checkpoint_every", 2},
                        {"image_error_spp", 4}};
    if (!extra_param.empty()) j["params"][extra_param] = {{"lr", 0.05}};
    const std::string path = dir + "/config.json";
    write_file_atomic(path, j.dump(2));
    return path;
}

} // namespace

TEST_SUITE("optimize") {
    TEST_CASE("a run writes its outputs, lowers the error, and resumes bit-identically") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const std::string dir = fresh_dir("optimize");
        const OptimizeConfig config = load_optimize_config(write_config(dir));

        OptimizeOptions full;
        full.out_dir = dir + "/full";
        const OptimizeSummary a = run_optimization(*ctx, lib, config, full);
        for (const char* f : {"metrics.csv", "target.exr", "iter_0002.exr", "iter_0006.exr", "params.json",
                              "convergence.png", "checkpoint.bin", "alpha_0006.exr", "variance_0006.exr"})
            CHECK_MESSAGE(fs::exists(full.out_dir + "/" + f), f);
        CHECK(a.iterations_done == 6);
        const std::string csv = read_file(full.out_dir + "/metrics.csv");
        CHECK(csv.rfind("iteration,seconds,loss,param_error,image_error,alpha_mean,inputs_changed\n", 0) == 0);
        CHECK(std::count(csv.begin(), csv.end(), '\n') == 7);
        // the floor starts at 0.2 against (0.6, 0.5, 0.4): six Adam steps of 0.05 close most of it
        CHECK(a.param_error < 0.15);

        // interrupted after iteration 3 (a checkpoint at 2, and one at the stop), then resumed
        OptimizeOptions part;
        part.out_dir = dir + "/resumed";
        part.until = 3;
        CHECK(run_optimization(*ctx, lib, config, part).iterations_done == 3);
        part.resume = true;
        part.until = 2; // before the checkpoint: an error, and the run's files are left alone
        const std::string metrics = read_file(part.out_dir + "/metrics.csv");
        CHECK_THROWS_WITH_AS(
            run_optimization(*ctx, lib, config, part),
            doctest::Contains("checkpoint.bin: the checkpoint is at iteration 3, past --until 2"),
            Error);
        CHECK(read_file(part.out_dir + "/metrics.csv") == metrics);
        part.until = 0;
        const OptimizeSummary b = run_optimization(*ctx, lib, config, part);
        CHECK(b.iterations_done == 6);
        CHECK(read_file(full.out_dir + "/params.json") == read_file(part.out_dir + "/params.json"));
        CHECK(a.final_loss == b.final_loss);
        CHECK(a.param_error == b.param_error);
        int w = 0, h = 0;
        CHECK(test::same_bytes(read_image(full.out_dir + "/iter_0006.exr", &w, &h, false),
                               read_image(part.out_dir + "/iter_0006.exr", &w, &h, false)));
    }

    TEST_CASE("resuming with a checkpoint of another setup is an error naming the changed key") {
        TANDEM_REQUIRE_DEVICE(ctx);
        const KernelLibrary& lib = KernelLibrary::from_environment();
        const std::string dir = fresh_dir("optimize-mismatch");
        OptimizeOptions o;
        o.out_dir = dir + "/out";
        o.until = 1;
        run_optimization(*ctx, lib, load_optimize_config(write_config(dir)), o);
        o.resume = true;
        o.until = 0;
        const OptimizeConfig other = load_optimize_config(write_config(dir, "sky.radiance"));
        // (core/inverse/checkpoint.h: the first setting that differs, with its values)
        CHECK_THROWS_WITH_AS(run_optimization(*ctx, lib, other, o),
                             doctest::Contains("config.json: params.sky.radiance.lr changed since "
                                               "the checkpoint ((absent) -> 0.0500000007)"),
                             Error);
        // the control variate's variance form is part of the setup a checkpoint records
        OptimizeConfig reference = load_optimize_config(write_config(dir));
        CHECK(reference.cv_variance == "consistent"); // the default
        reference.cv_variance = "reference";
        CHECK_THROWS_WITH_AS(run_optimization(*ctx, lib, reference, o),
                             doctest::Contains("config.json: cv_variance changed since the "
                                               "checkpoint (consistent -> reference): cannot "
                                               "resume"),
                             Error);
        // a resume without a checkpoint (a run killed before its first) starts from the start
        OptimizeOptions none;
        none.out_dir = dir + "/empty";
        none.resume = true;
        none.until = 1;
        OptimizeOptions fresh = none;
        fresh.out_dir = dir + "/fresh";
        fresh.resume = false;
        const OptimizeSummary a = run_optimization(*ctx, lib, other, none);
        const OptimizeSummary b = run_optimization(*ctx, lib, other, fresh);
        CHECK(a.iterations_done == 1);
        CHECK(a.final_loss == b.final_loss);
    }

    TEST_CASE("a step that destroys a mesh stops the run with the shape and the iteration") {
        // a learning rate of 1e38 throws the light's corners to the ends of the float range
        TANDEM_REQUIRE_DEVICE(ctx);
        const std::string dir = fresh_dir("destroyed");
        const OptimizeConfig config = load_optimize_config(
            std::string(TANDEM_SOURCE_DIR) + "/tests/scenes/shape-destroy.json");
        OptimizeOptions o;
        o.out_dir = dir + "/run";
        CHECK_THROWS_WITH_AS(run_optimization(*ctx, KernelLibrary::from_environment(), config, o),
                             "iteration 2: light.vertex_positions: all 2 triangles are degenerate "
                             "(zero or non-finite area)",
                             Error);
        // what the run wrote before is kept: the header and its first iteration's metrics row
        const std::string csv = read_file(o.out_dir + "/metrics.csv");
        CHECK(std::count(csv.begin(), csv.end(), '\n') == 2);
    }

    TEST_CASE("config errors name the file and the problem") {
        const std::string dir = fresh_dir("optimize-config");
        auto with = [&](const std::string& text) {
            write_file_atomic(dir + "/c.json", text);
            return dir + "/c.json";
        };
        const std::string base = R"("scene": "s.xml", "target": {"image": "t.exr"}, "params": {"a.alpha": {"lr": 0.1}})";
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"iterations\": 0}")),
                             doctest::Contains("c.json: 'iterations' must be at least 1"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"spp\": \"four\"}")),
                             doctest::Contains("'spp' has the wrong type"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"loss\": \"l3\"}")),
                             doctest::Contains("c.json: unknown loss 'l3'"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"spp\": 4, \"spp\": 8}")),
                             doctest::Contains("c.json: key 'spp' is given twice in one object"),
                             Error);
        CHECK_THROWS_WITH_AS(
            load_optimize_config(with(
                R"({"scene": "s.xml", "target": {"image": "t.exr"}, "params": {"a": {"lr": 0.1, "lr": 0.2}}})")),
            doctest::Contains("key 'lr' is given twice"), Error);
        // the same key in two objects is fine
        CHECK_NOTHROW(load_optimize_config(with(
            R"({"scene": "s.xml", "target": {"image": "t.exr"}, "params": {"a": {"lr": 0.1}, "b": {"lr": 0.2}}})")));
        CHECK_THROWS_WITH_AS(
            load_optimize_config(with("{" + base + ", \"optimizer\": \"sgd\", \"beta1\": 0.5}")),
            doctest::Contains("c.json: 'beta1' is Adam's; 'optimizer' is \"sgd\""), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"spp\": 1000000000}")),
                             doctest::Contains("c.json: 'spp' is 1000000000; at most 1048576"),
                             Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with(R"({"scene": "s.xml", "params": {"a": {}}})")),
                             doctest::Contains("'target' is required"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with(R"({"scene": "s.xml", "target": {"image": "t.exr", "scene": "u.xml"}, "params": {"a": {}}})")),
                             doctest::Contains("target needs exactly one of 'scene', 'images' and 'image'"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with(R"({"scene": "s.xml", "target": {"images": ["a.exr", "b.exr"], "masks": ["m.png"]}, "params": {"a": {}}})")),
                             doctest::Contains("c.json: target.masks has 1 files, target.images 2"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with(R"({"scene": "s.xml", "target": {"images": ["a.exr"], "spp": 4}, "params": {"a": {}}})")),
                             doctest::Contains("c.json: target.spp is a target scene's; the target is images"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"views\": \"some\"}")),
                             doctest::Contains("c.json: views must be \"all\" or a list of sensors"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"views\": [0, 1.5]}")),
                             doctest::Contains("c.json: views: a sensor is an index (0, 1, ...) or an id"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"batch\": 0}")),
                             doctest::Contains("c.json: 'batch' must be at least 1 (views per iteration)"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with(R"({"scene": "s.xml", "target": {"image": "t.exr"}, "params": {"a": {"lr": -1}}})")),
                             doctest::Contains("params.a: 'lr' must be positive"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("[1, 2")), doctest::Contains("malformed JSON"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"cv\": \"yes\"}")),
                             doctest::Contains("c.json: unknown control variate 'yes' (none, pss, ps)"), Error);
        CHECK_THROWS_WITH_AS(load_optimize_config(with("{" + base + ", \"cv_variance\": \"exact\"}")),
                             doctest::Contains("c.json: unknown cv_variance 'exact' (expected \"consistent\" or \"reference\")"), Error);
        CHECK(load_optimize_config(with("{" + base + ", \"cv_variance\": \"reference\"}")).cv_variance == "reference");
        const OptimizeConfig ok = load_optimize_config(with("{" + base + "}"));
        CHECK(ok.target_images == std::vector<std::string>{(fs::path(dir) / "t.exr").string()}); // relative to the config
    }
}

TEST_CASE("image_error weighs each pixel by the target's mask, as the loss does") {
    // two pixels: the first off by 1 in each channel, the second by 3
    const std::vector<float> a = {1, 1, 1, 3, 3, 3}, b(6, 0.0f);
    CHECK(image_rmse(a, b, {}) == doctest::Approx(std::sqrt(5.0)).epsilon(1e-12)); // (1 + 9) / 2
    CHECK(image_rmse(a, b, {1.0f, 0.0f}) == doctest::Approx(1.0).epsilon(1e-12));  // masked out
    CHECK(image_rmse(a, b, {0.0f, 1.0f}) == doctest::Approx(3.0).epsilon(1e-12));
    // a half weight: (0.5 * 1 + 1 * 9) / 1.5
    CHECK(image_rmse(a, b, {0.5f, 1.0f}) == doctest::Approx(std::sqrt(9.5 / 1.5)).epsilon(1e-12));
    CHECK(image_rmse(a, b, {0.0f, 0.0f}) == 0.0); // nothing to measure
}
