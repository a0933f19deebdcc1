// Shared by the Python module's binding files (python/src/module.cpp, bind_scene.cpp,
// bind_inverse.cpp): conversions between Python objects and the session's C++ types, and running
// device work with the GIL released.
#pragma once

#include <cstdint>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include "python/src/session.h"
#include "runtime/device.h"
#include "runtime/error.h"
#include "runtime/pocl_llvm.h"

namespace tandem::python {

namespace nb = nanobind;

/// A float32 array on the host, C-contiguous; nanobind converts other dtypes and layouts.
using InArray = nb::ndarray<const float, nb::device::cpu, nb::c_contig>;
using OutArray = nb::ndarray<nb::numpy, float>;

/// Raised through C++ when Ctrl-C arrives during a long call; becomes KeyboardInterrupt.
struct Interrupted {
    std::string message;
};

/// A NumPy array that owns `v` (moved, not copied), of the given shape.
inline OutArray to_numpy(std::vector<float>&& v, const std::vector<std::size_t>& shape) {
    auto* owned = new std::vector<float>(std::move(v));
    nb::capsule owner(owned, [](void* p) noexcept { delete static_cast<std::vector<float>*>(p); });
    return OutArray(owned->data(), shape.size(), shape.data(), owner);
}

/// Any array-like as float32 C-contiguous (lists and scalars through numpy.ascontiguousarray).
inline InArray as_floats(nb::handle obj, const char* what) {
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

inline FloatSpan span(const InArray& a) {
    return {a.data(), a.size()};
}

/// The sensor a `sensor=` argument names: an index, or an id (str). Error naming the sensors
/// there are otherwise.
inline unsigned sensor_of(const Session& s, nb::handle sensor) {
    if (nb::isinstance<nb::str>(sensor)) return s.sensor(nb::cast<std::string>(sensor));
    const long k = nb::cast<long>(sensor);
    if (k < 0) throw Error("sensor " + std::to_string(k) + ": sensors are numbered from 0");
    return s.sensor(std::to_string(k));
}

/// An image argument: (height, width, 3) or flat, of sensor `k`'s film.
inline FloatSpan image_span(const InArray& a, const Session& s, const char* what,
                            unsigned k = 0) {
    const bool shaped = a.ndim() == 3 && a.shape(0) == s.height(k) && a.shape(1) == s.width(k) &&
                        a.shape(2) == 3;
    const bool flat = a.ndim() == 1 && a.size() == s.image_size(k);
    if (!shaped && !flat) {
        std::string shape = "(";
        for (std::size_t i = 0; i < a.ndim(); ++i)
            shape += (i ? ", " : "") + std::to_string(a.shape(i));
        shape += a.ndim() == 1 ? ",)" : ")";
        throw Error(std::string(what) + " has shape " + shape + "; the film is (" +
                    std::to_string(s.height(k)) + ", " + std::to_string(s.width(k)) + ", 3)");
    }
    return span(a);
}

/// An image of sensor `k`'s film as a (height, width, 3) array.
inline OutArray image(std::vector<float>&& v, const Session& s, unsigned k = 0) {
    return to_numpy(std::move(v), {s.height(k), s.width(k), 3});
}

/// The array shape of a parameter: (height, width, 3) for a texture, (V, 3) for a mesh's vertex
/// positions, (depth, height, width) or
/// (depth, height, width, channels) for a grid (the (z, y, x[, c]) order of its voxels, as
/// Mitsuba's VolumeGrid arrays), (size,) otherwise.
inline std::vector<std::size_t> param_dims(const Parameter& p) {
    if (p.kind == Parameter::Kind::texture) return {std::size_t(p.height), std::size_t(p.width), 3};
    if (p.kind == Parameter::Kind::vertices) return {std::size_t(p.width), 3};
    if (p.kind == Parameter::Kind::volume) {
        std::vector<std::size_t> d{std::size_t(p.depth), std::size_t(p.height), std::size_t(p.width)};
        if (p.channels != 1) d.push_back(std::size_t(p.channels));
        return d;
    }
    return {p.size};
}

inline nb::tuple param_shape(const Parameter& p) {
    nb::list dims;
    for (std::size_t d : param_dims(p)) dims.append(d);
    return nb::tuple(dims);
}

inline OutArray param_array(std::vector<float>&& v, const Parameter& p) {
    return to_numpy(std::move(v), param_dims(p));
}

/// {name: gradient} of `params` from a gradient in the registry's layout.
inline nb::dict gradient_dict(const std::vector<float>& g,
                              const std::vector<const Parameter*>& params) {
    nb::dict out;
    for (const Parameter* p : params)
        out[p->name.c_str()] =
            param_array(std::vector<float>(g.begin() + std::ptrdiff_t(p->offset),
                                           g.begin() + std::ptrdiff_t(p->offset + p->size)),
                        *p);
    return out;
}

/// Parameters named by `names` (None: every parameter of the scene but meshes' vertex
/// positions, whose gradients are taken where they are named: shape gradients run passes of their
/// own and cover diffuse meshes only, untextured or with a bilinear bitmap).
inline std::vector<const Parameter*> select(const Session& s, const nb::handle& names) {
    std::vector<const Parameter*> out;
    if (names.is_none()) {
        for (const Parameter& p : s.parameters())
            if (!p.moves_geometry()) out.push_back(&p);
        return out;
    }
    if (nb::isinstance<nb::str>(names)) {
        out.push_back(&s.parameter(nb::cast<std::string>(names)));
        return out;
    }
    for (nb::handle n : names)
        out.push_back(&s.parameter(nb::cast<std::string>(n)));
    return out;
}

/// A dict {name: array} as (parameter, span) pairs; `keep` holds the converted arrays.
inline std::vector<std::pair<const Parameter*, FloatSpan>>
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

inline std::vector<std::pair<std::string, std::string>> defines_of(const nb::kwargs& kwargs) {
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

inline nb::dict device_dict(const DeviceInfo& d) {
    nb::dict j;
    j["index"] = d.index;
    j["platform"] = d.platform;
    j["platform_version"] = d.platform_version;
    j["name"] = d.name;
    j["vendor"] = d.vendor;
    j["type"] = d.type;
    j["compute_units"] = d.compute_units;
    j["native_float_width"] = d.native_float_width;
    j["global_mem_bytes"] = d.global_mem_bytes;
    j["max_alloc_bytes"] = d.max_alloc_bytes;
    j["opencl_c_version"] = d.opencl_c_version;
    j["driver_version"] = d.driver_version;
    j["correctly_rounded_divide_sqrt"] = d.correctly_rounded_divide_sqrt;
    j["denormals"] = d.denormals;
    j["hardware_fma"] = d.hardware_fma;
    j["reproducible"] = d.reproducible();
    const WorkGroupMethod wg = pocl_work_group_method_in_effect(d, tuning_from_environment());
    j["pocl_work_group_method"] =
        wg.method.empty() ? nb::none() : nb::object(nb::str(wg.method.c_str()));
    j["pocl_work_group_method_by"] =
        wg.by.empty() ? nb::none() : nb::object(nb::str(wg.by.c_str()));
    return j;
}

/// Runs `f` on the session with the GIL released and the session's lock held.
template <class F> auto on_device(Session& s, F&& f) {
    nb::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(s.mutex());
    return f();
}

void bind_scene(nb::module_& m);   ///< Parameter, Params, Scene, load (bind_scene.cpp)
void bind_inverse(nb::module_& m); ///< ControlVariate, Optimizer, optimize (bind_inverse.cpp)

} // namespace tandem::python
