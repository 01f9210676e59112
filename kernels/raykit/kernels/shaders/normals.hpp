// raykit/kernels/shaders/normals.hpp — the built-in ray hook ShaderKind::normals: 0.5 · N + 0.5
// of the shading normal at the first hit.
// Its C++ type is in include/raykit/cl/render.hpp; the ray-hook API it calls is the core's,
// kernels/raykit/kernels/shade.hpp. One header per shader: a program holds only the hooks it
// renders with.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kShadeNormals = R"CLC(typedef struct {
    float pad;
} rk_normals_params;

void rk_normals(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s, rk_normals_params p) {
    if (hit->prim == RK_INVALID) {
        rk_add_color(ctx, rk_f3(ctx->set.background));
        return;
    }
    rk_set_alpha(ctx, 1.0f);
    rk_add_color(ctx, s->ns * 0.5f + (float3)(0.5f));
}
)CLC";

}  // namespace raykit::kernels
