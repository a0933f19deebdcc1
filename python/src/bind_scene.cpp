// The Python module's scene: tandem.load, Scene, its parameters (python/src/convert.h).
#include <filesystem>

#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <nlohmann/json.hpp>

#include "core/inverse/optimize_config.h"
#include "core/render/boundary_guide.h"
#include "python/src/convert.h"

namespace tandem::python {

using namespace nb::literals;

void bind_scene(nb::module_& m) {
    nb::class_<ParamRef>(m, "Parameter",
                         "A differentiable scene parameter: a named range of the flat parameter "
                         "array (see `tandem params`).")
        .def_prop_ro("name", [](const ParamRef& r) { return r.param->name; })
        .def_prop_ro(
            "kind", [](const ParamRef& r) { return parameter_kind_name(r.param->kind); },
            "'rgb', 'texture' or 'scalar'")
        .def_prop_ro(
            "shape", [](const ParamRef& r) { return param_shape(*r.param); },
            nb::for_getter(nb::sig("def shape(self, /) -> tuple[int, ...]")),
            "(3,) for rgb, (1,) for scalar, (height, width, 3) for a texture")
        .def_prop_ro("size", [](const ParamRef& r) { return r.param->size; })
        .def_prop_ro(
            "range",
            [](const ParamRef& r) { return std::make_pair(r.param->lower, r.param->upper); },
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
                const std::vector<std::size_t> dims = param_dims(*r.param);
                bool shaped = a.ndim() == dims.size();
                for (std::size_t k = 0; shaped && k < dims.size(); ++k)
                    shaped = a.shape(k) == dims[k];
                if (a.ndim() > 1 && !shaped)
                    throw Error(r.param->name + ": expected shape " +
                                nb::cast<std::string>(nb::repr(param_shape(*r.param))));
                const FloatSpan s = span(a);
                on_device(*r.session, [&] { r.session->set_value(*r.param, s); });
            },
            nb::for_getter(nb::sig("def value(self, /) -> numpy.typing.NDArray[numpy.float32]")),
            nb::for_setter(nb::sig("def value(self, value: numpy.typing.ArrayLike, /) -> None")),
            "The current value as a float32 array of `shape` (a copy). Assigning writes it "
            "through to the device: an array of `shape` (or flat), one float for every element, "
            "or one rgb for every texel; ValueError for another size, NaN or a value outside "
            "`range`. An assignment also sets the previous state of render_two_state().")
        .def("__repr__", [](const ParamRef& r) {
            std::string shape = nb::cast<std::string>(nb::repr(param_shape(*r.param)));
            return "<tandem.Parameter '" + r.param->name + "' " + parameter_kind_name(r.param->kind) + " " +
                   shape + ">";
        });

    nb::class_<ParamMap>(m, "Params", "`scene.params`: a mapping from names to Parameter.")
        .def("__len__", [](const ParamMap& p) { return p.session->parameters().size(); })
        .def(
            "__getitem__",
            [](const ParamMap& p, const std::string& name) {
                for (const Parameter& q : p.session->parameters())
                    if (q.name == name) return ParamRef{p.session, &q};
                throw nb::key_error((name + " (known: " +
                                     [&] {
                                         std::string s;
                                         for (const Parameter& q : p.session->parameters())
                                             s += (s.empty() ? "" : ", ") + q.name;
                                         return s;
                                     }() +
                                     ")")
                                        .c_str());
            },
            nb::keep_alive<0, 1>())
        .def(
            "__setitem__",
            [](const ParamMap& p, const std::string& name, nb::handle value) {
                // `scene.params[name] = value`, as a Mitsuba user writes it: the checks of
                // Parameter.value's setter, through it
                nb::object ref = nb::cast(p).attr("__getitem__")(name);
                ref.attr("value") = value;
            },
            "name"_a, "value"_a,
            nb::sig("def __setitem__(self, name: str, value: numpy.typing.ArrayLike, /) -> None"),
            "scene.params[name] = value: the same as scene.params[name].value = value.")
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
                 for (const Parameter& q : p.session->parameters())
                     names.append(q.name);
                 return names.attr("__iter__")();
             })
        .def("__repr__", [](const ParamMap& p) {
            std::string s = "<tandem.Params";
            for (const Parameter& q : p.session->parameters())
                s += " " + q.name;
            return s + ">";
        });

    nb::class_<Session>(m, "Scene",
                        "A scene loaded onto an OpenCL device (tandem.load), with its current "
                        "parameter values.")
        .def_prop_ro("path", &Session::path)
        .def_prop_ro("width", [](const Session& s) { return s.width(0); }, "sensor 0's film width")
        .def_prop_ro("height", [](const Session& s) { return s.height(0); },
                     "sensor 0's film height")
        .def_prop_ro("spp", [](const Session& s) { return s.default_spp(0); },
                     "sensor 0's samples per pixel (its sampler)")
        .def_prop_ro(
            "sensors",
            [](const Session& s) {
                nb::list out;
                for (unsigned k = 0; k < s.sensors(); ++k) {
                    const Camera& c = s.scene().sensors[k];
                    std::vector<float> m(16);
                    for (int r = 0; r < 4; ++r)
                        for (int col = 0; col < 4; ++col)
                            m[std::size_t(4 * r + col)] = c.to_world[col][r]; // row-major
                    nb::dict d;
                    d["index"] = k;
                    d["id"] = c.id;
                    d["width"] = c.width;
                    d["height"] = c.height;
                    d["spp"] = c.spp;
                    d["fov"] = c.fov;
                    d["to_world"] = nb::cast(to_numpy(std::move(m), {4, 4}));
                    out.append(d);
                }
                return out;
            },
            nb::for_getter(nb::sig("def sensors(self, /) -> list[dict[str, object]]")),
            "The sensors in file order, each a dict: index, id ('' without one), width, height, "
            "spp, fov (degrees, along its fov_axis) and to_world (4x4 camera-to-world, "
            "row-major). `sensor=` arguments take an index or an id.")
        .def_prop_ro(
            "device", [](const Session& s) { return device_dict(s.device_info()); },
            nb::for_getter(nb::sig("def device(self, /) -> dict[str, object]")),
            "The device it is loaded on, as in devices().")
        .def_prop_ro(
            "params", [](Session& s) { return ParamMap{&s}; }, nb::keep_alive<0, 1>(),
            "The differentiable parameters, by name.")
        .def(
            "render",
            [](Session& s, int spp, std::uint32_t seed, nb::handle sensor) {
                const unsigned k = sensor_of(s, sensor);
                std::vector<float> rgb = on_device(s, [&] { return s.render(spp, seed, k); });
                return image(std::move(rgb), s, k);
            },
            "spp"_a = 0, "seed"_a = 0, "sensor"_a = 0,
            nb::sig("def render(self, spp: int = 0, seed: int = 0, sensor: int | str = 0) -> "
                    "numpy.typing.NDArray[numpy.float32]"),
            "Renders the current parameters as sensor `sensor` (an index or an id) sees them: "
            "`spp` paths per pixel (0: the sensor's) with `seed`. Returns float32 (height, width, "
            "3), bit for bit `tandem render --spp SPP --seed SEED --sensor SENSOR`.")
        .def(
            "render_two_state",
            [](Session& s, int spp, std::uint32_t seed, nb::object previous, nb::handle sensor) {
                const unsigned k = sensor_of(s, sensor);
                std::vector<InArray> keep;
                std::vector<std::pair<const Parameter*, FloatSpan>> prev;
                if (!previous.is_none())
                    prev = named_spans(s, nb::cast<nb::dict>(previous), keep, "previous");
                auto [f, h] =
                    on_device(s, [&] { return s.render_two_state(spp, seed, prev, k); });
                return nb::make_tuple(image(std::move(f), s, k), image(std::move(h), s, k));
            },
            "spp"_a = 0, "seed"_a = 0, "previous"_a = nb::none(), "sensor"_a = 0,
            nb::sig("def render_two_state(self, spp: int = 0, seed: int = 0, previous: "
                    "collections.abc.Mapping[str, numpy.typing.ArrayLike] | None = None, "
                    "sensor: int | str = 0) -> "
                    "tuple[numpy.typing.NDArray[numpy.float32], "
                    "numpy.typing.NDArray[numpy.float32]]"),
            "The fused two-state render of the recursive control variate: returns (F, H), the "
            "current parameters and the previous ones rendered along the same paths. The "
            "previous state is the one before the last Optimizer.step or value assignment; "
            "`previous` ({name: value}) overrides it for the parameters it names.")
        .def(
            "backward",
            [](Session& s, nb::handle delta, int spp, std::uint32_t seed, nb::handle params,
               nb::handle sensor) {
                const unsigned k = sensor_of(s, sensor);
                const InArray d = as_floats(delta, "delta");
                const FloatSpan ds = image_span(d, s, "delta", k);
                const std::vector<const Parameter*> ps = select(s, params);
                std::vector<float> g =
                    on_device(s, [&] { return s.backward(ds, spp, seed, ps, k); });
                return gradient_dict(g, ps);
            },
            "delta"_a, "spp"_a = 0, "seed"_a = 0, "params"_a = nb::none(), "sensor"_a = 0,
            nb::sig(
                "def backward(self, delta: numpy.typing.ArrayLike, spp: int = 0, seed: int = 0, "
                "params: str | collections.abc.Iterable[str] | None = None, "
                "sensor: int | str = 0) -> dict[str, numpy.typing.NDArray[numpy.float32]]"),
            "Path Replay Backpropagation: given delta = dloss/dimage (height, width, 3) of any "
            "loss the caller computed (NumPy, PyTorch, JAX), replays `spp` paths per pixel with "
            "`seed` and returns {name: dloss/dparam} for `params` (a name, a list of names, or "
            "None for all but meshes' vertex positions) of sensor `sensor`'s image. Use a seed independent of the render that "
            "fed the loss. The gradient also stays on the device for Optimizer.step(); for "
            "several views, add their gradients and pass them to Optimizer.step().")
        .def(
            "grad",
            [](Session& s, const std::string& loss, nb::handle ref, nb::handle params, int spp,
               int spp_grad, std::uint32_t seed, nb::handle sensor) {
                const unsigned k = sensor_of(s, sensor);
                InArray r;
                FloatSpan rs;
                if (!ref.is_none()) {
                    r = as_floats(ref, "ref");
                    rs = image_span(r, s, "ref", k);
                }
                const std::vector<const Parameter*> ps = select(s, params);
                Session::GradResult g =
                    on_device(s, [&] { return s.grad(loss, rs, ps, spp, spp_grad, seed, k); });
                return nb::make_tuple(g.loss, gradient_dict(g.gradient, ps));
            },
            "loss"_a = "mean", "ref"_a = nb::none(), "params"_a = nb::none(), "spp"_a = 0,
            "spp_grad"_a = 0, "seed"_a = 0, "sensor"_a = 0,
            nb::sig("def grad(self, loss: str = 'mean', ref: numpy.typing.ArrayLike | None = None, "
                    "params: str | collections.abc.Iterable[str] | None = None, spp: int = 0, "
                    "spp_grad: int = 0, seed: int = 0, sensor: int | str = 0) -> "
                    "tuple[float, dict[str, numpy.typing.NDArray[numpy.float32]]]"),
            "`tandem grad`: renders (primal_seed(seed, 0), spp), takes the built-in loss ('mean', "
            "'l1', 'l2' or 'rl2' against `ref`) and its delta on the device, and replays "
            "(adjoint_seed(seed, 0), spp_grad; 0: spp), of sensor `sensor` (with its own streams: "
            "view_seed). Returns (loss, {name: gradient}), bit for bit `tandem grad --sensor`'s.")
        .def(
            "faces",
            [](const Session& s, const std::string& name) {
                const MeshShape& shape = s.scene().mesh_shape(s.parameter(name));
                auto* owned = new std::vector<std::uint32_t>(s.scene().shape_triangles(shape));
                nb::capsule owner(owned, [](void* p) noexcept {
                    delete static_cast<std::vector<std::uint32_t>*>(p);
                });
                const std::size_t shape_[2] = {shape.triangle_count, 3};
                return nb::ndarray<nb::numpy, std::uint32_t>(owned->data(), 2, shape_, owner);
            },
            "name"_a,
            "The triangles of the mesh whose vertex positions are parameter `name` "
            "('SHAPE.vertex_positions'): (F, 3) uint32 indices into its (V, 3) positions "
            "(scene.params[name]).")
        .def(
            "set_boundary_samples",
            [](Session& s, int primary, int secondary, const std::string& guide,
               bool light_pairs) {
                const BoundarySamples b{primary, secondary, secondary_guide_mode(guide, "guide"),
                                        light_pairs}; // (set_boundary_reuse's reservoirs stay)
                on_device(s, [&] { s.set_boundary_samples(b); });
            },
            "primary"_a = -1, "secondary"_a = -1, "guide"_a = "auto", "light_pairs"_a = false,
            "Shape gradients: edge samples per pixel of the primary and secondary boundary terms "
            "(-1: the adjoint's spp; 0: left out), and the secondary term's guide toward glossy "
            "lobes ('auto': where a surface is roughconductor or roughplastic; 'on'; 'off'), and "
            "whether half the secondary samples aim at (edge, light) pairs whose edge may be a "
            "silhouette seen from the light (off by default: docs/method.md, 'Light pairs'), "
            "for every gradient from now on.")
        .def(
            "set_boundary_reuse",
            [](Session& s, nb::handle reuse) {
                // the value as optimize's "restir": {"boundary": ...} takes it, by way of JSON:
                // one parser, one set of checks and messages
                const std::string text =
                    nb::cast<std::string>(nb::module_::import_("json").attr("dumps")(reuse));
                nlohmann::json value;
                try {
                    value = nlohmann::json::parse(text);
                } catch (const nlohmann::json::exception&) { // NaN or infinity
                    throw Error("set_boundary_reuse: " + text + " holds a non-finite number");
                }
                const std::optional<SecondaryReuseConfig> c =
                    secondary_reuse_config("set_boundary_reuse", value);
                on_device(s, [&] { s.set_boundary_reuse(c); });
            },
            "reuse"_a = true,
            nb::sig("def set_boundary_reuse(self, reuse: bool | dict[str, object] = True) -> None"),
            "Shape gradients: the secondary boundary term reuses its light vertices from one "
            "gradient to the next (docs/restir.md, 'Reuse for the boundary'), for every gradient "
            "from now on, with reservoirs of the scene's own; each grad() reads the last one's "
            "and leaves its own. True: the default settings; a dict: some of candidates, "
            "neighbours, m_cap, cell, visibility, receiver, floor (as tandem optimize's "
            "'restir': {'boundary': {...}}); False: none, and the reservoirs are dropped (a "
            "new call starts afresh). The scene must be loaded with restir=True.")
        .def("__repr__", [](const Session& s) {
            return "<tandem.Scene '" + s.path() + "' " + std::to_string(s.width()) + "x" +
                   std::to_string(s.height()) + " on '" + s.device_info().name + "'>";
        });

    m.def(
        "load",
        [](const std::filesystem::path& path, nb::object device, bool restir,
           nb::kwargs defines) {
            const std::string dev =
                device.is_none() ? std::string() : nb::cast<std::string>(nb::str(device));
            const auto ds = defines_of(defines);
            SessionOptions options;
            options.restir = restir;
            nb::gil_scoped_release release;
            return new Session(path.string(), dev, ds, options);
        },
        "path"_a, "device"_a = nb::none(), nb::kw_only(), "restir"_a = false, "defines"_a,
        nb::rv_policy::take_ownership,
        nb::sig("def load(path: str | os.PathLike, device: int | str | None = None, *, "
                "restir: bool = False, **defines: object) -> Scene"),
        "Loads a scene (Mitsuba 3 XML subset) onto a device (an index or a name substring as "
        "`--device`; None: $TANDEM_DEVICE, else the first GPU, else the first device). Keyword "
        "arguments override the scene's <default> values like -D name=value, e.g. "
        "tandem.load('scenes/cbox.xml', res=64). restir=True builds its kernels for ReSTIR "
        "(Scene.set_boundary_reuse needs them; a longer first compile).");
}

} // namespace tandem::python
