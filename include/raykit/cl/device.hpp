// raykit/cl/device.hpp — choosing an OpenCL device; its context and queue.
//
//   raykit::cl::Device& dev = raykit::cl::Device::shared();        // default choice
//   raykit::cl::Device& cpu = raykit::cl::Device::shared("pthread"); // name substring
//   raykit::cl::Device& d01 = raykit::cl::Device::shared("0:1");     // platform 0, device 1
//
// Choice, in this order:
//   1. the spec passed to the API (Device::shared(spec), choose_device(spec)),
//   2. else the environment variable RAYKIT_CL_DEVICE,
//   3. else the first GPU of any platform (platform order, then device order),
//   4. else PoCL's CPU device (platform "Portable Computing Language"),
//   5. else the first device of the first platform that has one.
// A spec is "P:D" (platform index, device index, as list_devices() numbers
// them) or a case-insensitive substring of "platform name / device name";
// the first device matching wins. A spec matching nothing throws
// NoDeviceError listing the devices there are.
//
// No OpenCL platform, or no device on any platform, throws NoDeviceError
// whose message says what to install (never a crash). Nothing here runs at
// static initialisation: the first call does the work.
//
// Device::shared() objects live until the process ends (one per OpenCL
// device, created on first use and deliberately never destroyed, so no
// OpenCL object is released while the ICD loader is being torn down). They
// own one context and one in-order command queue with profiling enabled.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cctype>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "raykit/cl/error.hpp"

namespace raykit::cl {

/// How to get a device: the line every "no device" message ends with.
inline constexpr const char* kInstallHint =
    "install an OpenCL driver (ICD) and the ICD loader: on Debian/Ubuntu `apt install pocl-opencl-icd "
    "ocl-icd-libopencl1` for the CPU (PoCL), or your GPU vendor's OpenCL ICD";

/// One OpenCL device as list_devices() reports it.
struct DeviceInfo {
    unsigned platform_index = 0;  ///< position of the platform in clGetPlatformIDs order
    unsigned device_index = 0;    ///< position of the device within its platform
    std::string platform_name;
    std::string platform_version;
    std::string name;
    std::string vendor;
    std::string version;           ///< CL_DEVICE_VERSION
    std::string opencl_c_version;  ///< CL_DEVICE_OPENCL_C_VERSION
    cl_device_type type = 0;
    cl_uint compute_units = 0;
    cl_ulong global_memory = 0;
    bool fp64 = false;                         ///< cl_khr_fp64 (doubles in kernels)
    bool correctly_rounded_divide_sqrt = false;  ///< CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT
    ::cl::Device handle;

    bool is_gpu() const noexcept { return (type & CL_DEVICE_TYPE_GPU) != 0; }
    bool is_cpu() const noexcept { return (type & CL_DEVICE_TYPE_CPU) != 0; }
    bool is_pocl() const { return platform_name.find("Portable Computing Language") != std::string::npos; }
    /// "GPU", "CPU", "accelerator" or "other".
    const char* type_name() const noexcept {
        return is_gpu() ? "GPU" : is_cpu() ? "CPU" : (type & CL_DEVICE_TYPE_ACCELERATOR) ? "accelerator" : "other";
    }
    /// "P:D platform / device (TYPE)".
    std::string label() const {
        return std::to_string(platform_index) + ":" + std::to_string(device_index) + " " + platform_name + " / " +
               name + " (" + type_name() + ")";
    }
};

namespace detail {

template <cl_int Param, class Obj>
auto cl_info(const Obj& obj, const char* call) {
    cl_int err = CL_SUCCESS;
    auto v = obj.template getInfo<Param>(&err);
    check(err, call);
    return v;
}

/// Strings from OpenCL may carry a trailing NUL; drop it.
inline std::string trim(std::string s) {
    while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) s.pop_back();
    return s;
}

inline bool is_digit(char c) noexcept { return c >= '0' && c <= '9'; }

inline std::string lower(std::string_view s) {
    std::string r(s);
    for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return r;
}

}  // namespace detail

/// Every device of every platform, numbered as "P:D" specs use them.
/// Throws NoDeviceError when there is no OpenCL platform at all; a platform
/// without devices contributes nothing (the result may be empty).
inline std::vector<DeviceInfo> list_devices() {
    std::vector<::cl::Platform> platforms;
    const cl_int err = ::cl::Platform::get(&platforms);
    if (err == CL_PLATFORM_NOT_FOUND_KHR || (err == CL_SUCCESS && platforms.empty()))
        throw NoDeviceError("clGetPlatformIDs", err == CL_SUCCESS ? CL_PLATFORM_NOT_FOUND_KHR : err,
                            std::string("no OpenCL platform found; ") + kInstallHint);
    check(err, "clGetPlatformIDs");
    std::vector<DeviceInfo> out;
    for (unsigned p = 0; p < platforms.size(); ++p) {
        std::vector<::cl::Device> devices;
        const cl_int derr = platforms[p].getDevices(CL_DEVICE_TYPE_ALL, &devices);
        if (derr == CL_DEVICE_NOT_FOUND) continue;
        check(derr, "clGetDeviceIDs");
        const std::string pname = detail::trim(detail::cl_info<CL_PLATFORM_NAME>(platforms[p], "clGetPlatformInfo"));
        const std::string pver = detail::trim(detail::cl_info<CL_PLATFORM_VERSION>(platforms[p], "clGetPlatformInfo"));
        for (unsigned d = 0; d < devices.size(); ++d) {
            const ::cl::Device& dev = devices[d];
            DeviceInfo info;
            info.platform_index = p;
            info.device_index = d;
            info.platform_name = pname;
            info.platform_version = pver;
            info.name = detail::trim(detail::cl_info<CL_DEVICE_NAME>(dev, "clGetDeviceInfo(CL_DEVICE_NAME)"));
            info.vendor = detail::trim(detail::cl_info<CL_DEVICE_VENDOR>(dev, "clGetDeviceInfo(CL_DEVICE_VENDOR)"));
            info.version = detail::trim(detail::cl_info<CL_DEVICE_VERSION>(dev, "clGetDeviceInfo(CL_DEVICE_VERSION)"));
            info.opencl_c_version =
                detail::trim(detail::cl_info<CL_DEVICE_OPENCL_C_VERSION>(dev, "clGetDeviceInfo(CL_DEVICE_OPENCL_C_VERSION)"));
            info.type = detail::cl_info<CL_DEVICE_TYPE>(dev, "clGetDeviceInfo(CL_DEVICE_TYPE)");
            info.compute_units = detail::cl_info<CL_DEVICE_MAX_COMPUTE_UNITS>(dev, "clGetDeviceInfo(CL_DEVICE_MAX_COMPUTE_UNITS)");
            info.global_memory = detail::cl_info<CL_DEVICE_GLOBAL_MEM_SIZE>(dev, "clGetDeviceInfo(CL_DEVICE_GLOBAL_MEM_SIZE)");
            const std::string ext = detail::cl_info<CL_DEVICE_EXTENSIONS>(dev, "clGetDeviceInfo(CL_DEVICE_EXTENSIONS)");
            const cl_device_fp_config dbl =
                detail::cl_info<CL_DEVICE_DOUBLE_FP_CONFIG>(dev, "clGetDeviceInfo(CL_DEVICE_DOUBLE_FP_CONFIG)");
            info.fp64 = ext.find("cl_khr_fp64") != std::string::npos || dbl != 0;
            const cl_device_fp_config sgl =
                detail::cl_info<CL_DEVICE_SINGLE_FP_CONFIG>(dev, "clGetDeviceInfo(CL_DEVICE_SINGLE_FP_CONFIG)");
            info.correctly_rounded_divide_sqrt = (sgl & CL_FP_CORRECTLY_ROUNDED_DIVIDE_SQRT) != 0;
            info.handle = dev;
            out.push_back(std::move(info));
        }
    }
    return out;
}

/// The chosen device and why it was chosen (for logs and `raykit devices`).
struct DeviceChoice {
    DeviceInfo info;
    std::string reason;
};

/// Picks a device among `devices` by the rules at the top of this file.
/// `spec` empty means: use RAYKIT_CL_DEVICE if set, else the default rule.
inline DeviceChoice choose_device(const std::vector<DeviceInfo>& devices, std::string_view spec) {
    if (devices.empty()) throw NoDeviceError(std::string("an OpenCL platform exists but it has no device; ") + kInstallHint);
    std::string source = "requested";
    std::string s(spec);
    if (s.empty()) {
        if (const char* env = std::getenv("RAYKIT_CL_DEVICE"); env && *env) {
            s = env;
            source = "RAYKIT_CL_DEVICE";
        }
    }
    if (!s.empty()) {
        // "P:D"
        const auto colon = s.find(':');
        if (colon != std::string::npos && colon > 0 && colon + 1 < s.size() &&
            std::all_of(s.begin(), s.begin() + std::ptrdiff_t(colon), detail::is_digit) &&
            std::all_of(s.begin() + std::ptrdiff_t(colon) + 1, s.end(), detail::is_digit)) {
            if (colon <= 6 && s.size() - colon <= 7) {  // longer numbers cannot be indices
                const unsigned long p = std::stoul(s.substr(0, colon)), d = std::stoul(s.substr(colon + 1));
                for (const DeviceInfo& di : devices)
                    if (di.platform_index == p && di.device_index == d)
                        return {di, source + " \"" + s + "\" (platform:device index)"};
            }
        } else {
            const std::string needle = detail::lower(s);
            for (const DeviceInfo& di : devices)
                if (detail::lower(di.platform_name + " / " + di.name).find(needle) != std::string::npos)
                    return {di, source + " \"" + s + "\" (name match)"};
        }
        std::string list;
        for (const DeviceInfo& di : devices) list += "\n  " + di.label();
        throw NoDeviceError(source + " device spec \"" + s + "\" matches no OpenCL device; devices are:" + list);
    }
    for (const DeviceInfo& di : devices)
        if (di.is_gpu()) return {di, "first GPU"};
    for (const DeviceInfo& di : devices)
        if (di.is_pocl() && di.is_cpu()) return {di, "no GPU found: PoCL CPU device"};
    return {devices.front(), "no GPU and no PoCL CPU device: first device"};
}

inline DeviceChoice choose_device(std::string_view spec = {}) { return choose_device(list_devices(), spec); }

/// A device with its context and one in-order, profiling-enabled queue.
class Device {
public:
    explicit Device(DeviceInfo info, std::string reason = {}) : info_(std::move(info)), reason_(std::move(reason)) {
        cl_int err = CL_SUCCESS;
        context_ = ::cl::Context(info_.handle, nullptr, nullptr, nullptr, &err);
        check(err, "clCreateContext");
        queue_ = ::cl::CommandQueue(context_, info_.handle, CL_QUEUE_PROFILING_ENABLE, &err);
        check(err, "clCreateCommandQueueWithProperties");
    }
    Device(const Device&) = delete;
    Device& operator=(const Device&) = delete;

    /// The process-wide Device for `spec` (see the rules above), created on
    /// first use; later calls resolving to the same OpenCL device return the
    /// same object, so programs built for it are shared.
    static Device& shared(std::string_view spec = {}) {
        static std::mutex m;
        static auto* devices = new std::map<cl_device_id, Device*>();  // never freed, see top
        std::lock_guard lock(m);
        DeviceChoice c = choose_device(spec);
        auto& slot = (*devices)[c.info.handle()];
        if (!slot) slot = new Device(std::move(c.info), std::move(c.reason));
        return *slot;
    }

    const DeviceInfo& info() const noexcept { return info_; }
    /// Why this device was chosen ("first GPU", "RAYKIT_CL_DEVICE \"pthread\" (name match)", ...).
    const std::string& reason() const noexcept { return reason_; }
    const ::cl::Device& handle() const noexcept { return info_.handle; }
    const ::cl::Context& context() const noexcept { return context_; }
    ::cl::CommandQueue& queue() noexcept { return queue_; }

    /// Waits for every command queued so far.
    void finish() { check(queue_.finish(), "clFinish"); }

private:
    DeviceInfo info_;
    std::string reason_;
    ::cl::Context context_;
    ::cl::CommandQueue queue_;
};

}  // namespace raykit::cl
