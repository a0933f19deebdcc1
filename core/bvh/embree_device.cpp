// Embree device ownership and error reporting.
#include "core/bvh/embree_device.h"

#include "runtime/error.h"

namespace tandem {

EmbreeDevice::EmbreeDevice(const std::string& config) {
    m_device = rtcNewDevice(config.empty() ? nullptr : config.c_str());
    if (!m_device)
        throw Error("cannot create an Embree device (error " +
                    std::to_string(rtcGetDeviceError(nullptr)) + ")");
}

EmbreeDevice::~EmbreeDevice() { rtcReleaseDevice(m_device); }

void EmbreeDevice::check(const char* what) const {
    const RTCError err = rtcGetDeviceError(m_device);
    if (err != RTC_ERROR_NONE)
        throw Error(std::string(what) + ": Embree error " + std::to_string(static_cast<int>(err)));
}

} // namespace tandem
