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
//
// The switches of docs/tuning.md are read from the environment (tuning_from_environment) when a
// call opens a device (tandem.load, tandem.optimize: Context::create) and when devices() reports
// PoCL's work-group method: a change of os.environ applies from the next such call.
#include <filesystem>
#include <string>
#include <vector>

#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/pair.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include "core/inverse/gradient_step.h"
#include "core/io/image_io.h"
#include "python/src/convert.h"

using namespace nanobind::literals;
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
            PyErr_SetString(PyExc_RuntimeError, (std::string("OpenCL: ") + e.what() +
                                                 " failed: " + cl_error_name(e.err()))
                                                    .c_str());
        } catch (const Interrupted& e) {
            PyErr_SetString(PyExc_KeyboardInterrupt, e.message.c_str());
        }
    });

    m.def(
        "devices",
        [] {
            nb::list out;
            for (const DeviceInfo& d : list_devices())
                out.append(device_dict(d));
            return out;
        },
        nb::sig("def devices() -> list[dict[str, object]]"),
        "The OpenCL devices, as `tandem devices --json` lists them: a list of dicts (index, "
        "platform, name, vendor, type, compute_units, global_mem_bytes, ...).");

    m.def("primal_seed", &primal_seed, "seed"_a, "iteration"_a,
          "The seed of iteration `iteration`'s primal render in a run seeded with `seed` "
          "(`tandem grad --seed S` renders with primal_seed(S, 0)).");
    m.def("adjoint_seed", &adjoint_seed, "seed"_a, "iteration"_a,
          "The seed of iteration `iteration`'s adjoint pass in a run seeded with `seed` "
          "(`tandem grad --seed S` replays with adjoint_seed(S, 0)).");
    m.def("view_seed", &view_seed, "stream"_a, "sensor"_a,
          "The seed sensor `sensor` draws from stream seed `stream` (e.g. primal_seed(S, n)): the "
          "stream's own for sensor 0, else an independent one (`tandem grad --sensor K` and "
          "`tandem optimize` give each view its own streams this way).");

    m.def(
        "read_image",
        [](const std::filesystem::path& path) {
            int w = 0, h = 0;
            std::vector<float> rgb = read_image(path.string(), &w, &h);
            return to_numpy(std::move(rgb), {std::size_t(h), std::size_t(w), 3});
        },
        "path"_a,
        "Reads an image (EXR, PNG, PFM, ...) as float32 (height, width, 3), linear RGB (8-bit "
        "formats are decoded from sRGB). ValueError naming the file when it is unreadable or "
        "holds NaN or Inf.");
    m.def(
        "write_image",
        [](const std::filesystem::path& path, nb::handle array) {
            const InArray a = as_floats(array, "image");
            if (a.ndim() != 3 || a.shape(2) != 3)
                throw Error("write_image: expected an array (height, width, 3)");
            const float* p = a.data();
            write_image(path.string(), int(a.shape(1)), int(a.shape(0)),
                        std::vector<float>(p, p + a.size()));
        },
        "path"_a, "image"_a,
        nb::sig("def write_image(path: str | os.PathLike, image: numpy.typing.ArrayLike) -> None"),
        "Writes a (height, width, 3) image: .exr keeps linear float32, .png is sRGB 8-bit. The "
        "file is written beside the target and renamed over it.");

    bind_scene(m);
    bind_inverse(m);
}
