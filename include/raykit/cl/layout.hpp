// raykit/cl/layout.hpp — the host side of the structs that cross to OpenCL.
//
// Each struct has one layout, written twice: in C++ (here and in the CPU
// headers named below) and in OpenCL C (kernels/raykit/kernels/layout.hpp).
//
//   C++                      OpenCL C      bytes
//   raykit::Node             rk_node       32 (aligned 32)
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
#include <vector>

#include "raykit/bvh/node.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/intersect/slab.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/kernels/common.hpp"
#include "raykit/kernels/layout.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/math/ray.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/scene/scene.hpp"

namespace raykit::cl {

/// An instance as the device sees it (rk_instance).
struct InstanceRecord {
    Affine world_to_object;
    Affine object_to_world;
    std::uint32_t object = 0;
    std::uint32_t pad[3] = {0, 0, 0};
};

/// An object's place in a device scene's concatenated arrays (rk_object).
struct ObjectRecord {
    std::uint32_t node_offset = 0;
    std::uint32_t node_count = 0;
    std::uint32_t prim_offset = 0;
    std::uint32_t triangle_offset = 0;
    std::uint32_t vertex_offset = 0;
    std::uint32_t vertex_count = 0;
    std::uint32_t triangle_count = 0;
    std::uint32_t pad = 0;
};

static_assert(sizeof(Node) == 32 && alignof(Node) == 32);
static_assert(offsetof(Node, box) == 0 && offsetof(Node, index) == 24 && offsetof(Node, count) == 28);
static_assert(offsetof(AABB, min) == 0 && offsetof(AABB, max) == 12);
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
              offsetof(InstanceRecord, object) == 96);
static_assert(sizeof(ObjectRecord) == 32 && alignof(ObjectRecord) == 4);
static_assert(offsetof(ObjectRecord, node_count) == 4 && offsetof(ObjectRecord, prim_offset) == 8 &&
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
    size("rk_object", sizeof(ObjectRecord), alignof(ObjectRecord));
    off("rk_object", "node_offset", offsetof(ObjectRecord, node_offset));
    off("rk_object", "node_count", offsetof(ObjectRecord, node_count));
    off("rk_object", "prim_offset", offsetof(ObjectRecord, prim_offset));
    off("rk_object", "triangle_offset", offsetof(ObjectRecord, triangle_offset));
    off("rk_object", "vertex_offset", offsetof(ObjectRecord, vertex_offset));
    off("rk_object", "vertex_count", offsetof(ObjectRecord, vertex_count));
    off("rk_object", "triangle_count", offsetof(ObjectRecord, triangle_count));
    return e;
}

/// How this build of the CPU code evaluates the two fusable expressions of
/// Watertight::intersect (intersect/triangle.hpp): A[kx] − sx·A[kz]
/// (`msub`) and U·Az + V·Bz + W·Cz (`tnum`). Compilers fuse them into fma or
/// not depending on flags (GCC -O2 with FMA hardware fuses; -O0/-O1,
/// -ffp-contract=off or no FMA do not), and the device must do the same to
/// return the same t, u, v bit for bit.
struct HostFloatConfig {
    bool fuse_msub = true;
    bool fuse_tnum = true;
    bool probed = false;  ///< false when no probe ray told the variants apart (defaults kept)
};

namespace detail {

/// Watertight::intersect written out with a chosen fusion (volatile keeps
/// the compiler from fusing the unfused variant).
inline bool watertight_variant(const Ray& r, const vec3& p0, const vec3& p1, const vec3& p2, bool fuse_msub,
                               bool fuse_tnum, TriHit& out) {
    const Watertight::RayData d = Watertight::prepare(r);
    const vec3 A = p0 - d.org, B = p1 - d.org, C = p2 - d.org;
    auto msub = [&](float a, float s, float b) {
        if (fuse_msub) return std::fma(-s, b, a);
        volatile float m = s * b;
        return a - m;
    };
    const float Ax = msub(A[d.kx], d.sx, A[d.kz]), Ay = msub(A[d.ky], d.sy, A[d.kz]);
    const float Bx = msub(B[d.kx], d.sx, B[d.kz]), By = msub(B[d.ky], d.sy, B[d.kz]);
    const float Cx = msub(C[d.kx], d.sx, C[d.kz]), Cy = msub(C[d.ky], d.sy, C[d.kz]);
    const double Ud = double(Cx) * double(By) - double(Cy) * double(Bx);
    const double Vd = double(Ax) * double(Cy) - double(Ay) * double(Cx);
    const double Wd = double(Bx) * double(Ay) - double(By) * double(Ax);
    if ((Ud < 0.0 || Vd < 0.0 || Wd < 0.0) && (Ud > 0.0 || Vd > 0.0 || Wd > 0.0)) return false;
    const double detd = Ud + Vd + Wd;
    if (!(detd != 0.0)) return false;
    const float U = static_cast<float>(Ud), V = static_cast<float>(Vd), W = static_cast<float>(Wd);
    const float det = static_cast<float>(detd);
    if (!(det != 0.0f)) return false;
    const float Az = d.sz * A[d.kz], Bz = d.sz * B[d.kz], Cz = d.sz * C[d.kz];
    float T;
    if (fuse_tnum) {
        T = std::fma(W, Cz, std::fma(U, Az, V * Bz));
    } else {
        volatile float a = U * Az, b = V * Bz, c = W * Cz;
        volatile float ab = a + b;
        T = ab + c;
    }
    const float inv = 1.0f / det;
    out = {T * inv, V * inv, W * inv};
    return true;
}

inline bool same_float_bits(float a, float b) noexcept { return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b); }

}  // namespace detail

/// Probes (once) how this translation unit's Watertight::intersect rounds:
/// random rays and triangles until the four fused/unfused variants have been
/// told apart, then the variant the library's own code agrees with.
inline HostFloatConfig host_float_config() {
    static const HostFloatConfig cfg = [] {
        std::uint64_t state = 0x243F6A8885A308D3ull;
        auto next = [&] {  // xorshift, deterministic and cheap
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            return float(double(state >> 40) / double(1ull << 24)) * 2.0f - 1.0f;
        };
        int votes[4] = {0, 0, 0, 0};
        int decisive = 0;
        for (int i = 0; i < 20000 && decisive < 64; ++i) {
            const vec3 c(next(), next(), next());
            const vec3 p0 = c + vec3(next(), next(), next()) * 0.3f, p1 = c + vec3(next(), next(), next()) * 0.3f,
                       p2 = c + vec3(next(), next(), next()) * 0.3f;
            const vec3 o(next() * 3.0f, next() * 3.0f, next() * 3.0f);
            const vec3 target = (p0 + p1 + p2) * (1.0f / 3.0f);
            const Ray r{o, 0.0f, target - o + vec3(next(), next(), next()) * 0.01f, kInf};
            TriHit lib{}, v[4]{};
            bool hl = Watertight::intersect(Watertight::prepare(r), p0, p1, p2, 0.0f, kInf, lib);
            bool hv[4];
            for (int k = 0; k < 4; ++k) hv[k] = detail::watertight_variant(r, p0, p1, p2, k & 1, k & 2, v[k]);
            bool all_same = true;
            for (int k = 1; k < 4; ++k)
                all_same = all_same && hv[k] == hv[0] &&
                           (!hv[0] || (detail::same_float_bits(v[k].t, v[0].t) && detail::same_float_bits(v[k].u, v[0].u) &&
                                       detail::same_float_bits(v[k].v, v[0].v)));
            if (all_same) continue;
            ++decisive;
            for (int k = 0; k < 4; ++k)
                votes[k] += hv[k] == hl && (!hl || (detail::same_float_bits(v[k].t, lib.t) &&
                                                    detail::same_float_bits(v[k].u, lib.u) &&
                                                    detail::same_float_bits(v[k].v, lib.v)));
        }
        HostFloatConfig c;
        if (decisive == 0) return c;
        int best = 3;  // ties prefer fusing (what the device compiler would do by itself)
        for (int k = 2; k >= 0; --k)
            if (votes[k] > votes[best]) best = k;
        c.fuse_msub = best & 1;
        c.fuse_tnum = best & 2;
        c.probed = true;
        return c;
    }();
    return cfg;
}

/// The program preamble every raykit kernel program starts with: the
/// compile-time constants shared with the CPU code, as exact literals, and
/// the host's fusion choices (host_float_config()).
inline std::string config_source() {
    const HostFloatConfig f = host_float_config();
    return "#define RK_MAX_DEPTH " + std::to_string(RAYKIT_BVH_MAX_DEPTH) + "\n" +
           "#define RK_SLAB_EXIT_SCALE " + hex_float(kSlabExitScale) + "\n" +
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
