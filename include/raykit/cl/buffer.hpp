// raykit/cl/buffer.hpp — typed device buffers.
//
//   Buffer<Ray> rays(dev, host_rays);          // allocate + upload
//   Buffer<Hit> hits(dev, host_rays.size());   // allocate only
//   std::vector<Hit> out = hits.read(dev);     // blocking download
//
// T must be trivially copyable and have the same layout on the device (the
// crossing structs are checked in raykit/cl/layout.hpp). An empty buffer
// still allocates one element, since OpenCL has no zero-sized buffers;
// size() reports the element count asked for.
#pragma once

#include <cstddef>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "raykit/cl/device.hpp"
#include "raykit/math/types.hpp"
#include "raykit/util/block_cache.hpp"

namespace raykit::cl {

/// vec3s as the flat float array the device reads with vload3.
inline std::span<const float> float_span(std::span<const vec3> v) noexcept {
    return {reinterpret_cast<const float*>(v.data()), v.size() * 3};
}

template <class T>
class Buffer {
    static_assert(std::is_trivially_copyable_v<T>, "device buffers hold trivially copyable types");

public:
    Buffer() = default;
    Buffer(Device& dev, std::size_t count, cl_mem_flags flags = CL_MEM_READ_WRITE) { allocate(dev, count, flags); }
    Buffer(Device& dev, std::span<const T> data, cl_mem_flags flags = CL_MEM_READ_WRITE) {
        allocate(dev, data.size(), flags);
        write(dev, data);
    }
    Buffer(Device& dev, const std::vector<T>& data, cl_mem_flags flags = CL_MEM_READ_WRITE)
        : Buffer(dev, std::span<const T>(data), flags) {}

    /// (Re)allocates for `count` elements; contents are undefined.
    void allocate(Device& dev, std::size_t count, cl_mem_flags flags = CL_MEM_READ_WRITE) {
        cl_int err = CL_SUCCESS;
        const std::size_t n = count == 0 ? 1 : count;
        buffer_ = ::cl::Buffer(dev.context(), flags, n * sizeof(T), nullptr, &err);
        if (err != CL_SUCCESS)
            throw Error("clCreateBuffer(" + std::to_string(n * sizeof(T)) + " bytes)", err);
        size_ = count;
        capacity_ = n;
        advise_huge_pages(dev, n * sizeof(T));
    }
    /// Allocates only when the buffer holds fewer than `count` elements.
    void reserve(Device& dev, std::size_t count, cl_mem_flags flags = CL_MEM_READ_WRITE) {
        if (buffer_() == nullptr || capacity_ < count) allocate(dev, count, flags);
        size_ = count;
    }

    /// Copies `data` to elements [offset, offset + data.size()).
    void write(Device& dev, std::span<const T> data, std::size_t offset = 0, bool blocking = true) {
        if (data.empty()) return;
        if (offset + data.size() > capacity_) throw std::out_of_range("raykit::cl::Buffer::write past the end");
        check(dev.queue().enqueueWriteBuffer(buffer_, blocking ? CL_TRUE : CL_FALSE, offset * sizeof(T),
                                             data.size() * sizeof(T), data.data()),
              "clEnqueueWriteBuffer");
    }
    /// Copies elements [offset, offset + out.size()) into `out` (blocking).
    void read(Device& dev, std::span<T> out, std::size_t offset = 0) const {
        if (out.empty()) return;
        if (offset + out.size() > capacity_) throw std::out_of_range("raykit::cl::Buffer::read past the end");
        check(dev.queue().enqueueReadBuffer(buffer_, CL_TRUE, offset * sizeof(T), out.size() * sizeof(T), out.data()),
              "clEnqueueReadBuffer");
    }
    std::vector<T> read(Device& dev) const {
        std::vector<T> out(size_);
        read(dev, std::span<T>(out));
        return out;
    }

    std::size_t size() const noexcept { return size_; }
    std::size_t bytes() const noexcept { return size_ * sizeof(T); }
    const ::cl::Buffer& handle() const noexcept { return buffer_; }
    operator const ::cl::Buffer&() const noexcept { return buffer_; }  // NOLINT: pass as a kernel argument

private:
    /// On a CPU device (PoCL), a new buffer of 4 MiB or more is mapped once, before anything is
    /// written to it, and the 2 MiB-aligned part of its memory advised as huge pages (the host
    /// side does the same, util/block_cache.hpp). A CPU device's buffer is host memory that the
    /// driver allocates with plain 4 KiB pages, and a random ray's walk over the 1M torus's
    /// 57 MB of nodes and blocks then missed the TLB at most steps: PoCL's random closest rays
    /// took 126 ms, 0.75x the CPU's 94 ms, and 104 ms (0.90x) with huge pages. Advice only:
    /// where the mapping fails or is a copy, nothing changes.
    void advise_huge_pages([[maybe_unused]] Device& dev, [[maybe_unused]] std::size_t bytes) {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
        if (bytes < 2 * ::raykit::detail::kHugePageBytes || !dev.info().is_cpu()) return;
        cl_int err = CL_SUCCESS;
        void* p = dev.queue().enqueueMapBuffer(buffer_, CL_TRUE, CL_MAP_WRITE_INVALIDATE_REGION, 0, bytes, nullptr,
                                               nullptr, &err);
        if (err != CL_SUCCESS || p == nullptr) return;
        ::raykit::detail::advise_huge_pages(p, bytes);
        dev.queue().enqueueUnmapMemObject(buffer_, p);
#endif
    }

    ::cl::Buffer buffer_;
    std::size_t size_ = 0;
    std::size_t capacity_ = 0;
};

/// Host memory that device results are read back into: a CL_MEM_ALLOC_HOST_PTR
/// buffer mapped once and kept mapped (never passed to a kernel), which a driver
/// can pin. On an H200 the renderer's 4.9 MB image read back 2.05-2.43 ms into a
/// new std::vector and 1.00-1.14 ms into a stage. Grows on demand; move-only;
/// unmapped on destruction.
template <class T>
class HostStage {
    static_assert(std::is_trivially_copyable_v<T>, "host stages hold trivially copyable types");

public:
    HostStage() = default;
    HostStage(const HostStage&) = delete;
    HostStage& operator=(const HostStage&) = delete;
    HostStage(HostStage&& o) noexcept { swap(o); }
    HostStage& operator=(HostStage&& o) noexcept {
        swap(o);
        return *this;
    }
    ~HostStage() { release(); }

    /// `count` elements of mapped host memory, valid until the next larger request.
    std::span<T> get(Device& dev, std::size_t count) {
        if (count > count_) {
            release();
            cl_int err = CL_SUCCESS;
            buffer_ = ::cl::Buffer(dev.context(), CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, count * sizeof(T), nullptr,
                                   &err);
            if (err != CL_SUCCESS)
                throw Error("clCreateBuffer(CL_MEM_ALLOC_HOST_PTR, " + std::to_string(count * sizeof(T)) + " bytes)", err);
            queue_ = dev.queue();
            void* p = queue_.enqueueMapBuffer(buffer_, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, count * sizeof(T), nullptr,
                                              nullptr, &err);
            check(err, "clEnqueueMapBuffer");
            ptr_ = static_cast<T*>(p);
            count_ = count;
        }
        return {ptr_, count};
    }

private:
    void release() noexcept {
        if (ptr_ != nullptr) {
            queue_.enqueueUnmapMemObject(buffer_, ptr_);
            queue_.finish();
        }
        ptr_ = nullptr;
        count_ = 0;
        buffer_ = ::cl::Buffer();
    }
    void swap(HostStage& o) noexcept {
        std::swap(buffer_, o.buffer_);
        std::swap(queue_, o.queue_);
        std::swap(ptr_, o.ptr_);
        std::swap(count_, o.count_);
    }

    ::cl::Buffer buffer_;
    ::cl::CommandQueue queue_;
    T* ptr_ = nullptr;
    std::size_t count_ = 0;
};

}  // namespace raykit::cl
