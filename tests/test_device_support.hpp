// Shared set-up of raykit's OpenCL test programs. Include it from exactly one
// source file of a test program (it defines __lsan_default_options).
#pragma once

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <mutex>
#include <string>

#include "raykit/cl.hpp"

// Under ASan, LeakSanitizer's exit-time scan can die on a bogus dynamic TLS range
// that the runtime's __tls_get_addr hook made up for one of PoCL's blocks ("Tracer
// caught signal 11", "DTLS ... at 0x..."; RAYKIT_TEST_ENV in the top-level
// CMakeLists.txt says when). The same setting as ctest's, for a device test program
// run by hand. Leak checking stays on (tests/lsan.supp).
extern "C" const char* __lsan_default_options() { return "intercept_tls_get_addr=0"; }

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

/// With RAYKIT_TEST_CL_SOURCES naming a folder, the program writes the text and options of
/// every OpenCL program it built there when it ends, one file each ("// options: ..." first);
/// tests/cl_programs_check.cmake compiles them with clang's OpenCL C front ends.
struct ProgramSourceDump {
    ~ProgramSourceDump() {
        const char* dir = std::getenv("RAYKIT_TEST_CL_SOURCES");
        if (!dir || !*dir) return;
        auto& c = raykit::cl::detail::program_cache();
        std::lock_guard lock(c.m);
        for (const auto& entry : c.programs) {
            const std::string& options = std::get<2>(entry.first);
            const std::string& source = std::get<3>(entry.first);
            char name[32];
            std::snprintf(name, sizeof name, "%016zx.cl", std::hash<std::string>{}(options + '\n' + source));
            std::ofstream(std::string(dir) + "/" + name) << "// options: " << options << "\n" << source;
        }
    }
};
inline ProgramSourceDump program_source_dump;

}  // namespace raykit::test
