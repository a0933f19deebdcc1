// Redirecting the process' stderr for the span of a library call (runtime/program.cpp,
// core/io/image_io.cpp).
#pragma once

#include <cstdio>
#include <string>

#include <fcntl.h>
#include <unistd.h>

namespace tandem {

/// Points the process's stderr at /dev/null (discard) or at a temporary file (capture) until
/// restore() or the end of its scope: for libraries that print on stderr what they also report
/// (or report nothing else), so that an error stays one line. Users: a kernel build discards
/// PoCL's diagnostic summary (the same text is in CL_PROGRAM_BUILD_LOG, which Error::detail()
/// keeps); kernel creation captures Oclgrind's reason for a failure, printed nowhere else; image
/// reads discard libpng's own error line (core/io/image_io.cpp). Redirects the whole process:
/// single-threaded use only.
class StderrRedirect {
public:
    enum Mode { discard, capture };
    explicit StderrRedirect(Mode mode) {
        std::fflush(stderr);
        m_saved = ::dup(STDERR_FILENO);
        if (mode == capture) m_file = std::tmpfile();
        const int fd = m_file ? ::fileno(m_file) : ::open("/dev/null", O_WRONLY);
        if (m_saved >= 0 && fd >= 0) ::dup2(fd, STDERR_FILENO);
        if (!m_file && fd >= 0) ::close(fd);
    }
    ~StderrRedirect() {
        restore();
        if (m_file) std::fclose(m_file);
    }
    StderrRedirect(const StderrRedirect&) = delete;
    StderrRedirect& operator=(const StderrRedirect&) = delete;

    /// Points stderr back where it was and returns what was captured.
    std::string restore() {
        if (m_saved < 0) return {};
        std::fflush(stderr);
        ::dup2(m_saved, STDERR_FILENO);
        ::close(m_saved);
        m_saved = -1;
        std::string text;
        if (m_file && std::fseek(m_file, 0, SEEK_SET) == 0) {
            char buf[4096];
            std::size_t n;
            while ((n = std::fread(buf, 1, sizeof buf, m_file)) > 0)
                text.append(buf, n);
        }
        return text;
    }

private:
    int m_saved = -1;
    std::FILE* m_file = nullptr;
};

} // namespace tandem
