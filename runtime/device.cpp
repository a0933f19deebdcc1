// OpenCL platform and device discovery, and device selection.
#include "runtime/device.h"

#include <algorithm>
#include <cctype>
#include <cstdlib>

#include "runtime/error.h"

namespace tandem {

namespace {

std::string trim(std::string s) {
    // Some drivers pad info strings with NULs or spaces.
    while (!s.empty() && (s.back() == '\0' || std::isspace(static_cast<unsigned char>(s.back()))))
        s.pop_back();
    return s;
}

std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

std::string type_name(cl_device_type type) {
    if (type & CL_DEVICE_TYPE_GPU) return "GPU";
    if (type & CL_DEVICE_TYPE_CPU) return "CPU";
    if (type & CL_DEVICE_TYPE_ACCELERATOR) return "accelerator";
    return "other";
}

} // namespace

std::vector<DeviceInfo> list_devices() {
    std::vector<cl::Platform> platforms;
    try {
        cl::Platform::get(&platforms);
    } catch (const cl::Error& e) {
        if (e.err() != CL_PLATFORM_NOT_FOUND_KHR)
            throw DeviceError(std::string("OpenCL platform query failed: ") + e.what() + " (" +
                        cl_error_name(e.err()) + ")");
        platforms.clear();
    }
    if (platforms.empty())
        throw DeviceError("no OpenCL platform found: install an OpenCL driver (on Debian: apt-get install "
                    "pocl-opencl-icd) and check OCL_ICD_VENDORS");
    std::vector<DeviceInfo> out;
    for (const cl::Platform& platform : platforms) {
        std::vector<cl::Device> devices;
        try {
            platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
        } catch (const cl::Error&) {
            continue; // a platform without devices (CL_DEVICE_NOT_FOUND) is not an error
        }
        for (const cl::Device& d : devices) {
            DeviceInfo info;
            info.index = static_cast<int>(out.size());
            info.platform = trim(platform.getInfo<CL_PLATFORM_NAME>());
            info.platform_version = trim(platform.getInfo<CL_PLATFORM_VERSION>());
            info.name = trim(d.getInfo<CL_DEVICE_NAME>());
            info.vendor = trim(d.getInfo<CL_DEVICE_VENDOR>());
            info.type = type_name(d.getInfo<CL_DEVICE_TYPE>());
            info.driver_version = trim(d.getInfo<CL_DRIVER_VERSION>());
            info.opencl_c_version = trim(d.getInfo<CL_DEVICE_OPENCL_C_VERSION>());
            info.compute_units = d.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
            info.global_mem_bytes = d.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
            info.max_alloc_bytes = d.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
            const cl_device_fp_config fp = d.getInfo<CL_DEVICE_SINGLE_FP_CONFIG>();
            info.correctly_rounded_divide_sqrt = (fp & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) != 0;
            info.denormals = (fp & CL_FP_DENORM) != 0;
            info.hardware_fma = (fp & CL_FP_FMA) != 0;
            info.native_float_width = d.getInfo<CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT>();
            info.device = d;
            out.push_back(std::move(info));
        }
    }
    if (out.empty()) throw DeviceError("OpenCL platforms were found, but none has a device");
    return out;
}

DeviceInfo select_device(const std::string& spec) {
    std::vector<DeviceInfo> devices = list_devices();
    if (spec.empty()) {
        for (const DeviceInfo& d : devices)
            if (d.type == "GPU") return d;
        return devices.front();
    }
    const bool numeric = std::all_of(spec.begin(), spec.end(),
                                     [](unsigned char c) { return std::isdigit(c) != 0; });
    if (numeric) {
        const long index = std::strtol(spec.c_str(), nullptr, 10);
        if (index >= 0 && index < static_cast<long>(devices.size())) return devices[index];
        throw Error("device index " + spec + " is out of range: there " +
                    (devices.size() == 1 ? std::string("is 1 device")
                                         : "are " + std::to_string(devices.size()) + " devices") +
                    " (see `tandem devices`)");
    }
    const std::string needle = lower(spec);
    for (const DeviceInfo& d : devices)
        if (lower(d.platform + " " + d.name).find(needle) != std::string::npos) return d;
    throw Error("no OpenCL device matches '" + spec + "' (see `tandem devices`)");
}

} // namespace tandem
