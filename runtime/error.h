// Error type of the runtime and core libraries: a one-line message that names the cause (the file
// and line, the device, the OpenCL call and code). The CLI prints it and exits nonzero.
#pragma once

#include <stdexcept>
#include <string>

namespace tandem {

/// `message` with its line breaks shown as \n and \r: an Error names what a file holds (a key,
/// a name, a header line), and a file may hold line breaks there (found by fuzz/).
inline std::string escape_line_breaks(const std::string& message) {
    std::string out;
    for (const char c : message)
        out += c == '\n' ? "\\n" : c == '\r' ? "\\r" : std::string(1, c);
    return out;
}

/// A user-facing failure. what() is one line, whatever the message quotes (build logs are kept
/// separately in detail()).
class Error : public std::runtime_error {
public:
    explicit Error(const std::string& message, std::string detail = {})
        : std::runtime_error(escape_line_breaks(message)), m_detail(std::move(detail)) {}
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

/// A multi-line message (a compiler's, OpenImageIO's, Assimp's) as one line, as an Error's
/// what() is: its non-empty lines, trimmed, joined by "; ".
inline std::string one_line(const std::string& text) {
    std::string out;
    for (std::size_t at = 0; at <= text.size();) {
        std::size_t end = text.find('\n', at);
        if (end == std::string::npos) end = text.size();
        const std::size_t b = text.find_first_not_of(" \t\r", at);
        if (b < end) {
            const std::size_t e = text.find_last_not_of(" \t\r", end - 1);
            out += (out.empty() ? "" : "; ") + text.substr(b, e - b + 1);
        }
        at = end + 1;
    }
    return out;
}

} // namespace tandem
