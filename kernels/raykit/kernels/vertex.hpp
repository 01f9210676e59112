// raykit/kernels/vertex.hpp — the vertex stage, instantiated once per vertex
// hook a scene uses (raykit::cl::DeviceScene replaces @NAME@ with the hook's
// name; see include/raykit/cl/hook.hpp for what a hook provides).
//
// One work item per vertex of every dynamic object moved by this hook; the
// objects' vertex ranges are concatenated: range r covers work items
// [begin[r], begin[r+1]). Each vertex is computed from the untouched rest
// copy, never from the previous frame:
//   moved[pos_offset[r] + i] = @NAME@(rest[rest_offset[r] + i], i, params[r])
// (the scene's vertex records, read by the renderer) and its position also
// goes to the scene's position array (read by trace and refit) at the same
// vertex.
// @BUFFER_PARAMS@ / @BUFFER_ARGS@ become the hook's global buffers (see
// H::buffers in include/raykit/cl/hook.hpp): extra kernel parameters
// ", __global const T0* rk_hook_buf0, ..." passed on to the hook function;
// both are empty for a hook without buffers.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kVertexStage = R"CLC(
__kernel void rk_vertex_stage_@NAME@(__global const rk_vertex* rest, __global rk_vertex* moved, __global float* pos,
                                     __global const uint* begin, __global const uint* rest_offset,
                                     __global const uint* pos_offset, __global const @NAME@_params* params,
                                     const uint ranges, const uint total@BUFFER_PARAMS@) {
    const uint i = (uint)get_global_id(0);
    if (i >= total) return;
    /* the range r with begin[r] <= i < begin[r+1]: a binary search with the
       same trip count for every work item (so the compiler may vectorize) */
    uint lo = 0;
    for (uint step = 1u << (31 - clz(ranges)); step > 0u; step >>= 1)
        if (lo + step < ranges && begin[lo + step] <= i) lo += step;
    const uint k = i - begin[lo]; /* vertex index within its object */
    const @NAME@_params p = params[lo];
    const rk_vertex w = @NAME@(rest[rest_offset[lo] + k], k, p@BUFFER_ARGS@);
    moved[pos_offset[lo] + k] = w;
    vstore3((float3)(w.position[0], w.position[1], w.position[2]), pos_offset[lo] + k, pos);
}
)CLC";

}  // namespace raykit::kernels
