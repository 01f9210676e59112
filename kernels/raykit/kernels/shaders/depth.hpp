// raykit/kernels/shaders/depth.hpp — the built-in ray hook ShaderKind::depth: 1 - distance / far
// at the first hit.
// Its C++ type is in include/raykit/cl/render.hpp; the ray-hook API it calls is the core's,
// kernels/raykit/kernels/shade.hpp. One header per shader: a program holds only the hooks it
// renders with.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kShadeDepth = R"CLC(typedef struct {
    float pad;
} rk_depth_params;

void rk_depth(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s, rk_depth_params p) {
    if (hit->prim == RK_INVALID) {
        rk_add_color(ctx, rk_f3(ctx->set.background));
        return;
    }
    rk_set_alpha(ctx, 1.0f);
    const float far = ctx->set.depth_far;
    const float dist = hit->t * length(rk_f3(path->ray.dir));
    rk_add_color(ctx, (float3)(far > 0.0f ? clamp(1.0f - dist / far, 0.0f, 1.0f) : 0.0f));
}
)CLC";

}  // namespace raykit::kernels
