// RAII owner of an Embree device whose errors become tandem::Error.
#pragma once

#include <string>

#include <embree3/rtcore.h>

namespace tandem {

class EmbreeDevice {
public:
    /// `config` is Embree's device configuration string, e.g. "threads=2".
    explicit EmbreeDevice(const std::string& config = {});
    ~EmbreeDevice();
    EmbreeDevice(const EmbreeDevice&) = delete;
    EmbreeDevice& operator=(const EmbreeDevice&) = delete;

    RTCDevice get() const { return m_device; }
    /// Throws Error with Embree's last error, prefixed by `what`, if there is one.
    void check(const char* what) const;

private:
    RTCDevice m_device = nullptr;
};

} // namespace tandem
