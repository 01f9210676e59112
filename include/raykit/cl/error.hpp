// raykit/cl/error.hpp — OpenCL error reporting for the device layer.
//
// Every OpenCL call raykit makes goes through check(): a non-success code
// becomes a raykit::cl::Error whose message names the call and the error
// ("clEnqueueNDRangeKernel(rk_trace_closest) failed: CL_INVALID_WORK_GROUP_SIZE (-54)").
// The C++ bindings are used without CL_HPP_ENABLE_EXCEPTIONS; raykit checks
// the codes itself, so it works whatever the user defines.
//
// This header is also where the bindings are configured: the defaults below
// (target OpenCL 3.0, minimum 2.0 — Debian 12's opencl.hpp does not compile
// with minimum 1.2 and target 3.0) apply unless the build defines them (the
// raykit::cl CMake target does, with the same values).
#pragma once

#ifndef CL_HPP_TARGET_OPENCL_VERSION
#define CL_HPP_TARGET_OPENCL_VERSION 300
#endif
#ifndef CL_HPP_MINIMUM_OPENCL_VERSION
#define CL_HPP_MINIMUM_OPENCL_VERSION 200
#endif

#include <CL/opencl.hpp>

#include <stdexcept>
#include <string>

namespace raykit::cl {

/// The symbolic name of an OpenCL error code ("CL_INVALID_VALUE"), or
/// "unknown OpenCL error" for codes this table does not know.
inline const char* error_name(cl_int code) noexcept {
    switch (code) {
#define RAYKIT_CL_ERR(name, value) \
    case value: return #name;
        RAYKIT_CL_ERR(CL_SUCCESS, 0)
        RAYKIT_CL_ERR(CL_DEVICE_NOT_FOUND, -1)
        RAYKIT_CL_ERR(CL_DEVICE_NOT_AVAILABLE, -2)
        RAYKIT_CL_ERR(CL_COMPILER_NOT_AVAILABLE, -3)
        RAYKIT_CL_ERR(CL_MEM_OBJECT_ALLOCATION_FAILURE, -4)
        RAYKIT_CL_ERR(CL_OUT_OF_RESOURCES, -5)
        RAYKIT_CL_ERR(CL_OUT_OF_HOST_MEMORY, -6)
        RAYKIT_CL_ERR(CL_PROFILING_INFO_NOT_AVAILABLE, -7)
        RAYKIT_CL_ERR(CL_MEM_COPY_OVERLAP, -8)
        RAYKIT_CL_ERR(CL_IMAGE_FORMAT_MISMATCH, -9)
        RAYKIT_CL_ERR(CL_IMAGE_FORMAT_NOT_SUPPORTED, -10)
        RAYKIT_CL_ERR(CL_BUILD_PROGRAM_FAILURE, -11)
        RAYKIT_CL_ERR(CL_MAP_FAILURE, -12)
        RAYKIT_CL_ERR(CL_MISALIGNED_SUB_BUFFER_OFFSET, -13)
        RAYKIT_CL_ERR(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST, -14)
        RAYKIT_CL_ERR(CL_COMPILE_PROGRAM_FAILURE, -15)
        RAYKIT_CL_ERR(CL_LINKER_NOT_AVAILABLE, -16)
        RAYKIT_CL_ERR(CL_LINK_PROGRAM_FAILURE, -17)
        RAYKIT_CL_ERR(CL_DEVICE_PARTITION_FAILED, -18)
        RAYKIT_CL_ERR(CL_KERNEL_ARG_INFO_NOT_AVAILABLE, -19)
        RAYKIT_CL_ERR(CL_INVALID_VALUE, -30)
        RAYKIT_CL_ERR(CL_INVALID_DEVICE_TYPE, -31)
        RAYKIT_CL_ERR(CL_INVALID_PLATFORM, -32)
        RAYKIT_CL_ERR(CL_INVALID_DEVICE, -33)
        RAYKIT_CL_ERR(CL_INVALID_CONTEXT, -34)
        RAYKIT_CL_ERR(CL_INVALID_QUEUE_PROPERTIES, -35)
        RAYKIT_CL_ERR(CL_INVALID_COMMAND_QUEUE, -36)
        RAYKIT_CL_ERR(CL_INVALID_HOST_PTR, -37)
        RAYKIT_CL_ERR(CL_INVALID_MEM_OBJECT, -38)
        RAYKIT_CL_ERR(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR, -39)
        RAYKIT_CL_ERR(CL_INVALID_IMAGE_SIZE, -40)
        RAYKIT_CL_ERR(CL_INVALID_SAMPLER, -41)
        RAYKIT_CL_ERR(CL_INVALID_BINARY, -42)
        RAYKIT_CL_ERR(CL_INVALID_BUILD_OPTIONS, -43)
        RAYKIT_CL_ERR(CL_INVALID_PROGRAM, -44)
        RAYKIT_CL_ERR(CL_INVALID_PROGRAM_EXECUTABLE, -45)
        RAYKIT_CL_ERR(CL_INVALID_KERNEL_NAME, -46)
        RAYKIT_CL_ERR(CL_INVALID_KERNEL_DEFINITION, -47)
        RAYKIT_CL_ERR(CL_INVALID_KERNEL, -48)
        RAYKIT_CL_ERR(CL_INVALID_ARG_INDEX, -49)
        RAYKIT_CL_ERR(CL_INVALID_ARG_VALUE, -50)
        RAYKIT_CL_ERR(CL_INVALID_ARG_SIZE, -51)
        RAYKIT_CL_ERR(CL_INVALID_KERNEL_ARGS, -52)
        RAYKIT_CL_ERR(CL_INVALID_WORK_DIMENSION, -53)
        RAYKIT_CL_ERR(CL_INVALID_WORK_GROUP_SIZE, -54)
        RAYKIT_CL_ERR(CL_INVALID_WORK_ITEM_SIZE, -55)
        RAYKIT_CL_ERR(CL_INVALID_GLOBAL_OFFSET, -56)
        RAYKIT_CL_ERR(CL_INVALID_EVENT_WAIT_LIST, -57)
        RAYKIT_CL_ERR(CL_INVALID_EVENT, -58)
        RAYKIT_CL_ERR(CL_INVALID_OPERATION, -59)
        RAYKIT_CL_ERR(CL_INVALID_GL_OBJECT, -60)
        RAYKIT_CL_ERR(CL_INVALID_BUFFER_SIZE, -61)
        RAYKIT_CL_ERR(CL_INVALID_MIP_LEVEL, -62)
        RAYKIT_CL_ERR(CL_INVALID_GLOBAL_WORK_SIZE, -63)
        RAYKIT_CL_ERR(CL_INVALID_PROPERTY, -64)
        RAYKIT_CL_ERR(CL_INVALID_IMAGE_DESCRIPTOR, -65)
        RAYKIT_CL_ERR(CL_INVALID_COMPILER_OPTIONS, -66)
        RAYKIT_CL_ERR(CL_INVALID_LINKER_OPTIONS, -67)
        RAYKIT_CL_ERR(CL_INVALID_DEVICE_PARTITION_COUNT, -68)
        RAYKIT_CL_ERR(CL_INVALID_PIPE_SIZE, -69)
        RAYKIT_CL_ERR(CL_INVALID_DEVICE_QUEUE, -70)
        RAYKIT_CL_ERR(CL_INVALID_SPEC_ID, -71)
        RAYKIT_CL_ERR(CL_MAX_SIZE_RESTRICTION_EXCEEDED, -72)
        RAYKIT_CL_ERR(CL_PLATFORM_NOT_FOUND_KHR, -1001)
#undef RAYKIT_CL_ERR
        default: return "unknown OpenCL error";
    }
}

/// An OpenCL call failed (or, for subclasses, the device layer could not do
/// what was asked). what() reads "CALL failed: NAME (CODE)[: detail]".
class Error : public std::runtime_error {
public:
    Error(std::string call, cl_int code, const std::string& detail = {})
        : std::runtime_error(call + " failed: " + error_name(code) + " (" + std::to_string(code) + ")" +
                             (detail.empty() ? "" : ": " + detail)),
          call_(std::move(call)),
          code_(code) {}
    /// For failures that are not one OpenCL call (code is CL_SUCCESS then).
    Error(std::string call, const std::string& message)
        : std::runtime_error(message), call_(std::move(call)), code_(CL_SUCCESS) {}

    const std::string& call() const noexcept { return call_; }
    cl_int code() const noexcept { return code_; }

private:
    std::string call_;
    cl_int code_;
};

/// No OpenCL platform or no device: the message says what to install.
class NoDeviceError : public Error {
public:
    NoDeviceError(std::string call, cl_int code, const std::string& detail) : Error(std::move(call), code, detail) {}
    explicit NoDeviceError(const std::string& message) : Error("raykit::cl::choose_device", message) {}
};

/// A program failed to build; what() carries the full build log, whose
/// locations name the part of the program (kernel header or hook) and line.
class BuildError : public Error {
public:
    BuildError(std::string call, cl_int code, std::string log)
        : Error(std::move(call), code, "build log:\n" + log), log_(std::move(log)) {}
    const std::string& log() const noexcept { return log_; }

private:
    std::string log_;
};

/// Throws Error(call, code) unless code is CL_SUCCESS.
inline void check(cl_int code, const char* call) {
    if (code != CL_SUCCESS) throw Error(call, code);
}
inline void check(cl_int code, const std::string& call) {
    if (code != CL_SUCCESS) throw Error(call, code);
}

}  // namespace raykit::cl
