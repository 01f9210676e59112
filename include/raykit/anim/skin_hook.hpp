// raykit/anim/skin_hook.hpp — linear blend skinning as a vertex hook of the
// OpenCL core (raykit::cl::DeviceScene), with the CPU skinning of
// anim/skinning.hpp as its twin.
//
//   Scene scene;
//   const std::uint32_t body = scene.add_object(model.mesh, ObjectKind::dynamic);
//   scene.add_instance(body, place);
//   raykit::cl::DeviceScene<raykit::SkinHook> ds(raykit::cl::Device::shared(), scene);
//   const PackedSkin skin = pack_skin(model.weights, model.bones.size());
//   raykit::upload_skin(ds, body, skin);                  // once: offsets + links
//   per frame:
//     raykit::upload_skin_matrices(ds, skin_matrices(skeleton, local));  // 48 bytes per bone
//     ds.update();                                          // skin -> refit -> top level
//
// The hook (name "skin") uses the buffer extension of cl/hook.hpp:
//   buffers  b0 "uint"    PackedSkin::offsets (vertex_count + 1 entries)
//            b1 "ushort2" PackedSkin::links   (.x bone, .y unorm16 weight)
//            b2 "float"   SkinMatrix array, 12 floats per bone (row-major 3x4)
//   Params   { vertex_base, matrix_base, pad, pad }: the object's vertex i
//            reads offsets[vertex_base + i], offsets[vertex_base + i + 1]
//            (absolute indices into links) and bone b's matrix at
//            matrix_base + b. upload_skin() sets both to 0 (one skinned
//            object per DeviceScene); several skinned objects share the
//            buffers by concatenating them and giving each its bases.
// Each vertex is skinned from its rest copy: position M_v (p, 1), normal
// normalize(M_v (n, 0)) (zero stays zero), uv unchanged; a vertex without
// links keeps its rest vertex. M_v = sum_k w_k M_{bone_k}, a single-link
// vertex uses its matrix as is (exact) — the same arithmetic, in the same
// order, as skin_vertices(); the device may contract multiply-adds
// differently, so results agree to float rounding (about 1e-7 of the model).
//
// CPU twin: SkinHook::apply(v, i, p, SkinHook::Host{offsets, links, matrices}),
// or skin_vertices() for a whole mesh. This header needs no OpenCL: the
// upload helpers are templates over the DeviceScene type.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>

#include "raykit/anim/skinning.hpp"
#include "raykit/scene/scene.hpp"

namespace raykit {

struct SkinHook {
    static constexpr const char* name = "skin";
    struct Params {
        std::uint32_t vertex_base = 0;  ///< index of the object's vertex 0 in the offsets buffer
        std::uint32_t matrix_base = 0;  ///< first bone matrix of the object's skeleton
        std::uint32_t pad0 = 0;
        std::uint32_t pad1 = 0;
    };
    static constexpr std::array<const char*, 3> buffers = {"uint", "ushort2", "float"};
    static constexpr const char* source = R"CLC(typedef struct {
    uint vertex_base;
    uint matrix_base;
    uint pad0;
    uint pad1;
} skin_params;

rk_vertex skin(rk_vertex v, uint index, skin_params p, __global const uint* offsets,
               __global const ushort2* links, __global const float* mats) {
    const uint b = offsets[p.vertex_base + index], e = offsets[p.vertex_base + index + 1];
    if (b == e) return v;
    float a[12];
    if (e - b == 1) {
        __global const float* m = mats + 12 * (p.matrix_base + (uint)links[b].x);
        for (int j = 0; j < 12; ++j) a[j] = m[j];
    } else {
        for (int j = 0; j < 12; ++j) a[j] = 0.0f;
        for (uint k = b; k < e; ++k) {
            const ushort2 l = links[k];
            const float w = (float)l.y * (1.0f / 65535.0f);
            __global const float* m = mats + 12 * (p.matrix_base + (uint)l.x);
            for (int j = 0; j < 12; ++j) a[j] += w * m[j];
        }
    }
    const float3 q = rk_vertex_position(v);
    v = rk_vertex_set_position(v, (float3)(a[0] * q.x + a[1] * q.y + a[2] * q.z + a[3],
                                           a[4] * q.x + a[5] * q.y + a[6] * q.z + a[7],
                                           a[8] * q.x + a[9] * q.y + a[10] * q.z + a[11]));
    const float3 n = rk_vertex_normal(v);
    const float3 t = (float3)(a[0] * n.x + a[1] * n.y + a[2] * n.z, a[4] * n.x + a[5] * n.y + a[6] * n.z,
                              a[8] * n.x + a[9] * n.y + a[10] * n.z);
    const float len2 = t.x * t.x + t.y * t.y + t.z * t.z;
    return rk_vertex_set_normal(v, len2 > 0.0f ? t * (1.0f / sqrt(len2)) : (float3)(0.0f));
}
)CLC";

    /// Host copies of the three buffers, for the CPU twin.
    struct Host {
        std::span<const std::uint32_t> offsets;
        std::span<const PackedLink> links;
        std::span<const SkinMatrix> matrices;
    };
    /// CPU twin of one vertex (the arithmetic of skin_vertices()).
    static Vertex apply(const Vertex& v, std::uint32_t index, const Params& p, const Host& h) {
        const std::uint32_t b = h.offsets[p.vertex_base + index], e = h.offsets[p.vertex_base + index + 1];
        if (b == e) return v;
        float a[12];
        detail::skin_blend(h.links.data() + b, e - b, h.matrices.data() + p.matrix_base, a);
        Vertex o = v;
        const vec3 q = v.position, n = v.normal;
        o.position = vec3(a[0] * q.x + a[1] * q.y + a[2] * q.z + a[3], a[4] * q.x + a[5] * q.y + a[6] * q.z + a[7],
                          a[8] * q.x + a[9] * q.y + a[10] * q.z + a[11]);
        const vec3 t(a[0] * n.x + a[1] * n.y + a[2] * n.z, a[4] * n.x + a[5] * n.y + a[6] * n.z,
                     a[8] * n.x + a[9] * n.y + a[10] * n.z);
        const float len2 = t.x * t.x + t.y * t.y + t.z * t.z;
        o.normal = len2 > 0.0f ? t * (1.0f / std::sqrt(len2)) : vec3(0.0f);
        return o;
    }
};

/// Uploads `skin`'s offsets and links as SkinHook buffers 0 and 1 and lets
/// SkinHook move dynamic object `object` (bases 0). Throws
/// std::invalid_argument when the skin's vertex count is not the object's.
template <class DeviceSceneT>
void upload_skin(DeviceSceneT& ds, const Scene& scene, std::uint32_t object, const PackedSkin& skin) {
    if (object >= scene.objects().size() || scene.objects()[object].mesh.positions.size() != skin.vertex_count())
        throw std::invalid_argument("raykit::upload_skin: the skin has " + std::to_string(skin.vertex_count()) +
                                    " vertices, not the object's count");
    ds.template set_hook_buffer<SkinHook>(0, std::span<const std::uint32_t>(skin.offsets));
    ds.template set_hook_buffer<SkinHook>(1, std::span<const PackedLink>(skin.links));
    ds.template set_hook<SkinHook>(object, SkinHook::Params{});
}

/// Uploads this frame's bone matrices (SkinHook buffer 2).
template <class DeviceSceneT>
void upload_skin_matrices(DeviceSceneT& ds, std::span<const SkinMatrix> matrices) {
    ds.template set_hook_buffer<SkinHook>(2, matrices);
}

}  // namespace raykit
