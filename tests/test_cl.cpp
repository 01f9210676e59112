// The OpenCL device path against its CPU twins: device choice, errors,
// program cache, layouts, camera rays, traces, scenes, vertex hooks, refit.
//
// Every test skips (GTEST_SKIP) only when there is no OpenCL platform or no
// device at all; any other OpenCL failure fails the test. Programs are built
// once per process (raykit's program cache) and sizes are modest, so the
// binary stays fast, also under ASan/UBSan.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "raykit.hpp"
#include "test_support.hpp"
#include "test_device_support.hpp"
#include "raykit/cl.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/generate.hpp"
#include "raykit/scene/scene.hpp"

using namespace raykit;
namespace rcl = raykit::cl;

namespace {

using raykit::test::test_device;

#define RAYKIT_REQUIRE_DEVICE(dev)                                                       \
    std::string no_device_reason_;                                                       \
    rcl::Device* dev##_ptr_ = test_device(&no_device_reason_);                          \
    if (!dev##_ptr_) GTEST_SKIP() << "no OpenCL device, skipping: " << no_device_reason_; \
    rcl::Device& dev = *dev##_ptr_

double ms_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

using raykit::test::random_rays;

/// Rays from outside a closed mesh aimed exactly at vertices, edge midpoints
/// and edge quarter points (test_bvh.cpp's hard cases).
std::vector<Ray> vertex_edge_rays(const Mesh& m, const vec3& center, float scale, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    std::vector<Ray> rays;
    for (const Triangle& t : m.triangles) {
        const vec3 a = m.positions[t.v[0]], b = m.positions[t.v[1]];
        for (const vec3& target : {a, (a + b) * 0.5f, a + (b - a) * 0.25f}) {
            const vec3 dir(U(rng), U(rng), U(rng));
            const vec3 o = target - glm::normalize(target - center + dir * 0.5f * scale) * 3.0f * scale;
            rays.push_back({o, 0.0f, target - o, kInf});
        }
    }
    return rays;
}

Bvh build(const Mesh& m, unsigned leaf = 8) {
    BinnedSahBuilder::Config c;
    c.leaf.max_leaf_size = leaf;
    return build_bvh<BinnedSahBuilder>(m, c);
}

/// Differences between device and CPU answers.
struct Agreement {
    std::size_t rays = 0;
    std::size_t validity = 0;  ///< hit on one side only
    std::size_t prim = 0;      ///< both hit, different triangle (or instance)
    std::size_t t_bits = 0;    ///< same triangle, t not bit-identical
    std::size_t any = 0;       ///< any-hit answers differ
    std::size_t disagreements() const { return validity + prim + any; }
    void print(const char* what) const {
        std::printf("[ info ] %s: %zu rays, disagreements %zu (hit/miss %zu, triangle %zu, any-hit %zu), "
                    "t not bit-identical on %zu\n",
                    what, rays, disagreements(), validity, prim, any, t_bits);
    }
    void expect_good(const char* what) const {
        print(what);
        EXPECT_EQ(prim, 0u) << what << ": different triangles where both hit";
        EXPECT_LE(double(disagreements()), 1e-4 * double(rays)) << what << ": more than 0.01 % of rays disagree";
    }
};

Agreement compare_mesh(rcl::MeshTracer& tracer, const Mesh& m, const Bvh& bvh, const std::vector<Ray>& rays) {
    const std::vector<Hit> dh = tracer.closest(rays);
    const std::vector<std::uint32_t> da = tracer.any(rays);
    Agreement a;
    a.rays = rays.size();
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit c = intersect_closest(m, bvh, rays[i]);
        const bool ca = intersect_any(m, bvh, rays[i]);
        const Hit& d = dh[i];
        if (c.valid() != d.valid()) {
            ++a.validity;
        } else if (c.valid()) {
            if (c.prim != d.prim || c.inst != d.inst) ++a.prim;
            else if (!same_bits(c.t, d.t) || !same_bits(c.u, d.u) || !same_bits(c.v, d.v)) ++a.t_bits;
        } else if (d.inst != kInvalidIndex || !same_bits(d.t, kInf)) {
            ++a.validity;
        }
        a.any += ca != (da[i] != 0);
    }
    return a;
}

}  // namespace

// ---------------------------------------------------------------- 1. device, errors, programs

TEST(ClError, NamesTheCallAndTheError) {
    const rcl::Error e("clCreateBuffer", CL_INVALID_BUFFER_SIZE);
    EXPECT_NE(std::string(e.what()).find("clCreateBuffer"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("CL_INVALID_BUFFER_SIZE"), std::string::npos) << e.what();
    EXPECT_EQ(e.code(), CL_INVALID_BUFFER_SIZE);
    EXPECT_STREQ(rcl::error_name(CL_INVALID_VALUE), "CL_INVALID_VALUE");
    EXPECT_STREQ(rcl::error_name(CL_PLATFORM_NOT_FOUND_KHR), "CL_PLATFORM_NOT_FOUND_KHR");
    EXPECT_STREQ(rcl::error_name(-12345), "unknown OpenCL error");
}

TEST(ClDevice, ListsAndChoosesDevices) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const auto devices = rcl::list_devices();
    ASSERT_FALSE(devices.empty());
    for (const auto& d : devices) std::printf("[ info ] device %s\n", d.label().c_str());
    std::printf("[ info ] chosen: %s — %s\n", dev.info().label().c_str(), dev.reason().c_str());
    // by index and by name substring
    const rcl::DeviceChoice byidx = rcl::choose_device(devices, "0:0");
    EXPECT_EQ(byidx.info.platform_index, 0u);
    EXPECT_EQ(byidx.info.device_index, 0u);
    const rcl::DeviceChoice byname = rcl::choose_device(devices, devices.back().name.substr(0, 5));
    EXPECT_NE(byname.reason.find("name match"), std::string::npos);
    // default rule: a GPU when there is one, else PoCL's CPU device
    bool has_gpu = false;
    for (const auto& d : devices) has_gpu |= d.is_gpu();
    const char* env = std::getenv("RAYKIT_CL_DEVICE");
    if (!env || !*env) {
        const rcl::DeviceChoice def = rcl::choose_device(devices, "");
        EXPECT_EQ(def.info.is_gpu(), has_gpu) << def.reason;
    }
    // a spec matching nothing: NoDeviceError listing the devices
    try {
        rcl::choose_device(devices, "no-such-device-xyzzy");
        ADD_FAILURE() << "expected NoDeviceError";
    } catch (const rcl::NoDeviceError& e) {
        EXPECT_NE(std::string(e.what()).find("no-such-device-xyzzy"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(devices.front().name), std::string::npos) << e.what();
    }
    EXPECT_THROW(rcl::choose_device(devices, "7:99"), rcl::NoDeviceError);
    EXPECT_THROW(rcl::choose_device(std::vector<rcl::DeviceInfo>{}, ""), rcl::NoDeviceError);
}

TEST(ClDevice, NoPlatformThrowsWithInstallHint) {
    // In a fresh process (gtest re-executes the binary for this statement),
    // point the ICD loader at an empty vendor directory: no platform at all.
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    EXPECT_EXIT(
        {
            ::setenv("OCL_ICD_VENDORS", "/nonexistent-raykit-test-dir", 1);
            try {
                rcl::Device::shared();
            } catch (const rcl::NoDeviceError& e) {
                std::fprintf(stderr, "%s\n", e.what());
                std::_Exit(0);
            } catch (const std::exception& e) {
                std::fprintf(stderr, "wrong exception: %s\n", e.what());
                std::_Exit(2);
            }
            std::_Exit(3);
        },
        ::testing::ExitedWithCode(0), "no OpenCL platform found.*pocl-opencl-icd");
}

TEST(ClDevice, EnvironmentVariableOverridesTheDefault) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const auto devices = rcl::list_devices();
    const char* old = std::getenv("RAYKIT_CL_DEVICE");
    const std::string saved = old ? old : "";
    const std::string spec = std::to_string(devices.back().platform_index) + ":" + std::to_string(devices.back().device_index);
    ::setenv("RAYKIT_CL_DEVICE", spec.c_str(), 1);
    const rcl::DeviceChoice c = rcl::choose_device(devices, "");
    EXPECT_EQ(c.info.handle(), devices.back().handle());
    EXPECT_NE(c.reason.find("RAYKIT_CL_DEVICE"), std::string::npos) << c.reason;
    // the API spec wins over the environment
    const rcl::DeviceChoice api = rcl::choose_device(devices, "0:0");
    EXPECT_EQ(api.info.handle(), devices.front().handle());
    ::setenv("RAYKIT_CL_DEVICE", "no-such-device-xyzzy", 1);
    EXPECT_THROW(rcl::choose_device(devices, ""), rcl::NoDeviceError);
    if (old) ::setenv("RAYKIT_CL_DEVICE", saved.c_str(), 1);
    else ::unsetenv("RAYKIT_CL_DEVICE");
    (void)dev;
}

TEST(ClProgram, OpenClErrorsNameTheCall) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const rcl::Program p = rcl::trace_program(dev);
    ::cl::Kernel k = p.kernel("rk_camera_rays");
    try {
        rcl::detail::set_arg(k, 99, 1.0f);
        ADD_FAILURE() << "expected an Error";
    } catch (const rcl::Error& e) {
        const std::string w = e.what();
        EXPECT_NE(w.find("clSetKernelArg(rk_camera_rays, 99)"), std::string::npos) << w;
        EXPECT_NE(w.find("CL_INVALID_ARG_INDEX"), std::string::npos) << w;
    }
    try {
        (void)p.kernel("rk_no_such_kernel");
        ADD_FAILURE() << "expected an Error";
    } catch (const rcl::Error& e) {
        EXPECT_NE(std::string(e.what()).find("clCreateKernel(rk_no_such_kernel)"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("CL_INVALID_KERNEL_NAME"), std::string::npos) << e.what();
    }
}

// The renderer reads its image back into a HostStage (pinned on NVIDIA). A stage keeps its
// memory for smaller requests, grows for larger ones, and moves; reads land there exactly.
TEST(ClBuffer, HostStageHoldsReadsAndGrows) {
    RAYKIT_REQUIRE_DEVICE(dev);
    std::vector<float> src(1000);
    for (std::size_t i = 0; i < src.size(); ++i) src[i] = float(i) * 0.5f - 7.0f;
    const rcl::Buffer<float> buf(dev, src);
    rcl::HostStage<float> stage;
    const std::span<float> a = stage.get(dev, 100);
    buf.read(dev, a, 20);
    for (std::size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i], src[20 + i]) << i;
    EXPECT_EQ(stage.get(dev, 50).data(), a.data());  // a smaller request keeps the memory
    rcl::HostStage<float> moved(std::move(stage));
    const std::span<float> b = moved.get(dev, 1000);  // grows
    EXPECT_EQ(b.size(), 1000u);
    buf.read(dev, b);
    EXPECT_TRUE(std::equal(b.begin(), b.end(), src.begin()));
    stage = std::move(moved);  // the moved-from stage takes the memory back
    EXPECT_EQ(stage.get(dev, 1000).data(), b.data());
}

// A CPU device's large buffer is advised as huge pages before its first write (buffer.hpp):
// the data survive the map and unmap around the advice, and the buffer's memory (mapped again
// to find it) lies in a mapping with the advice.
TEST(ClBuffer, LargeBuffersOfACpuDeviceKeepTheirDataOnHugePageAdvice) {
    RAYKIT_REQUIRE_DEVICE(dev);
    std::vector<float> src(std::size_t(3) << 20);  // 12 MiB
    for (std::size_t i = 0; i < src.size(); ++i) src[i] = float(i % 100003) * 0.25f - 3.0f;
    rcl::Buffer<float> buf(dev, src);
    const std::vector<float> back = buf.read(dev);
    ASSERT_EQ(back.size(), src.size());
    EXPECT_TRUE(std::equal(back.begin(), back.end(), src.begin()));
    if (!dev.info().is_cpu() || !test::huge_page_advice_visible()) return;
    cl_int err = CL_SUCCESS;
    void* p = dev.queue().enqueueMapBuffer(buf.handle(), CL_TRUE, CL_MAP_READ, 0, buf.bytes(), nullptr, nullptr, &err);
    ASSERT_EQ(err, CL_SUCCESS);
    const void* middle = static_cast<const char*>(p) + buf.bytes() / 2;
    const std::string flags = test::vm_flags_of(middle);
    EXPECT_EQ(static_cast<const float*>(middle)[0], src[src.size() / 2]);
    dev.queue().enqueueUnmapMemObject(buf.handle(), p);
    dev.queue().finish();
    EXPECT_NE(flags.find(" hg"), std::string::npos) << "the buffer's mapping: " << flags;
}

TEST(ClProgram, BuildsOnceAndCaches) {
    RAYKIT_REQUIRE_DEVICE(dev);
    // a program nobody else builds: the first call compiles, the second is cached
    const std::string src = rcl::assemble({{"cache-test", "__kernel void rk_cache_probe(__global int* x) { x[0] = 42; }"}});
    auto t0 = std::chrono::steady_clock::now();
    const rcl::Program a = rcl::build_program(dev, src);
    const double first = ms_since(t0);
    t0 = std::chrono::steady_clock::now();
    const rcl::Program b = rcl::build_program(dev, src);
    const double second = ms_since(t0);
    EXPECT_FALSE(a.cached());
    EXPECT_TRUE(b.cached());
    EXPECT_EQ(a.handle()(), b.handle()());
    const rcl::Program c = rcl::build_program(dev, src, "-DRK_OTHER_OPTIONS");
    EXPECT_FALSE(c.cached());
    EXPECT_NE(a.handle()(), c.handle()());
    // the full trace program: cold (unless an earlier test built it) and cached
    t0 = std::chrono::steady_clock::now();
    const rcl::Program tp = rcl::trace_program(dev);
    const double trace_first = ms_since(t0);
    t0 = std::chrono::steady_clock::now();
    const rcl::Program tp2 = rcl::trace_program(dev);
    const double trace_cached = ms_since(t0);
    EXPECT_TRUE(tp2.cached());
    std::printf("[ info ] tiny program: build %.1f ms, cached lookup %.3f ms; trace program: clBuildProgram %.1f ms "
                "(this call %.1f ms, %s), cached lookup %.3f ms\n",
                first, second, tp.build_ms(), trace_first, tp.cached() ? "already cached" : "built here", trace_cached);
}

TEST(ClProgram, BuildErrorPointsAtTheHookLine) {
    RAYKIT_REQUIRE_DEVICE(dev);
    std::vector<rcl::SourcePart> parts = rcl::base_parts();
    parts.push_back({"<hook broken>", "rk_vertex broken(rk_vertex v) {\n    v.position[0] += 1.0f;\n    return v\n}\n"});
    try {
        rcl::build_program(dev, rcl::assemble(parts));
        ADD_FAILURE() << "expected a BuildError";
    } catch (const rcl::BuildError& e) {
        const std::string w = e.what();
        EXPECT_NE(w.find("<hook broken>:3:"), std::string::npos) << w;
        EXPECT_NE(w.find("CL_BUILD_PROGRAM_FAILURE"), std::string::npos) << w;
        EXPECT_NE(w.find("clBuildProgram"), std::string::npos) << w;
    }
}

// NVIDIA's OpenCL compiler (CUDA 13, H200) ignores #line and reports "<kernel>:935:13"; the log
// must still name the hook and its line. No device needed: the log below is NVIDIA's form.
TEST(ClProgram, LogLinesOfTheWholeTextAreNamedByPart) {
    const std::string src = rcl::assemble({{"raykit/kernels/a", "int a;\nint b;\n"}, {"<hook broken>", "x\ny\nz\n"}});
    // physical lines: 1 #line a, 2 int a, 3 int b, 4 #line hook, 5 x, 6 y, 7 z
    const std::string log = "<kernel>:6:13: error: expected ';'\n    y\n<kernel>:2:1: note: here\n"
                            "<hook broken>:1:2: warning: kept\n<kernel>:99:1: error: past the end\n"
                            "  <kernel>:7:4: note: indented\nno location: 6:1: here\n";
    const std::string got = rcl::detail::locate_in_parts(src, log);
    EXPECT_EQ(got,
              "<hook broken>:2:13: error: expected ';'\n    y\nraykit/kernels/a:1:1: note: here\n"
              "<hook broken>:1:2: warning: kept\n<kernel>:99:1: error: past the end\n"
              "  <hook broken>:3:4: note: indented\nno location: 6:1: here\n");
    // a log whose locations already name parts (PoCL's) is returned unchanged
    const std::string pocl = "<hook broken>:3:13: error: expected ';' after return statement\n";
    EXPECT_EQ(rcl::detail::locate_in_parts(src, pocl), pocl);
}

// ---------------------------------------------------------------- 2. layouts

// quantize_node (device-free): seeded random nodes at offsets from 0 to 1e30 and extents from 0
// to 1e30, with 1 to 8 slots in use; every decoded box holds its child's box, no plane is
// looser than two steps and two ulps, and the step is at most 4/255 of the extent (or the
// smallest, 2^-126). Leaves of more than 255 blocks are refused; NaN and infinite planes read
// as unbounded up to kQuantizeLimit; an empty child leaves its siblings' steps alone.
namespace {
/// `count` seeded random wide nodes: offsets from 0 to +-1e30, extents from 0 to 1e30, flat boxes,
/// 1 to 8 slots in use at scattered positions, leaves and inner children.
std::vector<rcl::DeviceNode> random_wide_nodes(int count, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    const float offsets[] = {0.0f, -3.5f, 1e3f, 1e6f, -1e7f, 3e9f, -1e30f, 1e30f};
    const float extents[] = {0.0f, 1e-30f, 1e-3f, 1.0f, 250.0f, 1e5f, 1e30f};
    std::vector<rcl::DeviceNode> out;
    for (int trial = 0; trial < count; ++trial) {
        const float off = offsets[trial % 8], ext = extents[(trial / 8) % 7];
        rcl::DeviceNode n;
        for (int c = 0; c < rcl::kDeviceWidth; ++c) n.clear(c);
        const int used = 1 + int(rng() % 8);
        for (int c = 0; c < used; ++c) {
            AABB b;
            for (int a = 0; a < 3; ++a) {
                const float x = off + ext * U(rng), y = off + ext * U(rng);
                b.min[a] = std::min(x, y);
                b.max[a] = trial % 5 == 0 ? b.min[a] : std::max(x, y);  // flat boxes too
            }
            const int slot = (c * 3 + trial) % rcl::kDeviceWidth;
            if (!n.unused(slot)) continue;
            n.set_box(slot, b);
            n.index[slot] = c % 2 ? 7u + unsigned(c) : 100u;
            n.count[slot] = c % 2 ? 0u : unsigned(1 + c);
        }
        out.push_back(n);
    }
    return out;
}
}  // namespace

TEST(ClQuantize, DecodedBoxesHoldTheChildrenAndAreTight) {
    std::size_t nodes = 0, outside = 0, loose = 0, coarse = 0;
    for (const rcl::DeviceNode& n : random_wide_nodes(4000, 2027)) {
        const std::optional<rcl::QuantizedNode> q = rcl::quantize_node(n);
        ASSERT_TRUE(q.has_value());
        ++nodes;
        for (int c = 0; c < rcl::kDeviceWidth; ++c) {
            ASSERT_EQ(((q->used >> c) & 1u) != 0, !n.unused(c));
            if (n.unused(c)) continue;
            EXPECT_EQ(q->index[c], n.index[c]);
            EXPECT_EQ(q->count[c], n.count[c]);
            const AABB want = n.box(c), got = rcl::quantized_box(*q, c);
            for (int a = 0; a < 3; ++a) {
                const double step = std::ldexp(1.0, q->exponent[a]);
                const double ulp_lo = std::abs(double(std::nextafter(want.min[a], kInf)) - want.min[a]);
                const double ulp_hi = std::abs(double(std::nextafter(want.max[a], kInf)) - want.max[a]);
                outside += !(got.min[a] <= want.min[a]) + !(got.max[a] >= want.max[a]);
                loose += (double(want.min[a]) - got.min[a] > 2 * step + 2 * ulp_lo) +
                         (double(got.max[a]) - want.max[a] > 2 * step + 2 * ulp_hi);
                float lo = kInf, hi = -kInf;
                for (int k = 0; k < rcl::kDeviceWidth; ++k)
                    if (!n.unused(k)) {
                        lo = std::min(lo, n.planes[2 * a][k]);
                        hi = std::max(hi, n.planes[2 * a + 1][k]);
                    }
                coarse += step > std::max(4.0 * (double(hi) - double(lo)) / 255.0, std::ldexp(1.0, -126));
            }
        }
    }
    std::printf("[ info ] %zu random nodes: %zu planes outside their child, %zu looser than 2 steps + 2 ulps, %zu "
                "axes with a step over 4/255 of the extent\n",
                nodes, outside, loose, coarse);
    EXPECT_EQ(outside, 0u);
    EXPECT_EQ(loose, 0u);
    EXPECT_EQ(coarse, 0u);

    rcl::DeviceNode n;
    for (int c = 0; c < rcl::kDeviceWidth; ++c) n.clear(c);
    n.set_box(0, AABB{{0, 0, 0}, {1, 1, 1}});
    n.index[0] = 3;
    n.count[0] = 255;
    EXPECT_TRUE(rcl::quantize_node(n).has_value());
    n.count[0] = 256;
    EXPECT_FALSE(rcl::quantize_node(n).has_value()) << "a leaf of 256 blocks";
    n.count[0] = 1;
    n.set_box(1, AABB{{-2, 0, 0}, {-1, 1, 1}});
    n.index[1] = 9;
    for (const float bad : {kInf, std::nanf("")}) {  // an unbounded or NaN high x plane: unbounded
        n.planes[1][0] = bad;
        const std::optional<rcl::QuantizedNode> q = rcl::quantize_node(n);
        ASSERT_TRUE(q.has_value());
        EXPECT_GE(rcl::quantized_box(*q, 0).max.x, rcl::kQuantizeLimit) << bad;
        EXPECT_LE(rcl::quantized_box(*q, 1).min.x, -2.0f) << bad;
        EXPECT_GE(rcl::quantized_box(*q, 1).max.x, -1.0f) << bad;
    }
    n.planes[0][0] = std::nanf("");  // and a NaN low x plane: unbounded below
    ASSERT_TRUE(rcl::quantize_node(n).has_value());
    EXPECT_LE(rcl::quantized_box(*rcl::quantize_node(n), 0).min.x, -rcl::kQuantizeLimit);
    n.set_box(0, AABB{});  // an empty child (a refit over NaN vertices) beside a finite one
    const std::optional<rcl::QuantizedNode> e = rcl::quantize_node(n);
    ASSERT_TRUE(e.has_value());
    EXPECT_EQ(e->used, 3u);
    EXPECT_LE(rcl::quantized_box(*e, 1).min.x, -2.0f);
    EXPECT_GE(rcl::quantized_box(*e, 1).max.x, -1.0f);
    EXPECT_LE(rcl::quantized_box(*e, 1).max.x, -0.9f) << "the empty child widened its sibling's axis";
    for (int c = 0; c < rcl::kDeviceWidth; ++c) n.clear(c);
    const std::optional<rcl::QuantizedNode> empty = rcl::quantize_node(n);
    ASSERT_TRUE(empty.has_value());
    EXPECT_EQ(empty->used, 0u);
}

// The device's quantizer (rk_quantize_nodes, kernels/raykit/kernels/quantize.hpp) against the host's
// quantize_node, byte for byte: the 4,000 seeded random nodes above, and hostile ones (NaN, +-inf
// and +-FLT_MAX planes, empty children beside finite ones, every slot empty).
TEST(ClQuantize, DeviceQuantizerWritesTheHostsBytes) {
    RAYKIT_REQUIRE_DEVICE(dev);
    std::vector<rcl::DeviceNode> nodes = random_wide_nodes(4000, 2028);
    const float fmax = std::numeric_limits<float>::max(), nan = std::numeric_limits<float>::quiet_NaN();
    const float hostile[] = {nan, kInf, -kInf, fmax, -fmax, 0.0f, -0.0f, 1e-30f};
    for (int k = 0; k < 64; ++k) {
        rcl::DeviceNode n = nodes[std::size_t(k)];
        for (int c = 0; c < rcl::kDeviceWidth; ++c)
            if (!n.unused(c) && (c + k) % 3 == 0) n.planes[(c + k) % 6][c] = hostile[(c + k) % 8];
        if (k % 4 == 0) n.set_box(k % rcl::kDeviceWidth, AABB{});  // an empty box (it may be an unused slot)
        nodes.push_back(n);
    }
    rcl::DeviceNode empty;
    for (int c = 0; c < rcl::kDeviceWidth; ++c) empty.clear(c);
    nodes.push_back(empty);
    std::vector<rcl::SourcePart> parts = rcl::base_parts();
    parts.push_back({"raykit/kernels/quantize.hpp", raykit::kernels::kQuantize});
    const rcl::Program p = rcl::build_program(dev, rcl::assemble(parts), rcl::raykit_build_options(dev));
    ::cl::Kernel k = p.kernel("rk_quantize_nodes");
    const auto n = static_cast<std::uint32_t>(nodes.size());
    rcl::Buffer<rcl::DeviceNode> in(dev, nodes);
    rcl::Buffer<rcl::QuantizedNode> out(dev, nodes.size());
    rcl::Buffer<rcl::ObjectRecord> objects(dev, 1);
    rcl::Buffer<std::uint32_t> which(dev, 1);
    rcl::set_args(k, in, out, objects, which, 0u, n);
    rcl::launch(dev.queue(), k, n, 64);
    const std::vector<rcl::QuantizedNode> got = out.read(dev);
    std::size_t differ = 0;
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        const std::optional<rcl::QuantizedNode> want = rcl::quantize_node(nodes[i]);
        ASSERT_TRUE(want.has_value()) << i;
        differ += std::memcmp(&*want, &got[i], sizeof(rcl::QuantizedNode)) != 0;
    }
    std::printf("[ info ] device quantizer: %zu nodes, %zu differ from the host's bytes\n", nodes.size(), differ);
    EXPECT_EQ(differ, 0u);
}

TEST(ClLayout, DeviceAgreesWithHost) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const auto diff = rcl::check_layout(dev);
    for (const std::string& d : diff) ADD_FAILURE() << d;
    EXPECT_TRUE(diff.empty());
    std::printf("[ info ] %zu layout numbers checked on the device\n", rcl::layout_entries().size());
    const rcl::HostFloatConfig f = rcl::host_float_config();
    std::printf("[ info ] host Watertight rounding (RAYKIT_FMA %d): A[kx]-sx*A[kz] %s, t numerator %s; device "
                "edge functions in %s\n",
                RAYKIT_FMA, f.fuse_msub ? "fused" : "unfused", f.fuse_tnum ? "fused" : "unfused",
                dev.info().fp64 ? "double (cl_khr_fp64)" : "float, FP_CONTRACT OFF");
}

// ---------------------------------------------------------------- 3. camera rays

TEST(ClCamera, CpuConventionPixelCentres) {
    Camera cam;
    cam.position = {0, 0, 0};
    cam.target = {0, 0, -1};
    cam.width = 4;
    cam.height = 2;
    cam.vfov_degrees = 90.0f;
    // top-left pixel centre: up and to the left; bottom-right: down and to the right
    const Ray tl = cam.ray(0, 0), br = cam.ray(3, 1);
    EXPECT_LT(tl.dir.x, 0.0f);
    EXPECT_GT(tl.dir.y, 0.0f);
    EXPECT_GT(br.dir.x, 0.0f);
    EXPECT_LT(br.dir.y, 0.0f);
    // the image centre (x = 2, y = 1 with zero jitter) looks straight ahead
    const Ray c = cam.ray(2, 1, 0.0f, 0.0f);
    EXPECT_NEAR(c.dir.x, 0.0f, 1e-6f);
    EXPECT_NEAR(c.dir.y, 0.0f, 1e-6f);
    EXPECT_FLOAT_EQ(c.dir.z, -1.0f);
    // corner (0, 0) with zero jitter: 45 degrees up, aspect 2 -> 2 to the left
    const Ray k = cam.ray(0, 0, 0.0f, 0.0f);
    EXPECT_NEAR(k.dir.x, -2.0f, 1e-5f);
    EXPECT_NEAR(k.dir.y, 1.0f, 1e-5f);
    EXPECT_THROW((Camera{.width = 0}).frame(), std::invalid_argument);
    EXPECT_THROW((Camera{.position = {0, 0, 0}, .target = {0, 0, 0}}).frame(), std::invalid_argument);
    EXPECT_THROW((Camera{.position = {0, 0, 5}, .target = {0, 0, 0}, .up = {0, 0, 1}}).frame(), std::invalid_argument);
}

TEST(ClCamera, DeviceRaysAreBitIdentical) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const rcl::Program p = rcl::trace_program(dev);
    ::cl::Kernel k = p.kernel("rk_camera_rays");
    std::size_t checked = 0, differ = 0;
    for (const Camera& cam : {Camera{.position = {1.5f, 0.3f, 7.0f}, .target = {0.1f, -0.2f, 0.3f}, .width = 317, .height = 203},
                              Camera{.position = {1e4f, 2e3f, -3e3f}, .target = {1e4f + 1.0f, 2e3f, -3e3f + 0.5f},
                                     .up = {0, 0, 1}, .vfov_degrees = 100.0f, .width = 640, .height = 480},
                              Camera{.position = {-2, 3, 1}, .target = {0, 0, 0}, .vfov_degrees = 10.0f, .width = 64, .height = 256}}) {
        for (const auto& [jx, jy] : {std::pair{0.5f, 0.5f}, std::pair{0.0f, 1.0f}, std::pair{0.123f, 0.987f}}) {
            const CameraFrame f = cam.frame();
            rcl::Buffer<Ray> buf;
            rcl::camera_rays(dev, k, f, buf, jx, jy);
            const std::vector<Ray> dr = buf.read(dev);
            const std::vector<Ray> cr = camera_rays(cam, jx, jy);
            ASSERT_EQ(dr.size(), cr.size());
            for (std::size_t i = 0; i < cr.size(); ++i) differ += std::memcmp(&dr[i], &cr[i], sizeof(Ray)) != 0;
            checked += cr.size();
            // Camera::ray (frame per call) equals the bulk path
            const std::size_t idx = cr.size() / 3 + 5;
            const Ray one = cam.ray(std::uint32_t(idx % cam.width), std::uint32_t(idx / cam.width), jx, jy);
            EXPECT_EQ(std::memcmp(&cr[idx], &one, sizeof(Ray)), 0);
        }
    }
    std::printf("[ info ] camera rays: %zu of %zu differ from the CPU bitwise\n", differ, checked);
    EXPECT_EQ(differ, 0u);
}

// ---------------------------------------------------------------- 4. single-mesh trace

TEST(ClTrace, ClosedMeshRandomRaysAgreeWithCpu) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Mesh m = make_bumpy_torus(20000);
    const Bvh bvh = build(m);
    rcl::MeshTracer tracer(dev, m, bvh);
    compare_mesh(tracer, m, bvh, random_rays(m, 20000, 99)).expect_good("torus 20k, random + vertex/edge-aimed rays");
}

TEST(ClTrace, SoupsAndLeafSizesAgreeWithCpu) {
    RAYKIT_REQUIRE_DEVICE(dev);
    Agreement total;
    for (std::uint64_t seed = 1; seed <= 3; ++seed) {
        const Mesh m = make_random_soup(3000, seed, 0.05f * float(seed));
        for (unsigned leaf : {1u, 4u, 8u}) {
            const Bvh bvh = build(m, leaf);
            rcl::MeshTracer tracer(dev, m, bvh);
            const Agreement a = compare_mesh(tracer, m, bvh, random_rays(m, 2000, seed * 7 + leaf));
            total.rays += a.rays;
            total.validity += a.validity;
            total.prim += a.prim;
            total.t_bits += a.t_bits;
            total.any += a.any;
        }
    }
    total.expect_good("random soups, leaves 1/4/8");
}

TEST(ClTrace, CameraRaysAgreeWithCpu) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Mesh m = make_bumpy_torus(50000);
    const Bvh bvh = build(m);
    AABB box;
    for (const vec3& p : m.positions) box.grow(p);
    const Camera cam = camera_looking_at(box, 200, 150);
    rcl::MeshTracer tracer(dev, m, bvh);
    compare_mesh(tracer, m, bvh, camera_rays(cam)).expect_good("torus 50k, camera rays");
}

TEST(ClTrace, ExactVertexAndEdgeRaysNeverMiss) {
    RAYKIT_REQUIRE_DEVICE(dev);
    Agreement total;
    std::size_t misses = 0;
    for (float scale : {1.0f, 1e3f}) {
        for (float offset : {0.0f, 1e6f}) {
            Mesh m = make_icosphere(4);
            transform_positions(m, scale, vec3(offset, -offset, offset));
            const Bvh bvh = build(m);
            const auto rays = vertex_edge_rays(m, vec3(offset, -offset, offset), scale, 42);
            rcl::MeshTracer tracer(dev, m, bvh);
            const Agreement a = compare_mesh(tracer, m, bvh, rays);
            for (const Hit& h : tracer.closest(rays)) misses += !h.valid();
            total.rays += a.rays;
            total.validity += a.validity;
            total.prim += a.prim;
            total.t_bits += a.t_bits;
            total.any += a.any;
        }
    }
    total.expect_good("icosphere vertex/edge rays (4 scales/offsets)");
    EXPECT_EQ(misses, 0u) << "the device watertight test missed a closed mesh";
}

TEST(ClTrace, FloatEdgeFunctionsStayWatertight) {
    // The path for devices without cl_khr_fp64, forced here: still never
    // misses a closed mesh; t may differ from the CPU in the last bits, so
    // at shared vertices the tie may go to a neighbouring triangle.
    RAYKIT_REQUIRE_DEVICE(dev);
    std::size_t misses = 0, rays_total = 0, prim_differs = 0, hit_differs = 0;
    for (float scale : {1.0f, 1e3f}) {
        Mesh m = make_icosphere(4);
        transform_positions(m, scale, vec3(scale * 0.3f, 0.0f, 0.0f));
        const Bvh bvh = build(m);
        const auto rays = vertex_edge_rays(m, vec3(scale * 0.3f, 0.0f, 0.0f), scale, 7);
        rcl::MeshTracer tracer(dev, m, bvh, "-DRK_EDGE_DOUBLE=0");
        const std::vector<Hit> h = tracer.closest(rays);
        for (std::size_t i = 0; i < rays.size(); ++i) {
            const Hit c = intersect_closest(m, bvh, rays[i]);
            misses += !h[i].valid();
            hit_differs += h[i].valid() != c.valid();
            prim_differs += h[i].valid() && c.valid() && h[i].prim != c.prim;
        }
        rays_total += rays.size();
    }
    std::printf("[ info ] float edge functions: %zu vertex/edge rays, %zu misses, hit/miss differs from CPU on %zu, "
                "another triangle (ties at shared edges) on %zu\n",
                rays_total, misses, hit_differs, prim_differs);
    EXPECT_EQ(misses, 0u);
}

TEST(ClTrace, EmptyMeshAndEmptyRaySet) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Mesh empty;
    const Bvh bvh = build(empty);
    rcl::MeshTracer tracer(dev, empty, bvh);
    const std::vector<Ray> rays(5);
    for (const Hit& h : tracer.closest(rays)) EXPECT_FALSE(h.valid());
    for (std::uint32_t o : tracer.any(rays)) EXPECT_EQ(o, 0u);
    EXPECT_TRUE(tracer.closest(std::vector<Ray>{}).empty());
}

// ---------------------------------------------------------------- 5. scenes of objects (CPU)

namespace {

mat4 transform_of(float angle, const vec3& axis, float scale, const vec3& shift) {
    mat4 t = glm::translate(mat4(1.0f), shift);
    t = glm::rotate(t, angle, glm::normalize(axis));
    return glm::scale(t, vec3(scale));
}

/// A scene with static and dynamic objects and several instances of each.
Scene make_test_scene(bool with_dynamic, std::size_t torus_tris = 4000) {
    Scene s;
    const std::uint32_t torus = s.add_object(make_bumpy_torus(torus_tris));
    const std::uint32_t ball = s.add_object(make_icosphere(2));
    s.add_instance(torus);
    s.add_instance(torus, transform_of(0.7f, {1, 2, 3}, 0.5f, {2.5f, 0.0f, 0.3f}));
    s.add_instance(ball, transform_of(-0.3f, {0, 1, 0}, 0.4f, {-2.0f, 0.5f, 0.0f}));
    s.add_instance(ball, transform_of(1.1f, {1, 0, 1}, 1.3f, {0.0f, -2.5f, 1.0f}));
    if (with_dynamic) {
        const std::uint32_t soup = s.add_object(make_random_soup(1500, 11, 0.1f), ObjectKind::dynamic);
        const std::uint32_t cloth = s.add_object(make_bumpy_torus(2000, 0.05f), ObjectKind::dynamic,
                                                 BinnedSahBuilder::Config{.leaf = {.max_leaf_size = 2}});
        s.add_instance(soup, transform_of(0.2f, {0, 0, 1}, 2.0f, {0.5f, 1.5f, -1.0f}));
        s.add_instance(cloth, transform_of(0.0f, {0, 0, 1}, 1.0f, {0.0f, 0.0f, 2.0f}));
        s.add_instance(cloth, transform_of(2.0f, {1, 1, 0}, 0.7f, {-2.0f, -2.0f, -1.5f}));
    }
    s.update_top_level();
    return s;
}

/// Random rays over the scene's world box, half aimed at world-space vertices.
std::vector<Ray> scene_rays(const Scene& s, std::size_t n, std::uint64_t seed) {
    const auto [w, origin] = s.world_mesh();
    return random_rays(w, n, seed);
}

}  // namespace

TEST(SceneCpu, TwoLevelTraceMatchesBruteForceExactly) {
    const Scene s = make_test_scene(true);
    std::size_t bad = 0, hits = 0;
    const auto rays = scene_rays(s, 3000, 5);
    for (const Ray& r : rays) {
        const Hit h = s.intersect_closest(r), o = s.brute_force_closest(r);
        bad += h.prim != o.prim || h.inst != o.inst || !same_bits(h.t, o.t) || s.intersect_any(r) != o.valid();
        hits += o.valid();
    }
    EXPECT_EQ(bad, 0u) << "of " << rays.size();
    EXPECT_GT(hits, rays.size() / 4);
}

TEST(SceneCpu, TwoLevelTraceMatchesWorldSpaceTriangles) {
    // The world-space oracle sees the triangles through rounded transforms,
    // so rays aimed exactly at shared vertices and edges may pick another
    // triangle of the fan (at the same t), and grazing hits move in t. Real
    // disagreements — a hit on one side only, or another surface — are rare.
    const Scene s = make_test_scene(true);
    const auto [w, origin] = s.world_mesh();
    const auto rays = random_rays(w, 3000, 6);
    std::size_t validity = 0, tie = 0, other = 0, same = 0, t_off = 0, free_bad = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Ray& r = rays[i];
        const Hit h = s.intersect_closest(r);
        const Hit o = brute_force_closest(w, r);
        if (h.valid() != o.valid()) {
            ++validity;
            free_bad += i % 2 == 0;
            continue;
        }
        if (!h.valid()) continue;
        const double rel = std::fabs(double(h.t) - double(o.t)) / std::max(1e-30, double(o.t));
        const auto [inst, prim] = origin[o.prim];
        if (inst != h.inst || prim != h.prim) {
            (rel < 1e-4 ? tie : other) += 1;
            free_bad += rel >= 1e-4 && i % 2 == 0;
            continue;
        }
        ++same;
        t_off += rel > 1e-5;
    }
    std::printf("[ info ] two-level vs world-space brute force, %zu rays: same triangle %zu (t off by > 1e-5 relative: "
                "%zu), neighbour triangle at the same t %zu, hit/miss differs %zu, other surface %zu (of these on rays not aimed at "
                "a vertex or edge: %zu)\n",
                rays.size(), same, t_off, tie, validity, other, free_bad);
    // rays aimed exactly at a vertex or edge of open geometry (the soup) may
    // slip past on either side; random rays must agree
    EXPECT_EQ(free_bad, 0u);
    EXPECT_LE(double(validity + other), 0.02 * double(rays.size() / 2));
    EXPECT_LE(double(t_off), 0.01 * double(same));
    EXPECT_GT(same, rays.size() / 4);
}

TEST(SceneCpu, DynamicObjectsMoveFromTheirRestCopyAndRefit) {
    Scene s = make_test_scene(true);
    const std::uint32_t soup = 2;
    ASSERT_TRUE(s.objects()[soup].dynamic());
    const std::vector<vec3> rest = s.objects()[soup].mesh.positions;
    for (float f : {1.5f, 0.5f, 2.0f}) {
        s.move_vertices(soup, [&](const Vertex& v, std::uint32_t i) { return rcl::ScaleHook::apply(v, i, {f}); });
        for (std::size_t i = 0; i < rest.size(); ++i) ASSERT_EQ(s.objects()[soup].mesh.positions[i], rest[i] * f);
        EXPECT_EQ(validate(s.objects()[soup].bvh, primitive_refs(s.objects()[soup].mesh).boxes), "");
    }
    EXPECT_TRUE(s.stale());
    EXPECT_THROW(s.intersect_closest(Ray{}), std::logic_error);
    s.update_top_level(TopLevelUpdate::refit);
    EXPECT_FALSE(s.stale());
    EXPECT_THROW(s.move_vertices(0, [](const Vertex& v, std::uint32_t) { return v; }), std::logic_error);
    EXPECT_THROW(s.add_instance(99), std::out_of_range);
    mat4 bad(1.0f);
    bad[0][3] = 0.5f;  // not affine
    EXPECT_THROW(s.set_transform(0, bad), std::invalid_argument);
    EXPECT_THROW(s.set_transform(0, glm::scale(mat4(1.0f), vec3(0.0f))), std::invalid_argument);
}

namespace {

using raykit::test::packet_test_rays;

/// A tracer's (MeshTracer's, DeviceScene's) answers on a ray set: closest hits, any-hit flags.
struct Answers {
    std::vector<Hit> hits;
    std::vector<std::uint32_t> any;
    std::size_t hit_count() const {
        return std::size_t(std::count_if(hits.begin(), hits.end(), [](const Hit& h) { return h.valid(); }));
    }
};

/// `tracer`'s answers on `rays`, walked as packets or ray by ray.
template <class Tracer>
Answers answers(Tracer& tracer, const std::vector<Ray>& rays, bool packets) {
    tracer.set_packet_walk(packets);
    Answers a;
    a.hits = tracer.closest(rays);
    a.any = tracer.any(rays);
    return a;
}

/// The words (t, u, v, prim, inst of every hit; every any-hit flag) where two answer sets differ.
std::size_t words_differ(const Answers& a, const Answers& b) {
    std::size_t d = a.hits.size() != b.hits.size() || a.any.size() != b.any.size() ? 1 : 0;
    for (std::size_t i = 0; i < std::min(a.hits.size(), b.hits.size()); ++i) {
        const Hit &x = a.hits[i], &y = b.hits[i];
        d += !same_bits(x.t, y.t) + !same_bits(x.u, y.u) + !same_bits(x.v, y.v) + (x.prim != y.prim) + (x.inst != y.inst);
    }
    for (std::size_t i = 0; i < std::min(a.any.size(), b.any.size()); ++i) d += a.any[i] != b.any[i];
    return d;
}

/// The packet walk's closest hits on `rays` and the words where the single-ray walk's answers
/// differ (words_differ).
template <class Tracer>
std::pair<std::vector<Hit>, std::size_t> packet_vs_single(Tracer& tracer, const std::vector<Ray>& rays) {
    const Answers single = answers(tracer, rays, false);
    Answers packets = answers(tracer, rays, true);
    const std::size_t d = words_differ(single, packets);
    return {std::move(packets.hits), d};
}

}  // namespace

// The packet walk (kernels/raykit/kernels/trace_packet.hpp) against the single-ray walk on the
// same device: every word of every answer equal, on camera tiles, mixed-octant packets (the
// fallback), same-octant incoherent packets, axis-parallel and -0 directions, narrowed
// intervals, vertex-aimed rays; leaves of 1 and 8 triangles.
TEST(ClTrace, PacketWalkEqualsSingleRaysBitForBit) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Mesh m = make_bumpy_torus(20000);
    const std::vector<Ray> rays = packet_test_rays(m, 3001, 31);
    for (unsigned leaf : {1u, 8u}) {
        const Bvh bvh = build(m, leaf);
        rcl::MeshTracer tracer(dev, m, bvh);
        const auto [packet, d] = packet_vs_single(tracer, rays);
        std::size_t hits = 0;
        for (const Hit& h : packet) hits += h.valid();
        std::printf("[ info ] leaf %u: %zu rays, %zu hits; packet vs single: %zu words differ\n", leaf, rays.size(),
                    hits, d);
        EXPECT_EQ(d, 0u) << "leaf " << leaf;
        EXPECT_GT(hits, rays.size() / 4);
        EXPECT_EQ(compare_mesh(tracer, m, bvh, rays).prim, 0u);
    }
}

// Quantized nodes (cl/device_tree.hpp quantize_node) against the full ones on the same device:
// every word of every answer equal, single rays and packets, on tori with leaves of 1 and 8
// (packet test rays: camera tiles, axis-parallel and -0 directions, narrowed intervals, vertex
// aims), camera rays, needle soups, icospheres aimed at vertices and edges at scales 1 and 1e3
// and offsets 0 and 1e6, a torus 1e7 from the origin and one scaled by 2e9 (near the 2^32 limit of raykit/math/limits.hpp).
TEST(ClTrace, QuantizedNodesGiveTheFullNodesAnswersBitForBit) {
    RAYKIT_REQUIRE_DEVICE(dev);
    struct Case {
        std::string name;
        Mesh mesh;
        unsigned leaf;
        std::vector<Ray> rays;
    };
    std::vector<Case> cases;
    const auto num = [](float x) {
        char b[32];
        std::snprintf(b, sizeof b, "%g", double(x));
        return std::string(b);
    };
    const Mesh torus = make_bumpy_torus(20000);
    for (unsigned leaf : {1u, 8u}) cases.push_back({"torus 20k, leaf " + std::to_string(leaf), torus, leaf, packet_test_rays(torus, 3001, 31)});
    {
        AABB box;
        for (const vec3& p : torus.positions) box.grow(p);
        cases.push_back({"torus 20k, camera", torus, 8, camera_rays(camera_looking_at(box, 120, 90))});
    }
    for (unsigned leaf : {1u, 4u}) {
        const Mesh soup = make_random_soup(3000, 5, 0.02f);  // thin, crossing triangles
        cases.push_back({"soup, leaf " + std::to_string(leaf), soup, leaf, packet_test_rays(soup, 2001, 17)});
    }
    for (float scale : {1.0f, 1e3f})
        for (float offset : {0.0f, 1e6f}) {
            Mesh m = make_icosphere(4);
            transform_positions(m, scale, vec3(offset, -offset, offset));
            std::vector<Ray> rays = vertex_edge_rays(m, vec3(offset, -offset, offset), scale, 42);
            cases.push_back({"icosphere, scale " + num(scale) + ", offset " + num(offset), m, 8, rays});
        }
    for (const auto& [scale, offset] : {std::pair{1.0f, 1e7f}, std::pair{2e9f, 0.0f}}) {
        Mesh m = make_bumpy_torus(5000);
        transform_positions(m, scale, vec3(offset, offset, -offset));
        cases.push_back({"torus 5k, scale " + num(scale) + ", offset " + num(offset), m, 8,
                         packet_test_rays(m, 1001, 3)});
    }
    for (Case& c : cases) {
        const Bvh bvh = build(c.mesh, c.leaf);
        rcl::MeshTracer full(dev, c.mesh, bvh);
        rcl::MeshTracer quant(dev, c.mesh, bvh, {}, rcl::NodeForm::quantized);
        ASSERT_EQ(quant.node_form(), rcl::NodeForm::quantized) << c.name;
        const Answers a = answers(full, c.rays, false), q = answers(quant, c.rays, false);
        const std::size_t d = words_differ(a, q), packet_d = words_differ(q, answers(quant, c.rays, true));
        const std::size_t hits = a.hit_count();
        std::printf("[ info ] %s: %zu rays, %zu hits; quantized vs full: %zu words differ; quantized packets vs "
                    "single rays: %zu\n",
                    c.name.c_str(), c.rays.size(), hits, d, packet_d);
        EXPECT_EQ(d, 0u) << c.name;
        EXPECT_EQ(packet_d, 0u) << c.name;
        EXPECT_GT(hits, 0u) << c.name;
    }
}

// ---------------------------------------------------------------- 5-7. scenes on the device

namespace {

Agreement compare_scene(rcl::DeviceScene<rcl::WaveHook, rcl::ScaleHook>& ds, const Scene& s, const std::vector<Ray>& rays) {
    const std::vector<Hit> dh = ds.closest(rays);
    const std::vector<std::uint32_t> da = ds.any(rays);
    Agreement a;
    a.rays = rays.size();
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit c = s.intersect_closest(rays[i]);
        const Hit& d = dh[i];
        if (c.valid() != d.valid()) ++a.validity;
        else if (c.valid() && (c.prim != d.prim || c.inst != d.inst)) ++a.prim;
        else if (c.valid() && (!same_bits(c.t, d.t) || !same_bits(c.u, d.u) || !same_bits(c.v, d.v))) ++a.t_bits;
        a.any += s.intersect_any(rays[i]) != (da[i] != 0);
    }
    return a;
}

using TestDeviceScene = rcl::DeviceScene<rcl::WaveHook, rcl::ScaleHook>;

/// The device tree of object `o` and its blocks equal device_tree() of the CPU's refitted
/// BlockBvh8 bit for bit.
template <class DS>
void expect_nodes_equal(DS& ds, std::uint32_t o, const SceneObject& cpu, const char* what) {
    const std::vector<rcl::DeviceNode> dev = ds.nodes(o);
    const rcl::DeviceTree want = rcl::device_tree(cpu.blocks);
    ASSERT_EQ(dev.size(), want.nodes.size()) << what;
    std::size_t differ = 0;
    for (std::size_t i = 0; i < dev.size(); ++i) differ += std::memcmp(&dev[i], &want.nodes[i], sizeof(rcl::DeviceNode)) != 0;
    EXPECT_EQ(differ, 0u) << what << ": nodes not bit-identical to the CPU refit, of " << dev.size();
    const std::vector<TriangleBlock4> blocks = ds.blocks(o);
    ASSERT_EQ(blocks.size(), want.blocks.size()) << what;
    differ = 0;
    for (std::size_t i = 0; i < blocks.size(); ++i) differ += std::memcmp(&blocks[i], &want.blocks[i], sizeof(TriangleBlock4)) != 0;
    EXPECT_EQ(differ, 0u) << what << ": blocks not bit-identical to the CPU's, of " << blocks.size();
}

}  // namespace

TEST(ClScene, StaticSceneLaunchesNoVertexOrRefitKernel) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Scene s = make_test_scene(false);
    TestDeviceScene ds(dev, s);
    for (int frame = 0; frame < 3; ++frame) ds.update();
    compare_scene(ds, s, scene_rays(s, 4000, 3)).expect_good("static two-level scene");
    EXPECT_EQ(ds.launches().vertex, 0u);
    EXPECT_EQ(ds.launches().refit, 0u);
    EXPECT_EQ(ds.launches().top_level, 0u);
    EXPECT_EQ(ds.launches().trace, 2u);
    EXPECT_TRUE(ds.compiled_hooks().empty()) << "hooks no object uses must not be compiled";
    // no vertex stage and no refit kernels in the program at all
    EXPECT_THROW((void)ds.program().kernel("rk_vertex_stage_wave"), rcl::Error);
    EXPECT_THROW((void)ds.program().kernel("rk_refit_one_pass"), rcl::Error);
}

// The packet walk through a scene: a one-leaf top level (three instances, rotations past pi, a
// non-uniform scale: packets walk each instance in turn, rays mapped lane by lane) and a deeper
// one (make_test_scene's seven instances: ray by ray); every word equal to the single-ray walk.
TEST(ClScene, PacketWalkEqualsSingleRaysBitForBit) {
    RAYKIT_REQUIRE_DEVICE(dev);
    Scene one_leaf;
    const std::uint32_t torus = one_leaf.add_object(make_bumpy_torus(6000));
    const std::uint32_t ball = one_leaf.add_object(make_icosphere(3));
    one_leaf.add_instance(torus);
    one_leaf.add_instance(ball,
                          glm::scale(transform_of(3.5f, {1, 2, 0}, 1.0f, {1.5f, 0.2f, 0.0f}), vec3(0.6f, 0.3f, 0.9f)));
    one_leaf.add_instance(torus, transform_of(-4.0f, {0, 1, 1}, 0.4f, {-1.0f, 1.0f, 0.5f}));
    one_leaf.update_top_level();
    ASSERT_EQ(one_leaf.top_level().nodes.size(), 1u) << "the test wants a one-leaf top level";
    const Scene deep = make_test_scene(true);
    ASSERT_GT(deep.top_level().nodes.size(), 1u);
    for (const Scene* s : std::initializer_list<const Scene*>{&one_leaf, &deep}) {
        TestDeviceScene ds(dev, *s);
        ds.update();
        const std::vector<Ray> rays = packet_test_rays(s->world_mesh().first, 2001, 41);
        const auto [packet, d] = packet_vs_single(ds, rays);
        std::size_t hits = 0, insts = 0;
        std::vector<bool> seen(s->instances().size());
        for (const Hit& h : packet)
            if (h.valid()) {
                ++hits;
                if (!seen[h.inst]) ++insts;
                seen[h.inst] = true;
            }
        const char* what = s == &one_leaf ? "one-leaf top level" : "deeper top level";
        std::printf("[ info ] %s: %zu rays, %zu hits on %zu instances; packet vs single: %zu words differ\n", what,
                    rays.size(), hits, insts, d);
        EXPECT_EQ(d, 0u) << what;
        EXPECT_EQ(insts, s->instances().size()) << what;
        EXPECT_EQ(compare_scene(ds, *s, rays).prim, 0u) << what;
    }
}

TEST(ClScene, ExactHookGivesBitIdenticalVerticesTreesAndHits) {
    RAYKIT_REQUIRE_DEVICE(dev);
    Scene s = make_test_scene(true);
    TestDeviceScene ds(dev, s);
    const std::uint32_t soup = 2, cloth = 3;
    const std::vector<rcl::DeviceNode> static_nodes_before = ds.nodes(0);
    const std::vector<vec3> static_pos_before = ds.positions(1);
    for (const auto method : {rcl::RefitMethod::level_wise, rcl::RefitMethod::one_pass, rcl::RefitMethod::one_pass}) {
        const float f = method == rcl::RefitMethod::level_wise ? 1.25f : 0.75f + 0.01f * float(ds.launches().vertex);
        ds.set_hook<rcl::ScaleHook>(soup, {f});
        ds.set_hook<rcl::ScaleHook>(cloth, {1.0f / f});
        s.move_vertices(soup, [&](const Vertex& v, std::uint32_t i) { return rcl::ScaleHook::apply(v, i, {f}); });
        s.move_vertices(cloth, [&](const Vertex& v, std::uint32_t i) { return rcl::ScaleHook::apply(v, i, {1.0f / f}); });
        s.update_top_level();
        ds.update(method);
        EXPECT_EQ(ds.positions(soup), s.objects()[soup].mesh.positions);
        EXPECT_EQ(ds.positions(cloth), s.objects()[cloth].mesh.positions);
        expect_nodes_equal(ds, soup, s.objects()[soup], rcl::refit_method_name(method));
        expect_nodes_equal(ds, cloth, s.objects()[cloth], rcl::refit_method_name(method));
        compare_scene(ds, s, scene_rays(s, 3000, 17)).expect_good("dynamic scene, scale hook");
    }
    EXPECT_EQ(ds.compiled_hooks(), std::vector<std::string>{"scale"});
    EXPECT_EQ(ds.launches().vertex, 3u);  // one launch per frame for both objects
    // static objects were never touched
    const std::vector<rcl::DeviceNode> static_nodes_after = ds.nodes(0);
    ASSERT_EQ(static_nodes_before.size(), static_nodes_after.size());
    EXPECT_EQ(std::memcmp(static_nodes_before.data(), static_nodes_after.data(), static_nodes_after.size() * sizeof(rcl::DeviceNode)), 0);
    EXPECT_EQ(ds.positions(1), static_pos_before);
}

TEST(ClScene, WaveHookMatchesItsCpuTwinAndRefitIsBitIdentical) {
    RAYKIT_REQUIRE_DEVICE(dev);
    Scene s = make_test_scene(true);
    TestDeviceScene ds(dev, s);
    const std::uint32_t soup = 2, cloth = 3;
    for (int frame = 0; frame < 3; ++frame) {
        const rcl::WaveHook::Params p{.time = 0.4f * float(frame), .amplitude = 0.1f, .frequency = 3.0f};
        ds.set_hook<rcl::WaveHook>(cloth, p);
        if (frame == 1) ds.set_hook<rcl::ScaleHook>(soup, {1.1f});
        const auto method = frame % 2 ? rcl::RefitMethod::level_wise : rcl::RefitMethod::one_pass;
        ds.update(method);
        // vertices: the CPU twin to within a few ulps of sin/cos
        s.move_vertices(cloth, [&](const Vertex& v, std::uint32_t i) { return rcl::WaveHook::apply(v, i, p); });
        const std::vector<vec3> dp = ds.positions(cloth);
        float worst = 0.0f;
        for (std::size_t i = 0; i < dp.size(); ++i) worst = std::max(worst, glm::length(dp[i] - s.objects()[cloth].mesh.positions[i]));
        EXPECT_LT(worst, 1e-5f);
        const std::vector<Vertex> mv = ds.moved_vertices(cloth);
        ASSERT_EQ(mv.size(), dp.size());
        for (std::size_t i = 0; i < dp.size(); ++i) ASSERT_EQ(mv[i].position, dp[i]);
        // trees: the CPU refit of the device's vertices, bit for bit
        s.set_positions(cloth, dp);
        s.set_positions(soup, ds.positions(soup));
        expect_nodes_equal(ds, cloth, s.objects()[cloth], rcl::refit_method_name(method));
        expect_nodes_equal(ds, soup, s.objects()[soup], rcl::refit_method_name(method));
        s.update_top_level();
        compare_scene(ds, s, scene_rays(s, 2000, 23 + frame)).expect_good("dynamic scene, wave hook");
    }
    const auto hooks = ds.compiled_hooks();
    EXPECT_EQ(hooks.size(), 2u);
    EXPECT_EQ(ds.launches().vertex, 1u + 2u + 2u);
}

// A DeviceScene walking quantized nodes (NodeForm::quantized) beside one walking full nodes, over
// three frames of hooks and both refit methods: every object's quantized nodes are the host's
// quantize_node of its full nodes byte for byte (static ones quantized on the host at upload, their
// full nodes not uploaded; dynamic ones on the device after each refit), and every word of every
// answer equals the full scene's, single rays and packets.
TEST(ClScene, QuantizedNodesAreTheHostsBytesAndGiveTheFullAnswers) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Scene s = make_test_scene(true);
    TestDeviceScene full(dev, s);
    TestDeviceScene quant(dev, s, {}, rcl::NodeForm::quantized);
    ASSERT_EQ(quant.node_form(), rcl::NodeForm::quantized);
    const std::uint32_t soup = 2, cloth = 3;
    for (int frame = 0; frame < 3; ++frame) {
        const rcl::WaveHook::Params p{.time = 0.4f * float(frame), .amplitude = 0.1f, .frequency = 3.0f};
        for (TestDeviceScene* ds : {&full, &quant}) {
            ds->set_hook<rcl::WaveHook>(cloth, p);
            if (frame == 1) ds->set_hook<rcl::ScaleHook>(soup, {1.1f});
            ds->update(frame % 2 ? rcl::RefitMethod::level_wise : rcl::RefitMethod::one_pass);
        }
        std::size_t nodes = 0, differ = 0;
        for (std::uint32_t o = 0; o < s.objects().size(); ++o) {
            // a static object's full nodes are not on the device: the host's own
            const std::vector<rcl::DeviceNode> fn =
                s.objects()[o].dynamic() ? quant.nodes(o) : rcl::device_tree(s.objects()[o].blocks).nodes;
            if (!s.objects()[o].dynamic() && !fn.empty()) {
                EXPECT_THROW(quant.nodes(o), std::logic_error);
            }
            const std::vector<rcl::QuantizedNode> qn = quant.quantized_nodes(o);
            ASSERT_EQ(fn.size(), qn.size());
            for (std::size_t i = 0; i < fn.size(); ++i) {
                const std::optional<rcl::QuantizedNode> want = rcl::quantize_node(fn[i]);
                ASSERT_TRUE(want.has_value());
                differ += std::memcmp(&*want, &qn[i], sizeof(rcl::QuantizedNode)) != 0;
            }
            nodes += fn.size();
        }
        const std::vector<Ray> rays = packet_test_rays(s.world_mesh().first, 1501, 61 + frame);
        const Answers a = answers(full, rays, false), q = answers(quant, rays, false);
        const std::size_t d = words_differ(a, q), packet_d = words_differ(q, answers(quant, rays, true));
        const std::size_t hits = a.hit_count();
        std::printf("[ info ] frame %d: %zu nodes, %zu differ from the host's quantize_node; %zu rays, %zu hits, "
                    "quantized vs full %zu words differ, quantized packets vs single rays %zu\n",
                    frame, nodes, differ, rays.size(), hits, d, packet_d);
        EXPECT_EQ(differ, 0u);
        EXPECT_EQ(d, 0u);
        EXPECT_EQ(packet_d, 0u);
        EXPECT_GT(hits, rays.size() / 10);
    }
    EXPECT_EQ(quant.launches().quantize, 3u);
    EXPECT_EQ(full.launches().quantize, 0u);
}

TEST(ClRefit, LevelWiseAndOnePassAreBitIdenticalToCpu) {
    RAYKIT_REQUIRE_DEVICE(dev);
    Scene s;
    std::vector<std::uint32_t> dyn;
    dyn.push_back(s.add_object(make_random_soup(1, 1), ObjectKind::dynamic));  // a single leaf
    dyn.push_back(s.add_object(make_random_soup(700, 2, 0.2f), ObjectKind::dynamic, {.leaf = {.max_leaf_size = 1}}));
    dyn.push_back(s.add_object(make_bumpy_torus(5000), ObjectKind::dynamic));
    dyn.push_back(s.add_object(make_icosphere(3), ObjectKind::dynamic, {.leaf = {.max_leaf_size = 4}}));
    s.add_object(make_icosphere(1));  // static, in between
    for (std::uint32_t o = 0; o < s.objects().size(); ++o) s.add_instance(o);
    s.update_top_level();
    TestDeviceScene ds(dev, s);
    // the same frames with quantized nodes: after each refit the device's quantized nodes are the
    // host's quantize_node of the refitted ones, NaN-emptied leaf boxes included
    TestDeviceScene dq(dev, s, {}, rcl::NodeForm::quantized);
    ASSERT_EQ(dq.node_form(), rcl::NodeForm::quantized);
    std::size_t quantized_checked = 0, quantized_differ = 0;
    const auto check_quantized = [&] {
        for (std::uint32_t o : dyn) {
            const std::vector<rcl::DeviceNode> fn = dq.nodes(o);
            const std::vector<rcl::QuantizedNode> qn = dq.quantized_nodes(o);
            for (std::size_t i = 0; i < fn.size(); ++i) {
                const std::optional<rcl::QuantizedNode> want = rcl::quantize_node(fn[i]);
                quantized_differ += !want || std::memcmp(&*want, &qn[i], sizeof(rcl::QuantizedNode)) != 0;
            }
            quantized_checked += fn.size();
        }
    };
    std::printf("[ info ] refit plan: %zu levels, %zu leaves, %zu nodes\n", ds.refit_plan().levels(),
                ds.refit_plan().leaves(), ds.refit_plan().nodes());
    std::mt19937_64 rng(3);
    std::normal_distribution<float> N(0.0f, 0.05f);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int round = 0; round < 4; ++round) {
        for (std::uint32_t o : dyn) {
            std::vector<vec3> p = s.objects()[o].mesh.positions;
            for (vec3& q : p) q += vec3(N(rng), N(rng), N(rng));
            if (round == 2 && p.size() > 10) p[3].y = nan;  // non-finite vertex: empty triangle boxes
            if (round == 3 && p.size() > 10) p[5] = vec3(-0.0f, 0.0f, -0.0f);
            ds.set_positions(o, p);
            dq.set_positions(o, p);
            s.set_positions(o, p);
        }
        const auto method = round % 2 ? rcl::RefitMethod::one_pass : rcl::RefitMethod::level_wise;
        const std::size_t before = ds.launches().refit;
        ds.update(method);
        const std::size_t launches = ds.launches().refit - before;
        EXPECT_EQ(launches, method == rcl::RefitMethod::one_pass ? 1u : ds.refit_plan().levels());
        for (std::uint32_t o : dyn) expect_nodes_equal(ds, o, s.objects()[o], rcl::refit_method_name(method));
        // the other method on the same vertices gives the same nodes again
        ds.refit(method == rcl::RefitMethod::one_pass ? rcl::RefitMethod::level_wise : rcl::RefitMethod::one_pass);
        for (std::uint32_t o : dyn) expect_nodes_equal(ds, o, s.objects()[o], "second method");
        dq.update(method);
        for (std::uint32_t o : dyn) expect_nodes_equal(dq, o, s.objects()[o], "quantized scene");
        check_quantized();
    }
    std::printf("[ info ] quantized: %zu nodes checked after refits, %zu differ from the host's\n", quantized_checked,
                quantized_differ);
    EXPECT_EQ(quantized_differ, 0u);
    EXPECT_GT(quantized_checked, 0u);
    EXPECT_EQ(ds.launches().vertex, 0u);
}

namespace {
struct BrokenHook {
    static constexpr const char* name = "broken";
    struct Params {
        float k;
    };
    static constexpr const char* source = R"CLC(typedef struct { float k; } broken_params;
rk_vertex broken(rk_vertex v, uint index, broken_params p) {
    v.position[0] += p.k;
    return v
}
)CLC";
    static Vertex apply(const Vertex& v, std::uint32_t, const Params&) { return v; }
};
struct MismatchedHook {
    static constexpr const char* name = "mismatched";
    struct Params {
        float a, b;
    };
    static constexpr const char* source = R"CLC(typedef struct { float a; } mismatched_params;
rk_vertex mismatched(rk_vertex v, uint index, mismatched_params p) { return v; }
)CLC";
    static Vertex apply(const Vertex& v, std::uint32_t, const Params&) { return v; }
};
}  // namespace

TEST(ClScene, HookSyntaxErrorNamesTheHookAndLine) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Scene s = make_test_scene(true, 500);
    rcl::DeviceScene<BrokenHook> ds(dev, s);
    ds.update();  // the hook is not used yet: builds fine
    ds.set_hook<BrokenHook>(2, {1.0f});
    try {
        ds.update();
        ADD_FAILURE() << "expected a BuildError";
    } catch (const rcl::BuildError& e) {
        const std::string w = e.what();
        EXPECT_NE(w.find("<hook broken>:4:"), std::string::npos) << w;  // the missing ';' after "return v"
        EXPECT_NE(w.find("CL_BUILD_PROGRAM_FAILURE"), std::string::npos) << w;
    }
}

TEST(ClScene, HookParamsSizeMismatchIsABuildError) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Scene s = make_test_scene(true, 500);
    rcl::DeviceScene<MismatchedHook> ds(dev, s);
    ds.set_hook<MismatchedHook>(3, {1.0f, 2.0f});
    try {
        ds.update();
        ADD_FAILURE() << "expected a BuildError";
    } catch (const rcl::BuildError& e) {
        EXPECT_NE(std::string(e.what()).find("rk_hook_mismatched_params_must_be_8_bytes"), std::string::npos) << e.what();
    }
}

TEST(ClScene, MisuseThrows) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Scene s = make_test_scene(true, 500);
    TestDeviceScene ds(dev, s);
    EXPECT_THROW(ds.closest(std::vector<Ray>(3)), std::logic_error);  // before update()
    EXPECT_THROW(ds.set_hook<rcl::WaveHook>(0, {}), std::logic_error);  // static object
    EXPECT_THROW(ds.set_hook<rcl::WaveHook>(77, {}), std::out_of_range);
    EXPECT_THROW(ds.set_positions(2, std::vector<vec3>(3)), std::invalid_argument);
    ds.update();
    EXPECT_EQ(ds.closest(std::vector<Ray>{}).size(), 0u);
}
