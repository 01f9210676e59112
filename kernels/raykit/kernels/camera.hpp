// raykit/kernels/camera.hpp — primary rays, the twin of raykit::CameraFrame::ray
// (include/raykit/scene/camera.hpp): same operations in the same order with
// explicit fma(), so the rays are bit-identical to the CPU's.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kCamera = R"CLC(
RK_INLINE rk_ray rk_camera_ray(const rk_camera* cam, uint x, uint y, float jx, float jy) {
    const float fx = (float)x + jx;
    const float fy = (float)y + jy;
    rk_ray r;
    for (int c = 0; c < 3; ++c) {
        r.org[c] = cam->origin[c];
        r.dir[c] = fma(fy, cam->dv[c], fma(fx, cam->du[c], cam->corner[c]));
    }
    r.tmin = 0.0f;
    r.tmax = INFINITY;
    return r;
}

/* One ray per pixel, row-major: rays[y * width + x]. */
__kernel void rk_camera_rays(const rk_camera cam, const float jx, const float jy, __global rk_ray* rays) {
    const uint i = (uint)get_global_id(0);
    if (i >= cam.width * cam.height) return;
    const uint y = i / cam.width;
    const uint x = i - y * cam.width;
    rays[i] = rk_camera_ray(&cam, x, y, jx, jy);
}
)CLC";

}  // namespace raykit::kernels
