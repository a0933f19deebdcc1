// `import tandem`: the Python bindings of python/src/session.h.
//
// nanobind (PyPI) rather than Debian's pybind11: its ndarray type takes NumPy arrays, PyTorch CPU
// tensors and anything else that speaks DLPack or the buffer protocol without a copy, returns
// NumPy arrays that own the host vectors they wrap (no copy either), generates the type stubs an
// editor completes from (nanobind_add_stub), and makes a smaller, faster-loading extension.
//
// Conventions: images are float32 arrays (height, width, 3), linear RGB, row-major from the top
// left, as the CLI writes them. Errors in the input raise ValueError with the CLI's one-line
// message; failures of the device (no OpenCL device, out of memory, a kernel build) raise
// RuntimeError. Every call that runs on the device releases the GIL.
#include <cstdint>
#include <iostream>
#include <memory>
#include <mutex>
#include <string>
#include <unistd.h>
#include <utility>
#include <vector>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "core/inverse/gradient_step.h"
#include "core/inverse/optimize.h"
#include "core/io/image_io.h"
#include "python/src/session.h"
#include "runtime/device.h"
#include "runtime/error.h"

namespace nb = nanobind;
using namespace nb::literals;

namespace tandem::python {
namespace {

/// A float32 array on the host, C-contiguous; nanobind converts other dtypes and layouts.
using InArray = nb::ndarray<const float, nb::device::cpu, nb::c_contig>;
using OutArray = nb::ndarray<nb::numpy, float>;

/// Raised through C++ when Ctrl-C arrives during a long call; becomes KeyboardInterrupt.
struct Interrupted {
    std::string message;
};

/// A NumPy array that owns `v` (moved, not copied), of the given shape.
OutArray to_numpy(std::vector<float>&& v, std::initializer_list<std::size_t> shape) {
    auto* owned = new std::vector<float>(std::move(v));
    nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<float>*>(p); });
    return OutArray(owned->data(), shape, owner);
}

/// Any array-like as float32 C-contiguous (lists and scalars through numpy.ascontiguousarray).
InArray as_floats(nb::handle obj, const char* what) {
    InArray a;
    if (nb::try_cast(obj, a)) return a;
    nb::object converted;
    try {
        converted = nb::module_::import_("numpy").attr("ascontiguousarray")(obj, "float32");
    } catch (const nb::python_error&) {
        throw Error(std::string(what) + ": expected an array of floats, got " +
                    nb::cast<std::string>(nb::str(obj.type().attr("__name__"))));
    }
    if (!nb::try_cast(converted, a))
        throw Error(std::string(what) + ": expected an array of floats");
    return a;
}

FloatSpan span(const InArray& a) { return {a.data(), a.size()}; }

/// An image argument: (height, width, 3) or flat, of the scene's film.
FloatSpan image_span(const InArray& a, const Session& s, const char* what) {
    const bool shaped = a.ndim() == 3 && a.shape(0) == s.height() && a.shape(1) == s.width() &&
                        a.shape(2) == 3;
    const bool flat = a.ndim() == 1 && a.size() == s.image_size();
    if (!shaped && !flat) {
        std::string shape = "(";
        for (std::size_t i = 0; i < a.ndim(); ++i)
            shape += (i ? ", " : "") + std::to_string(a.shape(i));
        shape += a.ndim() == 1 ? ",)" : ")";
        throw Error(std::string(what) + " has shape " + shape + "; the film is (" +
                    std::to_string(s.height()) + ", " + std::to_string(s.width()) + ", 3)");
    }
    return span(a);
}

OutArray image(std::vector<float>&& v, const Session& s) {
    return to_numpy(std::move(v), {s.height(), s.width(), 3});
}

const char* kind_name(Parameter::Kind k) {
    switch (k) {
    case Parameter::Kind::rgb: return "rgb";
    case Parameter::Kind::texture: return "texture";
    case Parameter::Kind::scalar: return "scalar";
    }
    return "?";
}

nb::tuple param_shape(const Parameter& p) {
    if (p.kind == Parameter::Kind::texture)
        return nb::make_tuple(std::size_t(p.height), std::size_t(p.width), std::size_t(3));
    return nb::make_tuple(p.size);
}

OutArray param_array(std::vector<float>&& v, const Parameter& p) {
    if (p.kind == Parameter::Kind::texture)
        return to_numpy(std::move(v), {std::size_t(p.height), std::size_t(p.width), 3});
    return to_numpy(std::move(v), {p.size});
}

/// {name: gradient} of `params` from a gradient in the registry's layout.
nb::dict gradient_dict(const std::vector<float>& g, const std::vector<const Parameter*>& params) {
    nb::dict out;
    for (const Parameter* p : params)
        out[p->name.c_str()] = param_array(
            std::vector<float>(g.begin() + std::ptrdiff_t(p->offset),
                               g.begin() + std::ptrdiff_t(p->offset + p->size)),
            *p);
    return out;
}

/// Parameters named by `names` (None: every parameter of the scene).
std::vector<const Parameter*> select(const Session& s, const nb::handle& names) {
    std::vector<const Parameter*> out;
    if (names.is_none()) {
        for (const Parameter& p : s.parameters()) out.push_back(&p);
        return out;
    }
    if (nb::isinstance<nb::str>(names)) {
        out.push_back(&s.parameter(nb::cast<std::string>(names)));
        return out;
    }
    for (nb::handle n : names) out.push_back(&s.parameter(nb::cast<std::string>(n)));
    return out;
}

/// A dict {name: array} as (parameter, span) pairs; `keep` holds the converted arrays.
std::vector<std::pair<const Parameter*, FloatSpan>>
named_spans(const Session& s, const nb::dict& d, std::vector<InArray>& keep, const char* what) {
    std::vector<std::pair<const Parameter*, FloatSpan>> out;
    keep.reserve(d.size());
    for (auto [key, value] : d) {
        const Parameter& p = s.parameter(nb::cast<std::string>(key));
        keep.push_back(as_floats(value, (std::string(what) + " '" + p.name + "'").c_str()));
        out.emplace_back(&p, span(keep.back()));
    }
    return out;
}

/// One parameter of a scene, as `scene.params[name]` gives it.
struct ParamRef {
    Session* session;
    const Parameter* param;
};

/// `scene.params`: a read-only mapping from names to parameters (registered as a
/// collections.abc.Mapping in tandem/__init__.py).
struct ParamMap {
    Session* session;
};

std::vector<std::pair<std::string, std::string>> defines_of(const nb::kwargs& kwargs) {
    std::vector<std::pair<std::string, std::string>> out;
    for (auto [key, value] : kwargs) {
        std::string v;
        if (nb::isinstance<nb::bool_>(value))
            v = nb::cast<bool>(value) ? "true" : "false";
        else
            v = nb::cast<std::string>(nb::str(value));
        out.emplace_back(nb::cast<std::string>(key), v);
    }
    return out;
}

nb::dict device_dict(const DeviceInfo& d) {
    nb::dict j;
    j["index"] = d.index;
    j["platform"] = d.platform;
    j["platform_version"] = d.platform_version;
    j["name"] = d.name;
    j["vendor"] = d.vendor;
    j["type"] = d.type;
    j["compute_units"] = d.compute_units;
    j["global_mem_bytes"] = d.global_mem_bytes;
    j["max_alloc_bytes"] = d.max_alloc_bytes;
    j["opencl_c_version"] = d.opencl_c_version;
    j["driver_version"] = d.driver_version;
    return j;
}

/// Runs `f` on the session with the GIL released and the session's lock held.
template <class F> auto on_device(Session& s, F&& f) {
    nb::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(s.mutex());
    return f();
}

} // namespace
} // namespace tandem::python

using namespace tandem;
using namespace tandem::python;

NB_MODULE(_tandem, m) {
    m.doc() = "Tandem: a portable inverse path tracer (OpenCL). See help(tandem).";

    nb::register_exception_translator([](const std::exception_ptr& p, void*) {
        try {
            std::rethrow_exception(p);
        } catch (const DeviceError& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        } catch (const Error& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        } catch (const cl::Error& e) {
            PyErr_SetString(PyExc_RuntimeError,
                            (std::string("OpenCL: ") + e.what() + " failed: " +
                             cl_error_name(e.err()))
                                .c_str());
        } catch (const Interrupted& e) {
            PyErr_SetString(PyExc_KeyboardInterrupt, e.message.c_str());
        }
    });

    m.def(
        "devices",
        [] {
            nb::list out;
            for (const DeviceInfo& d : list_devices()) out.append(device_dict(d));
            return out;
        },
        "The OpenCL devices, as `tandem devices --json` lists them: a list of dicts (index, "
        "platform, name, vendor, type, compute_units, global_mem_bytes, ...).");

    m.def("primal_seed", &primal_seed, "seed"_a, "iteration"_a,
          "The seed of iteration `iteration`'s primal render in a run seeded with `seed` "
          "(`tandem grad --seed S` renders with primal_seed(S, 0)).");
    m.def("adjoint_seed", &adjoint_seed, "seed"_a, "iteration"_a,
          "The seed of iteration `iteration`'s adjoint pass in a run seeded with `seed` "
          "(`tandem grad --seed S` replays with adjoint_seed(S, 0)).");

    m.def(
        "read_image",
        [](const std::string& path) {
            int w = 0, h = 0;
            std::vector<float> rgb = read_image(path, &w, &h);
            return to_numpy(std::move(rgb), {std::size_t(h), std::size_t(w), 3});
        },
        "path"_a,
        "Reads an image (EXR, PNG, PFM, ...) as float32 (height, width, 3), linear RGB (8-bit "
        "formats are decoded from sRGB). ValueError naming the file when it is unreadable or "
        "holds NaN or Inf.");
    m.def(
        "write_image",
        [](const std::string& path, nb::handle array) {
            const InArray a = as_floats(array, "image");
            if (a.ndim() != 3 || a.shape(2) != 3)
                throw Error("write_image: expected an array (height, width, 3)");
            const float* p = a.data();
            write_image(path, int(a.shape(1)), int(a.shape(0)),
                        std::vector<float>(p, p + a.size()));
        },
        "path"_a, "image"_a,
        "Writes a (height, width, 3) image: .exr keeps linear float32, .png is sRGB 8-bit. The "
        "file is written beside the target and renamed over it.");

    nb::class_<ParamRef>(m, "Parameter",
                         "A differentiable scene parameter: a named range of the flat parameter "
                         "array (see `tandem params`).")
        .def_prop_ro("name", [](const ParamRef& r) { return r.param->name; })
        .def_prop_ro("kind", [](const ParamRef& r) { return kind_name(r.param->kind); },
                     "'rgb', 'texture' or 'scalar'")
        .def_prop_ro("shape", [](const ParamRef& r) { return param_shape(*r.param); },
                     "(3,) for rgb, (1,) for scalar, (height, width, 3) for a texture")
        .def_prop_ro("size", [](const ParamRef& r) { return r.param->size; })
        .def_prop_ro(
            "range", [](const ParamRef& r) { return std::make_pair(r.param->lower, r.param->upper); },
            "(lower, upper): the valid range of every element")
        .def_prop_rw(
            "value",
            [](ParamRef& r) {
                std::vector<float> v =
                    on_device(*r.session, [&] { return r.session->value(*r.param); });
                return nb::cast(param_array(std::move(v), *r.param)); // owns its data
            },
            [](ParamRef& r, nb::handle value) {
                const InArray a = as_floats(value, r.param->name.c_str());
                if (a.ndim() > 1 && r.param->kind == Parameter::Kind::texture &&
                    !(a.ndim() == 3 && a.shape(0) == std::size_t(r.param->height) &&
                      a.shape(1) == std::size_t(r.param->width) && a.shape(2) == 3))
                    throw Error(r.param->name + ": expected shape (" +
                                std::to_string(r.param->height) + ", " +
                                std::to_string(r.param->width) + ", 3)");
                const FloatSpan s = span(a);
                on_device(*r.session, [&] { r.session->set_value(*r.param, s); });
            },
            "The current value as a float32 array of `shape` (a copy). Assigning writes it "
            "through to the device: an array of `shape` (or flat), one float for every element, "
            "or one rgb for every texel; ValueError for another size, NaN or a value outside "
            "`range`. An assignment also sets the previous state of render_two_state().")
        .def("__repr__", [](const ParamRef& r) {
            std::string shape = nb::cast<std::string>(nb::repr(param_shape(*r.param)));
            return "<tandem.Parameter '" + r.param->name + "' " + kind_name(r.param->kind) + " " +
                   shape + ">";
        });

    nb::class_<ParamMap>(m, "Params", "`scene.params`: a mapping from names to Parameter.")
        .def("__len__", [](const ParamMap& p) { return p.session->parameters().size(); })
        .def(
            "__getitem__",
            [](const ParamMap& p, const std::string& name) {
                for (const Parameter& q : p.session->parameters())
                    if (q.name == name) return ParamRef{p.session, &q};
                throw nb::key_error(
                    (name + " (known: " + [&] {
                        std::string s;
                        for (const Parameter& q : p.session->parameters())
                            s += (s.empty() ? "" : ", ") + q.name;
                        return s;
                    }() + ")").c_str());
            },
            nb::keep_alive<0, 1>())
        .def("__contains__",
             [](const ParamMap& p, nb::handle name) {
                 if (!nb::isinstance<nb::str>(name)) return false;
                 const std::string n = nb::cast<std::string>(name);
                 for (const Parameter& q : p.session->parameters())
                     if (q.name == n) return true;
                 return false;
             })
        .def("__iter__",
             [](const ParamMap& p) {
                 nb::list names;
                 for (const Parameter& q : p.session->parameters()) names.append(q.name);
                 return names.attr("__iter__")();
             })
        .def("__repr__", [](const ParamMap& p) {
            std::string s = "<tandem.Params";
            for (const Parameter& q : p.session->parameters()) s += " " + q.name;
            return s + ">";
        });

    nb::class_<Session>(m, "Scene",
                        "A scene loaded onto an OpenCL device (tandem.load), with its current "
                        "parameter values.")
        .def_prop_ro("path", &Session::path)
        .def_prop_ro("width", &Session::width)
        .def_prop_ro("height", &Session::height)
        .def_prop_ro("spp", &Session::default_spp, "the scene's samples per pixel (its sampler)")
        .def_prop_ro("device", [](const Session& s) { return device_dict(s.device_info()); })
        .def_prop_ro(
            "params", [](Session& s) { return ParamMap{&s}; }, nb::keep_alive<0, 1>(),
            "The differentiable parameters, by name.")
        .def(
            "render",
            [](Session& s, int spp, std::uint32_t seed) {
                std::vector<float> rgb = on_device(s, [&] { return s.render(spp, seed); });
                return image(std::move(rgb), s);
            },
            "spp"_a = 0, "seed"_a = 0,
            "Renders the current parameters: `spp` paths per pixel (0: the scene's) with `seed`. "
            "Returns float32 (height, width, 3), bit for bit `tandem render --spp SPP --seed "
            "SEED`.")
        .def(
            "render_two_state",
            [](Session& s, int spp, std::uint32_t seed, nb::object previous) {
                std::vector<InArray> keep;
                std::vector<std::pair<const Parameter*, FloatSpan>> prev;
                if (!previous.is_none())
                    prev = named_spans(s, nb::cast<nb::dict>(previous), keep, "previous");
                auto [f, h] = on_device(s, [&] { return s.render_two_state(spp, seed, prev); });
                return nb::make_tuple(image(std::move(f), s), image(std::move(h), s));
            },
            "spp"_a = 0, "seed"_a = 0, "previous"_a = nb::none(),
            "The fused two-state render of the recursive control variate: returns (F, H), the "
            "current parameters and the previous ones rendered along the same paths. The "
            "previous state is the one before the last Optimizer.step or value assignment; "
            "`previous` ({name: value}) overrides it for the parameters it names.")
        .def(
            "backward",
            [](Session& s, nb::handle delta, int spp, std::uint32_t seed, nb::handle params) {
                const InArray d = as_floats(delta, "delta");
                const FloatSpan ds = image_span(d, s, "delta");
                const std::vector<const Parameter*> ps = select(s, params);
                std::vector<float> g = on_device(s, [&] { return s.backward(ds, spp, seed, ps); });
                return gradient_dict(g, ps);
            },
            "delta"_a, "spp"_a = 0, "seed"_a = 0, "params"_a = nb::none(),
            "Path Replay Backpropagation: given delta = dloss/dimage (height, width, 3) of any "
            "loss the caller computed (NumPy, PyTorch, JAX), replays `spp` paths per pixel with "
            "`seed` and returns {name: dloss/dparam} for `params` (a name, a list of names, or "
            "None for all). Use a seed independent of the render that fed the loss. The gradient "
            "also stays on the device for Optimizer.step().")
        .def(
            "grad",
            [](Session& s, const std::string& loss, nb::handle ref, nb::handle params, int spp,
               int spp_grad, std::uint32_t seed) {
                InArray r;
                FloatSpan rs;
                if (!ref.is_none()) {
                    r = as_floats(ref, "ref");
                    rs = image_span(r, s, "ref");
                }
                const std::vector<const Parameter*> ps = select(s, params);
                Session::GradResult g =
                    on_device(s, [&] { return s.grad(loss, rs, ps, spp, spp_grad, seed); });
                return nb::make_tuple(g.loss, gradient_dict(g.gradient, ps));
            },
            "loss"_a = "mean", "ref"_a = nb::none(), "params"_a = nb::none(), "spp"_a = 0,
            "spp_grad"_a = 0, "seed"_a = 0,
            "`tandem grad`: renders (primal_seed(seed, 0), spp), takes the built-in loss ('mean', "
            "'l1', 'l2' or 'rl2' against `ref`) and its delta on the device, and replays "
            "(adjoint_seed(seed, 0), spp_grad; 0: spp). Returns (loss, {name: gradient}), bit for "
            "bit the CLI's.")
        .def("__repr__", [](const Session& s) {
            return "<tandem.Scene '" + s.path() + "' " + std::to_string(s.width()) + "x" +
                   std::to_string(s.height()) + " on '" + s.device_info().name + "'>";
        });

    m.def(
        "load",
        [](const std::string& path, nb::object device, nb::kwargs defines) {
            const std::string dev =
                device.is_none() ? std::string() : nb::cast<std::string>(nb::str(device));
            const auto ds = defines_of(defines);
            nb::gil_scoped_release release;
            return new Session(path, dev, ds);
        },
        "path"_a, "device"_a = nb::none(), "defines"_a,
        nb::rv_policy::take_ownership,
        "Loads a scene (Mitsuba 3 XML subset) onto a device (an index or a name substring as "
        "`--device`; None: $TANDEM_DEVICE, else the first GPU, else the first device). Keyword "
        "arguments override the scene's <default> values like -D name=value, e.g. "
        "tandem.load('scenes/cbox.xml', res=64).");

    nb::class_<ControlVariate>(
        m, "ControlVariate",
        "The recursive control variate (Nicolet et al. 2023): keeps per-element statistics "
        "across calls. Each iteration, call it with F and H of scene.render_two_state().")
        .def(
            "__init__",
            [](ControlVariate* self, Session& scene, const std::string& variance, unsigned warmup,
               float beta1, float beta2) {
                nb::gil_scoped_release release;
                std::lock_guard<std::mutex> lock(scene.mutex());
                new (self) ControlVariate(scene, cv_variance(variance), warmup, beta1, beta2);
            },
            "scene"_a, "variance"_a = "consistent", "warmup"_a = 1, "beta1"_a = 0.9f,
            "beta2"_a = 0.999f, nb::keep_alive<1, 2>(),
            "variance: 'consistent' or 'reference' (the paper's eq. 10); warmup: iterations that "
            "use C = F; beta1, beta2: decay rates of the means and second moments.")
        .def(
            "__call__",
            [](ControlVariate& cv, nb::handle f, nb::handle h) {
                Session& s = cv.session();
                const InArray fa = as_floats(f, "F"), ha = as_floats(h, "H");
                const FloatSpan fs = image_span(fa, s, "F"), hs = image_span(ha, s, "H");
                std::vector<float> c = on_device(s, [&] { return cv(fs, hs); });
                return image(std::move(c), s);
            },
            "F"_a, "H"_a, "C_n, the control-variate estimate of this iteration's image.")
        .def_prop_ro(
            "alpha",
            [](ControlVariate& cv) {
                std::vector<float> a = on_device(cv.session(), [&] { return cv.alpha(); });
                return nb::cast(image(std::move(a), cv.session())); // owns its data
            },
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
               float beta1, float beta2, float epsilon) {
                OptimizerConfig c;
                if (method == "adam")
                    c.method = OptimizerConfig::Method::adam;
                else if (method == "sgd")
                    c.method = OptimizerConfig::Method::sgd;
                else
                    throw Error("optimizer method '" + method + "': expected 'adam' or 'sgd'");
                c.beta1 = beta1;
                c.beta2 = beta2;
                c.epsilon = epsilon;
                std::vector<std::pair<const Parameter*, float>> rates;
                for (auto [key, value] : lr)
                    rates.emplace_back(&scene.parameter(nb::cast<std::string>(key)),
                                       nb::cast<float>(value));
                nb::gil_scoped_release release;
                std::lock_guard<std::mutex> lock(scene.mutex());
                new (self) SceneOptimizer(scene, rates, c);
            },
            "scene"_a, "lr"_a, "method"_a = "adam", "beta1"_a = 0.9f, "beta2"_a = 0.999f,
            "epsilon"_a = 1e-8f, nb::keep_alive<1, 2>(),
            "lr: {parameter name: learning rate}; the other parameters are not changed.")
        .def(
            "step",
            [](SceneOptimizer& o, nb::object grads) {
                Session& s = o.session();
                std::vector<InArray> keep;
                std::vector<std::pair<const Parameter*, FloatSpan>> g;
                if (!grads.is_none()) g = named_spans(s, nb::cast<nb::dict>(grads), keep, "gradient");
                on_device(s, [&] { o.step(grads.is_none() ? nullptr : &g); });
            },
            "grads"_a = nb::none(),
            "One step, clamped to each parameter's range. grads: {name: gradient} (the others "
            "count as zero), or None for the gradient the last backward() or grad() left on the "
            "device (no copy). The values before the step become the previous state of the next "
            "render_two_state().")
        .def_prop_ro("steps", &SceneOptimizer::steps);

    m.def(
        "optimize",
        [](const std::string& config, const std::string& out, bool resume, int until,
           nb::object device, bool progress, bool timing) {
            const OptimizeConfig c = load_optimize_config(config);
            OptimizeOptions o;
            o.out_dir = out;
            o.resume = resume;
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
            nb::dict j;
            j["iterations"] = s.iterations_done;
            j["loss"] = s.final_loss;
            j["param_error"] = s.param_error;
            j["image_error"] = s.image_error;
            j["seconds"] = s.seconds;
            j["primal_seconds"] = s.primal_seconds;
            j["adjoint_seconds"] = s.adjoint_seconds;
            j["other_seconds"] = s.other_seconds;
            j["alpha_mean"] = s.alpha_mean;
            j["guards"] = s.guards;
            j["cv_plan"] = s.cv_plan;
            j["cv_variance"] = s.cv_variance;
            j["out"] = out;
            return j;
        },
        "config"_a, "out"_a = "optimize-out", "resume"_a = false, "until"_a = 0,
        "device"_a = nb::none(), "progress"_a = true, "timing"_a = false,
        "`tandem optimize CONFIG --out OUT`: the same run, files and checkpoints. Returns the "
        "summary of `--json` as a dict. resume: continue from OUT/checkpoint.bin; until: stop "
        "after this iteration; timing: measure device time per stage (*_seconds). Ctrl-C stops "
        "between iterations (KeyboardInterrupt); the last checkpoint stays.");
}
