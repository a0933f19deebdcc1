// OpenCL platform and device discovery, and device selection by index or name substring.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "runtime/cl.h"

namespace tandem {

/// What `tandem devices` reports about one device. `index` numbers devices across all platforms.
struct DeviceInfo {
    int index = 0;
    std::string platform;       ///< platform name
    std::string platform_version;
    std::string name;           ///< device name
    std::string vendor;
    std::string type;           ///< "GPU", "CPU", "accelerator" or "other"
    std::string driver_version;
    std::string opencl_c_version;
    std::uint32_t compute_units = 0;
    std::uint64_t global_mem_bytes = 0;
    std::uint64_t max_alloc_bytes = 0;
    /// CL_DEVICE_NATIVE_VECTOR_WIDTH_FLOAT: floats per native SIMD operation (8 with AVX and AVX2,
    /// 16 with AVX-512, 4 with SSE or NEON on PoCL; 1 on SIMT GPUs).
    std::uint32_t native_float_width = 1;
    /// CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT: single-precision division and sqrt can be built
    /// correctly rounded (then they give the host's bits). GPUs may instead be off by 2.5 ulp.
    bool correctly_rounded_divide_sqrt = false;
    /// CL_FP_DENORM: single-precision denormals are kept, not flushed to zero.
    bool denormals = false;
    /// CL_FP_FMA: "IEEE754-2008 fused multiply-add is supported", which we read as in hardware
    /// (PoCL sets it on this project's AVX-512 CPU; the flag is optional for single precision).
    /// kernels/shared/det_math.h calls fma(), which OpenCL requires to be correctly rounded either
    /// way; without the flag it is likely a software routine, with the same bits but slower. Not
    /// part of reproducible().
    bool hardware_fma = false;
    /// Whether Tandem's results on this device are the bits of every other reproducible device
    /// and of the host: the kernels use only correctly rounded operations (+, -, *, fma, and / and
    /// sqrt built correctly rounded) and their own transcendentals (kernels/shared/det_math.h),
    /// which holds when / and sqrt can be correctly rounded and denormals are not flushed.
    bool reproducible() const { return correctly_rounded_divide_sqrt && denormals; }
    /// Why not reproducible(), for a message; empty when it is.
    std::string reproducibility_note() const {
        std::string note;
        if (!correctly_rounded_divide_sqrt) note = "division and sqrt are not correctly rounded";
        if (!denormals) note += std::string(note.empty() ? "" : "; ") + "denormals are flushed to zero";
        return note;
    }
    cl::Device device;
};

/// Every device of every platform, in platform order. Throws Error if there is no OpenCL platform.
std::vector<DeviceInfo> list_devices();

/// Picks a device. `spec` is a device index or a case-insensitive substring of "platform device";
/// empty means the first GPU, else the first device (entry points pass Tuning::device, the user's
/// TANDEM_DEVICE, where the command line names none: Context::create).
/// Throws Error naming the spec when nothing matches.
DeviceInfo select_device(const std::string& spec = {});

} // namespace tandem
