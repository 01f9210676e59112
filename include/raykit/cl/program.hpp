// raykit/cl/program.hpp — assembling OpenCL C programs, building them once.
//
//   std::vector<SourcePart> parts{{"raykit/kernels/layout", kernels::kLayout},
//                                 {"<hook wave>", WaveHook::source}};
//   Program p = build_program(dev, assemble(parts), "-cl-fast-relaxed-math");
//   ::cl::Kernel k = p.kernel("rk_vertex_wave");
//
// A program is assembled from named parts (kernel headers under
// kernels/raykit/kernels/, hook sources): each part is preceded by
// `#line 1 "NAME"`, so a compiler message about a part names that part and
// the line within it ("<hook wave>:3:12: error: ..."). A compiler that ignores #line
// (NVIDIA's) reports lines of the whole text; a failed build's log is mapped back to parts.
//
// build_program() caches built programs for the life of the process, keyed
// by (source, options, device, context): every pipeline, test and benchmark
// in a process shares one build. A failed build throws BuildError carrying
// the full build log (failures are not cached: the next call tries again).
//
// PoCL compiles a kernel for its work-group size on the first launch, so a
// program's first launch is slow too; keep Kernel objects (or at least the
// Program) alive between frames. Kernel objects are not thread-safe
// (clSetKernelArg): one per user thread.
#pragma once

#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cstdio>
#include <map>
#include <memory>
#include <mutex>
#include <regex>
#include <span>
#include <sstream>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

#include "raykit/cl/device.hpp"
#include "raykit/config.hpp"

namespace raykit::cl {

/// One named piece of program text.
struct SourcePart {
    std::string name;  ///< what compiler messages call this part (goes into #line)
    std::string text;
};

/// What precedes each part's name in an assembled program (locate_in_parts reads it back).
inline constexpr std::string_view kPartDirective = "#line 1 \"";

/// Concatenates the parts, each preceded by `#line 1 "name"` and followed by
/// a newline. Quotes and backslashes in names are replaced by '_'.
inline std::string assemble(std::span<const SourcePart> parts) {
    std::string out;
    std::size_t n = 0;
    for (const SourcePart& p : parts) n += p.text.size() + p.name.size() + 16;
    out.reserve(n);
    for (const SourcePart& p : parts) {
        std::string name = p.name;
        for (char& c : name)
            if (c == '"' || c == '\\' || c == '\n') c = '_';
        out.append(kPartDirective).append(name).append("\"\n");
        out += p.text;
        if (out.empty() || out.back() != '\n') out += '\n';
    }
    return out;
}
inline std::string assemble(std::initializer_list<SourcePart> parts) {
    return assemble(std::span<const SourcePart>(parts.begin(), parts.size()));
}

namespace detail {
/// The build log with its locations in parts: NVIDIA's compiler (CUDA 13's OpenCL) ignores
/// `#line` and reports lines of the whole text ("<kernel>:935:13: error: ..."), so a
/// location at the start of a log line whose file is no part's name, and whose line lies
/// inside a part, becomes "NAME:LINE" of that part. Locations already in parts stay as they are.
inline std::string locate_in_parts(const std::string& source, const std::string& log) {
    std::vector<std::pair<std::size_t, std::string>> parts;  // (line of the part's directive, name)
    std::size_t lines = 0;
    std::istringstream src(source);
    for (std::string l; std::getline(src, l);)
        if (++lines; l.starts_with(kPartDirective) && l.size() > kPartDirective.size() && l.back() == '"')
            parts.emplace_back(lines, l.substr(kPartDirective.size(), l.size() - kPartDirective.size() - 1));
    static const std::regex location(R"(^(\s*)([^\s:]+):(\d{1,9}):)");
    std::string out;
    std::istringstream in(log);
    for (std::string l; std::getline(in, l);) {
        std::smatch m;
        if (std::regex_search(l, m, location) &&
            std::none_of(parts.begin(), parts.end(), [&](const auto& p) { return p.second == m[2].str(); })) {
            const std::size_t at = std::stoul(m[3].str());
            const std::pair<std::size_t, std::string>* part = nullptr;
            for (const auto& p : parts)
                if (p.first < at) part = &p;
            if (part && at <= lines) l = m[1].str() + part->second + ":" + std::to_string(at - part->first) + ":" + m.suffix().str();
        }
        out += l;
        if (!in.eof()) out += '\n';
    }
    return out;
}
}  // namespace detail

/// A built program (a cheap handle; copies share the OpenCL object).
class Program {
public:
    Program() = default;
    Program(::cl::Program p, double build_ms, bool cached, std::string log)
        : program_(std::move(p)), build_ms_(build_ms), cached_(cached), log_(std::move(log)) {}

    /// A new kernel object for the __kernel function `name`.
    ::cl::Kernel kernel(const std::string& name) const {
        cl_int err = CL_SUCCESS;
        ::cl::Kernel k(program_, name.c_str(), &err);
        check(err, "clCreateKernel(" + name + ")");
        return k;
    }
    const ::cl::Program& handle() const noexcept { return program_; }
    /// Milliseconds clBuildProgram took when the program was first built.
    double build_ms() const noexcept { return build_ms_; }
    /// True when build_program() found it in the cache.
    bool cached() const noexcept { return cached_; }
    /// Build log of the successful build (warnings; often empty).
    const std::string& log() const noexcept { return log_; }

private:
    ::cl::Program program_;
    double build_ms_ = 0.0;
    bool cached_ = false;
    std::string log_;
};

/// Counters of the process-wide program cache.
struct ProgramCacheStats {
    std::size_t builds = 0;  ///< programs compiled
    std::size_t hits = 0;    ///< build_program() calls answered from the cache
    double build_ms = 0.0;   ///< total time spent in clBuildProgram
};

namespace detail {

struct ProgramCache {
    using Key = std::tuple<cl_context, cl_device_id, std::string, std::string>;  // ctx, dev, options, source
    std::mutex m;
    std::map<Key, Program> programs;
    ProgramCacheStats stats;
};
inline ProgramCache& program_cache() {
    static auto* c = new ProgramCache();  // lives until exit, like Device::shared
    return *c;
}

}  // namespace detail

inline ProgramCacheStats program_cache_stats() {
    auto& c = detail::program_cache();
    std::lock_guard lock(c.m);
    return c.stats;
}

/// Builds `source` with `options` for `dev`, or returns the cached build.
/// Throws BuildError (with the full log) when compilation fails.
inline Program build_program(Device& dev, const std::string& source, const std::string& options = {}) {
    auto& c = detail::program_cache();
    std::lock_guard lock(c.m);  // held while building: concurrent requests for one program build it once
    const detail::ProgramCache::Key key{dev.context()(), dev.handle()(), options, source};
    if (auto it = c.programs.find(key); it != c.programs.end()) {
        ++c.stats.hits;
        const Program& p = it->second;
        return Program(p.handle(), p.build_ms(), true, p.log());
    }
    cl_int err = CL_SUCCESS;
    ::cl::Program prog(dev.context(), source, false, &err);
    check(err, "clCreateProgramWithSource");
    const auto t0 = std::chrono::steady_clock::now();
    const cl_int berr = prog.build(std::vector<::cl::Device>{dev.handle()}, options.c_str());
    const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    cl_int lerr = CL_SUCCESS;
    std::string log = detail::trim(prog.getBuildInfo<CL_PROGRAM_BUILD_LOG>(dev.handle(), &lerr));
    if (lerr != CL_SUCCESS) log = std::string("(no build log: ") + error_name(lerr) + ")";
    if (berr != CL_SUCCESS) throw BuildError("clBuildProgram", berr, detail::locate_in_parts(source, log));
    ++c.stats.builds;
    c.stats.build_ms += ms;
    Program p(prog, ms, false, log);
    c.programs.emplace(key, p);
    return p;
}

/// Options every raykit kernel program is built with on `dev`: correctly
/// rounded float division and sqrt where the device offers it (so 1/d and
/// the camera and triangle tests round like the CPU), nothing relaxed; on
/// NVIDIA's platform, RK_NV_PTX.
inline std::string raykit_build_options(const Device& dev) {
    std::string o;
    if (dev.info().correctly_rounded_divide_sqrt) o += "-cl-fp32-correctly-rounded-divide-sqrt";
    // NVIDIA's mem_fence is a work-group fence; RK_NV_PTX makes RK_GLOBAL_FENCE membar.gl (kernels/common.hpp)
    if (dev.info().platform_name.find("NVIDIA") != std::string::npos)
        o += std::string(o.empty() ? "" : " ") + "-DRK_NV_PTX=1";
    return o;
}

/// Exact text of a float as a C hex-float literal ("0x1.000006p+0f").
inline std::string hex_float(float f) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%af", static_cast<double>(f));
    return buf;
}

// ---------------------------------------------------------------- launching

namespace detail {
inline std::string kernel_name(const ::cl::Kernel& k) {
    cl_int err = CL_SUCCESS;
    std::string n = trim(k.getInfo<CL_KERNEL_FUNCTION_NAME>(&err));
    return err == CL_SUCCESS ? n : std::string("?");
}
template <class T>
void set_arg(::cl::Kernel& k, cl_uint i, const T& v) {
    cl_int err = CL_SUCCESS;
    if constexpr (requires { v.handle(); })  // raykit::cl::Buffer
        err = k.setArg(i, v.handle());
    else
        err = k.setArg(i, v);
    if (err != CL_SUCCESS) throw Error("clSetKernelArg(" + kernel_name(k) + ", " + std::to_string(i) + ")", err);
}
}  // namespace detail

/// Sets the kernel's arguments 0, 1, ... from `args` (buffers, scalars, PODs).
template <class... Args>
void set_args(::cl::Kernel& k, const Args&... args) {
    cl_uint i = 0;
    (detail::set_arg(k, i++, args), ...);
}

/// Enqueues k over `global` work-items (rounded up to a multiple of `local`;
/// kernels check their index against the real count). Enqueues nothing when
/// global is 0 and returns false then. `event` receives the launch's event.
inline bool launch(::cl::CommandQueue& q, ::cl::Kernel& k, std::size_t global, std::size_t local = 64,
                   ::cl::Event* event = nullptr) {
    if (global == 0) return false;
    const std::size_t g = (global + local - 1) / local * local;
    const cl_int err = q.enqueueNDRangeKernel(k, ::cl::NullRange, ::cl::NDRange(g), ::cl::NDRange(local), nullptr, event);
    if (err != CL_SUCCESS) throw Error("clEnqueueNDRangeKernel(" + detail::kernel_name(k) + ")", err);
    return true;
}

}  // namespace raykit::cl
