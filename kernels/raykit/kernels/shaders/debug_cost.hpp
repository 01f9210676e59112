// raykit/kernels/shaders/debug_cost.hpp — the built-in ray hook ShaderKind::debug_cost: the
// camera ray's traversal steps.
// Its C++ type is in include/raykit/cl/render.hpp; the ray-hook API it calls is the core's,
// kernels/raykit/kernels/shade.hpp. One header per shader: a program holds only the hooks it
// renders with.
#pragma once

namespace raykit::kernels {

/// ShaderKind::debug_cost: the camera ray's traversal steps; the host maps them to colours.
inline constexpr const char* kShadeDebugCost = R"CLC(typedef struct {
    float pad;
} rk_debug_cost_params;

void rk_debug_cost(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s,
                   rk_debug_cost_params p) {
    rk_set_alpha(ctx, hit->prim == RK_INVALID ? 0.0f : 1.0f);
    rk_add_color(ctx, (float3)((float)rk_traversal_steps(ctx)));
}
)CLC";

}  // namespace raykit::kernels
