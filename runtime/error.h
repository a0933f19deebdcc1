// Error type of the runtime and core libraries: a one-line message that names the cause (the file
// and line, the device, the OpenCL call and code). The CLI prints it and exits nonzero.
#pragma once

#include <stdexcept>
#include <string>

namespace tandem {

/// A user-facing failure. what() is one line (build logs are kept separately in detail()).
class Error : public std::runtime_error {
public:
    explicit Error(const std::string& message, std::string detail = {})
        : std::runtime_error(message), m_detail(std::move(detail)) {}
    /// Extra multi-line context, such as a full kernel build log; may be empty.
    const std::string& detail() const { return m_detail; }

private:
    std::string m_detail;
};

/// A failure of the device or its driver rather than of the input: no OpenCL device, a context,
/// an allocation, a transfer, a kernel build or launch that failed. Callers that distinguish the
/// two (the Python module raises RuntimeError for these and ValueError for other Errors) catch it
/// first; everyone else treats it as an Error.
class DeviceError : public Error {
public:
    using Error::Error;
};

} // namespace tandem
