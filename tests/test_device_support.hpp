// Shared set-up of raykit's OpenCL test programs. Include it from exactly one
// source file of a test program (it defines __lsan_default_options).
#pragma once

#include <string>

#include "raykit/cl.hpp"

// Under ASan, LeakSanitizer's exit-time scan reads the dynamic TLS blocks of
// libraries PoCL loads and unloads at run time (its compiled kernels) and can
// crash on a stale block ("Tracer caught signal 11", "DTLS ... at 0x..."), so
// device test programs do not scan TLS. Leak checking stays on (tests/lsan.supp).
extern "C" const char* __lsan_default_options() { return "use_tls=0"; }

namespace raykit::test {

/// The shared device, or nullptr (with the reason) when OpenCL has no device.
/// Other failures propagate: they are bugs.
inline raykit::cl::Device* test_device(std::string* why) {
    static std::string reason;
    static raykit::cl::Device* dev = []() -> raykit::cl::Device* {
        try {
            if (raykit::cl::list_devices().empty()) {
                reason = "an OpenCL platform exists but has no device";
                return nullptr;
            }
        } catch (const raykit::cl::NoDeviceError& e) {
            reason = e.what();
            return nullptr;
        }
        return &raykit::cl::Device::shared();
    }();
    if (why) *why = reason;
    return dev;
}

}  // namespace raykit::test
