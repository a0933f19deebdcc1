// The one place that includes the Khronos OpenCL C++ bindings, with the settings Tandem builds with:
// OpenCL 1.2 API, exceptions on (cl::Error carries the failing call and its error code).
#pragma once

#define CL_HPP_TARGET_OPENCL_VERSION 120
#define CL_HPP_MINIMUM_OPENCL_VERSION 120
#define CL_HPP_ENABLE_EXCEPTIONS
#include <CL/opencl.hpp>

namespace tandem {

/// Name of an OpenCL error code, e.g. "CL_OUT_OF_RESOURCES" for -5.
const char* cl_error_name(cl_int code);

} // namespace tandem
