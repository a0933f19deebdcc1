// The Python module's inverse rendering: ControlVariate, Optimizer, optimize
// (python/src/convert.h).
#include <filesystem>
#include <iostream>
#include <unistd.h>

#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "core/bvh/surface_distance.h"
#include "core/inverse/large_steps.h"
#include "core/inverse/optimize.h"
#include "runtime/tuning.h"
#include "python/src/convert.h"

namespace tandem::python {

using namespace nb::literals;

namespace {

using FaceArray = nb::ndarray<const std::uint32_t, nb::device::cpu, nb::c_contig>;

/// (n, cols) rows of a float array of the caller's, checked.
std::vector<float> rows(nb::handle obj, const char* what, unsigned cols = 3) {
    const InArray a = as_floats(obj, what);
    if (a.size() % cols != 0)
        throw Error(std::string(what) + ": " + std::to_string(a.size()) + " values are not rows of " +
                    (cols == 3 ? std::string("x y z") : std::to_string(cols) + " channels"));
    return std::vector<float>(a.data(), a.data() + a.size());
}

/// A mesh from a file (Assimp: OBJ, PLY, ...) or a (positions, faces) pair of arrays.
TriangleMesh mesh_of(nb::handle obj, const char* what) {
    if (nb::isinstance<nb::str>(obj) || nb::hasattr(obj, "__fspath__"))
        return load_mesh(nb::cast<std::string>(nb::str(nb::module_::import_("os").attr("fspath")(obj))));
    if (!nb::isinstance<nb::tuple>(obj) || nb::len(obj) != 2)
        throw Error(std::string(what) + ": a mesh file or a (positions, faces) pair");
    TriangleMesh mesh;
    mesh.source = what;
    const std::vector<float> p = rows(obj[0], what);
    for (std::size_t i = 0; i < p.size(); i += 3) mesh.positions.emplace_back(p[i], p[i + 1], p[i + 2]);
    const FaceArray f = nb::cast<FaceArray>(obj[1]);
    if (f.size() % 3 != 0) throw Error(std::string(what) + ": faces are not rows of 3 indices");
    for (std::size_t t = 0; t < f.size(); t += 3) {
        mesh.triangles.emplace_back(f.data()[t], f.data()[t + 1], f.data()[t + 2]);
        for (int c = 0; c < 3; ++c)
            if (mesh.triangles.back()[c] >= mesh.positions.size())
                throw Error(std::string(what) + ": face " + std::to_string(t / 3) +
                            " indexes past the positions");
    }
    return mesh;
}

} // namespace

void bind_inverse(nb::module_& m) {
    m.def(
        "surface_distance",
        [](nb::handle a, nb::handle b, std::size_t samples) {
            const TriangleMesh ma = mesh_of(a, "a"), mb = mesh_of(b, "b");
            nb::gil_scoped_release release;
            const SurfaceDistance d = surface_distance(EmbreeDevice(), ma, mb, samples);
            return std::make_pair(d.chamfer, d.hausdorff);
        },
        "a"_a, "b"_a, "samples"_a = 100000,
        "The Chamfer and Hausdorff distances between two triangle surfaces, each a mesh file or "
        "a (positions (V, 3) float32, faces (F, 3) uint32) pair, over `samples` points spread "
        "evenly on each, each point's distance to the other surface exact: (chamfer, hausdorff), "
        "chamfer the mean of the two one-sided mean distances, hausdorff the largest distance.");
    nb::class_<LargeSteps>(
        m, "LargeSteps",
        "Large Steps (Nicolet et al. 2021) for a mesh's vertex positions: u = (I + lam L) x with "
        "L the combinatorial Laplacian of the mesh, vertices at one position welded, solved back "
        "by Eigen's sparse Cholesky (as `\"large_steps\": lam` in an optimize job). Step u with "
        "an optimizer, using gradient() of the positions' gradient, and set the positions to "
        "from_differential(u). LargeSteps.image() gives the same for a texture.")
        .def(
            "__init__",
            [](LargeSteps* self, nb::handle positions, FaceArray faces, double lam) {
                const std::vector<float> x = rows(positions, "positions");
                new (self) LargeSteps(x, std::vector<unsigned>(faces.data(), faces.data() + faces.size()), lam);
            },
            "positions"_a, "faces"_a, "lam"_a = 19.0,
            "positions: (V, 3) float32; faces: (F, 3) uint32 vertex indices (Scene.faces gives "
            "them); lam: the smoothing weight (Mitsuba's default 19).")
        .def_static(
            "image",
            [](unsigned height, unsigned width, unsigned channels, double lam) {
                return LargeSteps::image(width, height, channels, lam);
            },
            "height"_a, "width"_a, "channels"_a = 3, "lam"_a = 19.0,
            "Large Steps for a texture of (height, width, channels) texels: L the texel grid's "
            "Laplacian, four neighbours each (as `\"large_steps\": lam` on a bitmap in an "
            "optimize job). Its arrays are (height * width, channels) rows of texels; a "
            "(height, width, channels) array is taken as it is.")
        .def_prop_ro("lam", &LargeSteps::lambda)
        .def_prop_ro("channels", &LargeSteps::channels, "floats per point: 3 for a mesh")
        .def_prop_ro("points", &LargeSteps::points, "distinct positions: the rows of u")
        .def(
            "to_differential",
            [](const LargeSteps& ls, nb::handle x) {
                return to_numpy(ls.to_differential(rows(x, "positions", ls.channels())),
                                {ls.points(), ls.channels()});
            },
            "positions"_a, "u = (I + lam L) x: (points, 3)")
        .def(
            "from_differential",
            [](const LargeSteps& ls, nb::handle u) {
                return to_numpy(ls.from_differential(rows(u, "u", ls.channels())),
                                {ls.vertices(), ls.channels()});
            },
            "u"_a, "x = (I + lam L)^-1 u for every vertex: (V, 3)")
        .def(
            "gradient",
            [](const LargeSteps& ls, nb::handle g) {
                return to_numpy(ls.gradient(rows(g, "gradient", ls.channels())),
                                {ls.points(), ls.channels()});
            },
            "gradient"_a,
            "The gradient with respect to u of one with respect to the positions (V, 3): "
            "(I + lam L)^-1 of each point's summed copies, (points, 3).");
    nb::class_<ControlVariate>(
        m, "ControlVariate",
        "The recursive control variate (Nicolet et al. 2023): keeps per-element statistics "
        "across calls. Each iteration, call it with F and H of scene.render_two_state().")
        .def(
            "__init__",
            [](ControlVariate* self, Session& scene, const std::string& variance, unsigned warmup,
               double beta1, double beta2, nb::handle sensor) {
                const unsigned k = sensor_of(scene, sensor);
                nb::gil_scoped_release release;
                std::lock_guard<std::mutex> lock(scene.mutex());
                CvSettings settings;
                settings.variance = cv_variance(variance);
                settings.warmup = warmup;
                settings.beta1 = float(beta1);
                settings.beta2 = float(beta2);
                new (self) ControlVariate(scene, settings, k);
            },
            "scene"_a, "variance"_a = "consistent", "warmup"_a = 1, "beta1"_a = 0.9,
            "beta2"_a = 0.999, "sensor"_a = 0, nb::keep_alive<1, 2>(),
            "variance: 'consistent' or 'reference' (the paper's eq. 10); warmup: iterations that "
            "use C = F; beta1, beta2: decay rates of the means and second moments.")
        .def(
            "__call__",
            [](ControlVariate& cv, nb::handle f, nb::handle h) {
                Session& s = cv.session();
                const InArray fa = as_floats(f, "F"), ha = as_floats(h, "H");
                const FloatSpan fs = image_span(fa, s, "F", cv.sensor()),
                                hs = image_span(ha, s, "H", cv.sensor());
                std::vector<float> c = on_device(s, [&] { return cv(fs, hs); });
                return image(std::move(c), s, cv.sensor());
            },
            "F"_a, "H"_a,
            nb::sig("def __call__(self, F: numpy.typing.ArrayLike, H: numpy.typing.ArrayLike) -> "
                    "numpy.typing.NDArray[numpy.float32]"),
            "C_n, the control-variate estimate of this iteration's image.")
        .def_prop_ro(
            "alpha",
            [](ControlVariate& cv) {
                std::vector<float> a = on_device(cv.session(), [&] { return cv.alpha(); });
                return nb::cast(image(std::move(a), cv.session(), cv.sensor())); // owns its data
            },
            nb::for_getter(nb::sig("def alpha(self, /) -> numpy.typing.NDArray[numpy.float32]")),
            "The control weight of every element after the last call.")
        .def_prop_ro("iteration", &ControlVariate::iteration, "calls so far")
        .def(
            "reset", [](ControlVariate& cv) { on_device(cv.session(), [&] { cv.reset(); }); },
            "Forgets the statistics: the next call is iteration 0.");

    nb::class_<SceneOptimizer>(m, "Optimizer",
                               "Adam or SGD on the device over some of a scene's parameters, "
                               "each with its own learning rate.")
        .def(
            "__init__",
            [](SceneOptimizer* self, Session& scene, nb::dict lr, const std::string& method,
               double beta1, double beta2, double epsilon) {
                OptimizerConfig c;
                c.method = optimizer_method(method);
                c.beta1 = float(beta1);
                c.beta2 = float(beta2);
                c.epsilon = float(epsilon);
                std::vector<std::pair<const Parameter*, float>> rates;
                for (auto [key, value] : lr)
                    rates.emplace_back(&scene.parameter(nb::cast<std::string>(key)),
                                       nb::cast<float>(value));
                nb::gil_scoped_release release;
                std::lock_guard<std::mutex> lock(scene.mutex());
                new (self) SceneOptimizer(scene, rates, c);
            },
            "scene"_a, "lr"_a, "method"_a = "adam", "beta1"_a = 0.9, "beta2"_a = 0.999,
            "epsilon"_a = 1e-8, nb::keep_alive<1, 2>(),
            nb::sig("def __init__(self, scene: Scene, lr: collections.abc.Mapping[str, float], "
                    "method: str = 'adam', beta1: float = 0.9, beta2: float = 0.999, "
                    "epsilon: float = 1e-08) -> None"),
            "lr: {parameter name: learning rate}; the other parameters are not changed.")
        .def(
            "step",
            [](SceneOptimizer& o, nb::object grads) {
                Session& s = o.session();
                std::vector<InArray> keep;
                std::vector<std::pair<const Parameter*, FloatSpan>> g;
                if (!grads.is_none())
                    g = named_spans(s, nb::cast<nb::dict>(grads), keep, "gradient");
                on_device(s, [&] { o.step(grads.is_none() ? nullptr : &g); });
            },
            "grads"_a = nb::none(),
            nb::sig("def step(self, grads: collections.abc.Mapping[str, numpy.typing.ArrayLike] | "
                    "None = None) -> None"),
            "One step, clamped to each parameter's range. grads: {name: gradient} (the others "
            "count as zero), or None for the gradient the last backward() or grad() left on the "
            "device (no copy). The values before the step become the previous state of the next "
            "render_two_state().")
        .def_prop_ro("steps", &SceneOptimizer::steps);

    m.def(
        "optimize",
        [](const std::filesystem::path& config, const std::filesystem::path& out, bool resume,
           int until, nb::object device, bool progress, bool timing, bool force) {
            if (tuning_from_environment().mpi_launched) // each rank would run the whole job
                throw Error("tandem.optimize runs as one process, and this one was started by an "
                            "MPI launcher: run `mpirun -np N tandem optimize CONFIG.json` for "
                            "several (docs/cli.md)");
            const OptimizeConfig c = load_optimize_config(config.string());
            OptimizeOptions o;
            o.out_dir = out.string();
            if (force && !resume) throw Error("tandem.optimize: force=True needs resume=True");
            o.resume = resume;
            o.force = force;
            o.until = until;
            o.stage_timing = timing;
            const bool tty = isatty(STDERR_FILENO);
            o.progress = [progress, tty](int it, int total, float loss) {
                if (progress && tty) {
                    const int width = 30, filled = width * it / total;
                    std::cerr << "\r[" << std::string(filled, '#')
                              << std::string(width - filled, ' ') << "] " << it << "/" << total
                              << " loss " << loss << (it == total ? "\n" : "   ") << std::flush;
                }
                nb::gil_scoped_acquire acquire; // Ctrl-C stops between iterations
                if (PyErr_CheckSignals() != 0) {
                    PyErr_Clear();
                    throw Interrupted{"tandem.optimize interrupted after iteration " +
                                      std::to_string(it) +
                                      "; continue from the last checkpoint with resume=True"};
                }
            };
            const std::string dev =
                device.is_none() ? std::string() : nb::cast<std::string>(nb::str(device));
            OptimizeSummary s;
            {
                nb::gil_scoped_release release;
                Context ctx = Context::create(dev);
                s = run_optimization(ctx, KernelLibrary::from_environment(), c, o);
            }
            // the CLI's --json summary, the same keys and values
            nb::object j =
                nb::module_::import_("json").attr("loads")(optimize_summary_json(s, o.out_dir));
            return j;
        },
        "config"_a, "out"_a = "optimize-out", "resume"_a = false, "until"_a = 0,
        "device"_a = nb::none(), "progress"_a = true, "timing"_a = false, "force"_a = false,
        nb::sig("def optimize(config: str | os.PathLike, out: str | os.PathLike = 'optimize-out', "
                "resume: bool = False, until: int = 0, device: int | str | None = None, "
                "progress: bool = True, timing: bool = False, force: bool = False) -> "
                "dict[str, object]"),
        "`tandem optimize CONFIG --out OUT`: the same run, files and checkpoints. Returns the "
        "summary of `--json` as a dict. resume: continue from OUT/checkpoint.bin (or the previous "
        "checkpoint, when it is damaged), refused when an input changed since it; force: resume "
        "over changed inputs anyway (metrics.csv marks the rows after it); until: stop "
        "after this iteration; timing: measure device time per stage (*_seconds). Ctrl-C stops "
        "between iterations (KeyboardInterrupt); the last checkpoint stays.");
}

} // namespace tandem::python
