// raykit/cl/layout.hpp — the host side of the structs that cross to OpenCL.
//
// Each struct has one layout, written twice: in C++ (here and in the CPU
// headers named below) and in OpenCL C (kernels/raykit/kernels/layout.hpp).
//
//   C++                      OpenCL C      bytes
//   raykit::Node             rk_node       32 (aligned 32; the top level)
//   cl::DeviceNode           rk_wnode      256 (aligned 64; WideNodeT<kDeviceWidth>, objects)
//   cl::QuantizedNode        rk_qnode      104 (the same node, child boxes quantized to bytes)
//   raykit::TriangleBlock4   rk_block      160 (aligned 32; objects' leaves)
//   raykit::Triangle         rk_triangle   12
//   raykit::Vertex           rk_vertex     32
//   raykit::Ray              rk_ray        32
//   raykit::Hit              rk_hit        20
//   raykit::CameraFrame      rk_camera     56
//   cl::InstanceRecord       rk_instance   112
//   cl::ObjectRecord         rk_object     32
//
// The C++ side is pinned with static_asserts; check_layout() runs a probe
// kernel that reports sizeof/alignof/offsetof of every field as the device
// compiler sees them and returns each difference (tests require none).
// 3-vectors are three floats on both sides (never float3).
#pragma once

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <type_traits>
#include <vector>

#include "raykit/bvh/node.hpp"
#include "raykit/bvh/wide.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/intersect/slab.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/kernels/common.hpp"
#include "raykit/kernels/layout.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/math/ray.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/scene/scene.hpp"

namespace raykit::cl {

/// Children per node of the objects' trees on the device (RK_WIDTH): the CPU's fastest path
/// (BlockBvh8, every Scene query) walks the same 8-wide tree, so the device's traversal steps
/// equal the CPU's node counts.
inline constexpr int kDeviceWidth = 8;
/// An object tree's node as the device sees it (rk_wnode; see cl/device_tree.hpp).
using DeviceNode = WideNodeT<kDeviceWidth>;

/// The largest plane magnitude quantize_node keeps, 2^126 (RK_QUANTIZE_LIMIT): the extent is then
/// at most 2^127, so the step is at most 2^120 and 255·step stays below FLT_MAX. A product that
/// overflowed would decode differently fused (fma) and unfused: with ±FLT_MAX here the ASan
/// build's host code, which does not fuse, disagreed with the device on 3 of 4,065 hostile
/// nodes. The limit is far beyond raykit's coordinates (math/limits.hpp: 2^32).
inline constexpr float kQuantizeLimit = 0x1p126f;
/// The largest step exponent of a quantized node (RK_QUANTIZE_MAX_EXP): 255·2^120 spans 2^127.
inline constexpr int kQuantizeMaxExponent = 120;
static_assert(255.0 * 0x1p120 >= 2.0 * double(kQuantizeLimit) && 255.0 * 0x1p120 < 0x1p128,
              "the largest step spans every extent within the limit and 255 of them stay finite");

/// A DeviceNode with its child boxes quantized to bytes (rk_qnode; cl/device_tree.hpp
/// quantize_node): plane (row r = 2·axis + hi, child c) is origin[axis] + q[r][c]·2^exponent[axis]
/// in float, rounded outward so it holds the child's box; `used` has a bit per slot in use.
struct QuantizedNode {
    float origin[3];
    std::int8_t exponent[3];
    std::uint8_t used;
    std::uint8_t q[6][kDeviceWidth];
    std::uint32_t index[kDeviceWidth];  ///< as DeviceNode::index
    std::uint8_t count[kDeviceWidth];   ///< as DeviceNode::count (leaves of at most 255 blocks)
};

/// An instance as the device sees it (rk_instance).
struct InstanceRecord {
    Affine world_to_object;
    Affine object_to_world;
    std::uint32_t object = 0;
    std::uint32_t identity = 0;  ///< 1: SceneInstance::identity (rays and surfaces are not mapped)
    std::uint32_t pad[2] = {0, 0};
};

/// An object's place in a device scene's concatenated arrays (rk_object).
struct ObjectRecord {
    std::uint32_t node_offset = 0;
    std::uint32_t node_count = 0;
    std::uint32_t block_offset = 0;  ///< first TriangleBlock4 of its tree's leaves
    std::uint32_t triangle_offset = 0;
    std::uint32_t vertex_offset = 0;
    std::uint32_t vertex_count = 0;
    std::uint32_t triangle_count = 0;
    std::uint32_t pad = 0;
};

static_assert(sizeof(Node) == 32 && alignof(Node) == 32);
static_assert(offsetof(Node, box) == 0 && offsetof(Node, index) == 24 && offsetof(Node, count) == 28);
static_assert(offsetof(AABB, min) == 0 && offsetof(AABB, max) == 12);
static_assert(sizeof(DeviceNode) == 32 * kDeviceWidth && alignof(DeviceNode) == 64);
static_assert(offsetof(DeviceNode, planes) == 0 && offsetof(DeviceNode, index) == 24 * kDeviceWidth &&
              offsetof(DeviceNode, count) == 28 * kDeviceWidth);
static_assert(std::is_trivially_copyable_v<DeviceNode>);
static_assert(sizeof(QuantizedNode) == 104 && alignof(QuantizedNode) == 4);
static_assert(offsetof(QuantizedNode, exponent) == 12 && offsetof(QuantizedNode, used) == 15 &&
              offsetof(QuantizedNode, q) == 16 && offsetof(QuantizedNode, index) == 64 &&
              offsetof(QuantizedNode, count) == 96);
static_assert(std::is_trivially_copyable_v<QuantizedNode>);
static_assert(sizeof(TriangleBlock4) == 160 && alignof(TriangleBlock4) == 32);
static_assert(offsetof(TriangleBlock4, p) == 0 && offsetof(TriangleBlock4, prim) == 144);
static_assert(std::is_trivially_copyable_v<TriangleBlock4>);
static_assert(sizeof(Triangle) == 12 && alignof(Triangle) == 4 && offsetof(Triangle, v) == 0);
static_assert(sizeof(Vertex) == 32 && alignof(Vertex) == 4);
static_assert(offsetof(Vertex, position) == 0 && offsetof(Vertex, normal) == 12 && offsetof(Vertex, uv) == 24);
static_assert(sizeof(Ray) == 32 && alignof(Ray) == 4);
static_assert(offsetof(Ray, org) == 0 && offsetof(Ray, tmin) == 12 && offsetof(Ray, dir) == 16 &&
              offsetof(Ray, tmax) == 28);
static_assert(sizeof(Hit) == 20 && alignof(Hit) == 4);
static_assert(offsetof(Hit, t) == 0 && offsetof(Hit, u) == 4 && offsetof(Hit, v) == 8 && offsetof(Hit, prim) == 12 &&
              offsetof(Hit, inst) == 16);
static_assert(sizeof(CameraFrame) == 56 && alignof(CameraFrame) == 4);
static_assert(offsetof(CameraFrame, origin) == 0 && offsetof(CameraFrame, corner) == 12 &&
              offsetof(CameraFrame, du) == 24 && offsetof(CameraFrame, dv) == 36 &&
              offsetof(CameraFrame, width) == 48 && offsetof(CameraFrame, height) == 52);
static_assert(sizeof(InstanceRecord) == 112 && alignof(InstanceRecord) == 4);
static_assert(offsetof(InstanceRecord, world_to_object) == 0 && offsetof(InstanceRecord, object_to_world) == 48 &&
              offsetof(InstanceRecord, object) == 96 && offsetof(InstanceRecord, identity) == 100);
static_assert(sizeof(ObjectRecord) == 32 && alignof(ObjectRecord) == 4);
static_assert(offsetof(ObjectRecord, node_count) == 4 && offsetof(ObjectRecord, block_offset) == 8 &&
              offsetof(ObjectRecord, triangle_offset) == 12 && offsetof(ObjectRecord, vertex_offset) == 16 &&
              offsetof(ObjectRecord, vertex_count) == 20 && offsetof(ObjectRecord, triangle_count) == 24);
static_assert(std::is_trivially_copyable_v<InstanceRecord> && std::is_trivially_copyable_v<ObjectRecord> &&
              std::is_trivially_copyable_v<CameraFrame> && std::is_trivially_copyable_v<Vertex>);

/// One number of the layout: a device expression and the host's value.
struct LayoutEntry {
    std::string device_expr;  ///< OpenCL C, e.g. "__builtin_offsetof(rk_ray, dir)"
    std::size_t host;
};

/// Every size, alignment and field offset that must agree.
inline std::vector<LayoutEntry> layout_entries() {
    std::vector<LayoutEntry> e;
    auto size = [&](const char* t, std::size_t s, std::size_t a) {
        e.push_back({std::string("sizeof(") + t + ")", s});
        e.push_back({std::string("__alignof__(") + t + ")", a});
    };
    auto off = [&](const char* t, const char* f, std::size_t o) {
        e.push_back({std::string("__builtin_offsetof(") + t + ", " + f + ")", o});
    };
    size("rk_node", sizeof(Node), alignof(Node));
    off("rk_node", "min", offsetof(Node, box) + offsetof(AABB, min));
    off("rk_node", "max", offsetof(Node, box) + offsetof(AABB, max));
    off("rk_node", "index", offsetof(Node, index));
    off("rk_node", "count", offsetof(Node, count));
    size("rk_wnode", sizeof(DeviceNode), alignof(DeviceNode));
    off("rk_wnode", "planes", offsetof(DeviceNode, planes));
    off("rk_wnode", "index", offsetof(DeviceNode, index));
    off("rk_wnode", "count", offsetof(DeviceNode, count));
    size("rk_qnode", sizeof(QuantizedNode), alignof(QuantizedNode));
    off("rk_qnode", "origin", offsetof(QuantizedNode, origin));
    off("rk_qnode", "exponent", offsetof(QuantizedNode, exponent));
    off("rk_qnode", "used", offsetof(QuantizedNode, used));
    off("rk_qnode", "q", offsetof(QuantizedNode, q));
    off("rk_qnode", "index", offsetof(QuantizedNode, index));
    off("rk_qnode", "count", offsetof(QuantizedNode, count));
    size("rk_block", sizeof(TriangleBlock4), alignof(TriangleBlock4));
    off("rk_block", "p", offsetof(TriangleBlock4, p));
    off("rk_block", "prim", offsetof(TriangleBlock4, prim));
    size("rk_triangle", sizeof(Triangle), alignof(Triangle));
    off("rk_triangle", "v", offsetof(Triangle, v));
    size("rk_vertex", sizeof(Vertex), alignof(Vertex));
    off("rk_vertex", "position", offsetof(Vertex, position));
    off("rk_vertex", "normal", offsetof(Vertex, normal));
    off("rk_vertex", "uv", offsetof(Vertex, uv));
    size("rk_ray", sizeof(Ray), alignof(Ray));
    off("rk_ray", "org", offsetof(Ray, org));
    off("rk_ray", "tmin", offsetof(Ray, tmin));
    off("rk_ray", "dir", offsetof(Ray, dir));
    off("rk_ray", "tmax", offsetof(Ray, tmax));
    size("rk_hit", sizeof(Hit), alignof(Hit));
    off("rk_hit", "t", offsetof(Hit, t));
    off("rk_hit", "u", offsetof(Hit, u));
    off("rk_hit", "v", offsetof(Hit, v));
    off("rk_hit", "prim", offsetof(Hit, prim));
    off("rk_hit", "inst", offsetof(Hit, inst));
    size("rk_camera", sizeof(CameraFrame), alignof(CameraFrame));
    off("rk_camera", "origin", offsetof(CameraFrame, origin));
    off("rk_camera", "corner", offsetof(CameraFrame, corner));
    off("rk_camera", "du", offsetof(CameraFrame, du));
    off("rk_camera", "dv", offsetof(CameraFrame, dv));
    off("rk_camera", "width", offsetof(CameraFrame, width));
    off("rk_camera", "height", offsetof(CameraFrame, height));
    size("rk_instance", sizeof(InstanceRecord), alignof(InstanceRecord));
    off("rk_instance", "world_to_object", offsetof(InstanceRecord, world_to_object));
    off("rk_instance", "object_to_world", offsetof(InstanceRecord, object_to_world));
    off("rk_instance", "object", offsetof(InstanceRecord, object));
    off("rk_instance", "identity", offsetof(InstanceRecord, identity));
    size("rk_object", sizeof(ObjectRecord), alignof(ObjectRecord));
    off("rk_object", "node_offset", offsetof(ObjectRecord, node_offset));
    off("rk_object", "node_count", offsetof(ObjectRecord, node_count));
    off("rk_object", "block_offset", offsetof(ObjectRecord, block_offset));
    off("rk_object", "triangle_offset", offsetof(ObjectRecord, triangle_offset));
    off("rk_object", "vertex_offset", offsetof(ObjectRecord, vertex_offset));
    off("rk_object", "vertex_count", offsetof(ObjectRecord, vertex_count));
    off("rk_object", "triangle_count", offsetof(ObjectRecord, triangle_count));
    return e;
}

/// How this build of the CPU code rounds the two multiply-adds of
/// Watertight::intersect (intersect/triangle.hpp): A[kx] − sx·A[kz] (`msub`) and
/// U·Az + V·Bz + W·Cz (`tnum`). The CPU code fuses both explicitly exactly when
/// RAYKIT_FMA is 1 (config.hpp, the default), so this is known at compile time; the device
/// is told the same through config_source() and returns the same t, u, v bit for
/// bit. (A run-time probe of the rounding used to stand here; it is now the test
/// that checks this constant, test_geometry's Watertight.RoundsAsRaykitFmaSays.)
struct HostFloatConfig {
    bool fuse_msub = RAYKIT_FMA != 0;
    bool fuse_tnum = RAYKIT_FMA != 0;
};

/// The rounding of this build's Watertight::intersect (see HostFloatConfig).
inline constexpr HostFloatConfig host_float_config() noexcept { return {}; }

/// The program preamble every raykit kernel program starts with: the
/// compile-time constants shared with the CPU code, as exact literals, and
/// the host's fusion choices (host_float_config()).
inline std::string config_source() {
    const HostFloatConfig f = host_float_config();
    return "#define RK_MAX_DEPTH " + std::to_string(RAYKIT_BVH_MAX_DEPTH) + "\n" +
           "#define RK_WIDTH " + std::to_string(kDeviceWidth) + "\n" +
           "#define RK_SLAB_EXIT_SCALE " + hex_float(kSlabExitScale) + "\n" +
           "#define RK_QUANTIZE_LIMIT " + hex_float(kQuantizeLimit) + "\n" +
           "#define RK_QUANTIZE_MAX_EXP " + std::to_string(kQuantizeMaxExponent) + "\n" +
           "#define RK_FUSE_MSUB " + (f.fuse_msub ? "1" : "0") + "\n" +
           "#define RK_FUSE_T " + (f.fuse_tnum ? "1" : "0") + "\n";
}

/// The parts every raykit program starts with: config, layout, common math.
inline std::vector<SourcePart> base_parts() {
    return {{"raykit/kernels/config", config_source()},
            {"raykit/kernels/layout.hpp", kernels::kLayout},
            {"raykit/kernels/common.hpp", kernels::kCommon}};
}

/// Source of the probe kernel rk_layout_probe(out): out[i] = device value of
/// layout_entries()[i].
inline std::string layout_probe_source() {
    std::string s = "__kernel void rk_layout_probe(__global uint* out) {\n    if (get_global_id(0) != 0) return;\n";
    const auto e = layout_entries();
    for (std::size_t i = 0; i < e.size(); ++i)
        s += "    out[" + std::to_string(i) + "] = (uint)(" + e[i].device_expr + ");\n";
    return s + "}\n";
}

/// Runs the probe on `dev`; returns one line per difference
/// ("sizeof(rk_hit): device 24, host 20"), empty when the layouts agree.
inline std::vector<std::string> check_layout(Device& dev) {
    std::vector<SourcePart> parts = base_parts();
    parts.push_back({"raykit/cl/layout.hpp probe", layout_probe_source()});
    const Program p = build_program(dev, assemble(parts), raykit_build_options(dev));
    ::cl::Kernel k = p.kernel("rk_layout_probe");
    const auto e = layout_entries();
    Buffer<std::uint32_t> out(dev, e.size());
    set_args(k, out);
    launch(dev.queue(), k, 1, 1);
    const std::vector<std::uint32_t> v = out.read(dev);
    std::vector<std::string> diff;
    for (std::size_t i = 0; i < e.size(); ++i)
        if (v[i] != e[i].host)
            diff.push_back(e[i].device_expr + ": device " + std::to_string(v[i]) + ", host " + std::to_string(e[i].host));
    return diff;
}

}  // namespace raykit::cl
