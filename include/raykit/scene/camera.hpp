// raykit/scene/camera.hpp — pinhole camera and its primary rays.
//
//   Camera cam{.position = {0, 0, 5}, .target = {0, 0, 0}, .up = {0, 1, 0},
//              .vfov_degrees = 45, .width = 640, .height = 480};
//   Ray r = cam.ray(x, y);                      // through the centre of pixel (x, y)
//   std::vector<Ray> all = camera_rays(cam);    // row-major, width * height rays
//
// Pixel convention: pixel (0, 0) is the top-left one; x grows to the right,
// y downwards. The image plane spans [0, width] x [0, height] in pixel units
// and ray(x, y, jx, jy) goes through the image point (x + jx, y + jy), so the
// default jitter 0.5 is the pixel centre; 0 and 1 are its edges.
//
// Rays start at the camera position with tmin = 0, tmax = inf. Directions are
// NOT normalised: dir = forward + a·right + b·up with forward a unit vector,
// so |dir| >= 1 and t is in units of |dir| (as everywhere in raykit).
//
// Bit-exact twin on the device: everything that needs division, sqrt or tan
// is done once per frame on the host (Camera::frame(), in double, rounded to
// float). Per ray, both the CPU (CameraFrame::ray) and the kernel compute
//   fx = float(x) + jx,  fy = float(y) + jy,
//   dir[c] = fma(fy, dv[c], fma(fx, du[c], corner[c]))
// with explicit fused multiply-adds, which are correctly rounded on both
// sides, so no compiler contraction (-ffp-contract) can make them differ:
// device rays equal CPU rays bit for bit (for x, y < 2^24).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "raykit/math/aabb.hpp"
#include "raykit/math/ray.hpp"

namespace raykit {

/// Per-frame constants of a camera; crosses to OpenCL as rk_camera (56 bytes).
struct CameraFrame {
    vec3 origin{0.0f};
    vec3 corner{0.0f, 0.0f, -1.0f};  ///< direction to the image point (0, 0), the top-left corner
    vec3 du{0.0f};                   ///< change of direction per pixel to the right
    vec3 dv{0.0f};                   ///< change of direction per pixel downwards
    std::uint32_t width = 0;
    std::uint32_t height = 0;

    /// Direction of the ray through the image point (x + jx, y + jy) (not normalised).
    vec3 dir(std::uint32_t x, std::uint32_t y, float jx = 0.5f, float jy = 0.5f) const noexcept {
        const float fx = static_cast<float>(x) + jx;
        const float fy = static_cast<float>(y) + jy;
        return vec3(std::fma(fy, dv.x, std::fma(fx, du.x, corner.x)), std::fma(fy, dv.y, std::fma(fx, du.y, corner.y)),
                    std::fma(fy, dv.z, std::fma(fx, du.z, corner.z)));
    }
    /// Ray through the image point (x + jx, y + jy).
    Ray ray(std::uint32_t x, std::uint32_t y, float jx = 0.5f, float jy = 0.5f) const noexcept {
        return Ray{origin, 0.0f, dir(x, y, jx, jy), kInf};
    }
    /// ray(), written field by field into `r`: a copy of a whole Ray made just before loads it
    /// back from the stores that built it (a store-forwarding stall that took 19 % of the
    /// renderer's own time on the thesis scene, perf).
    void ray_into(Ray& r, std::uint32_t x, std::uint32_t y, float jx = 0.5f, float jy = 0.5f) const noexcept {
        r.org = origin;
        r.tmin = 0.0f;
        r.dir = dir(x, y, jx, jy);
        r.tmax = kInf;
    }
};
static_assert(sizeof(CameraFrame) == 56 && alignof(CameraFrame) == 4);

struct Camera {
    vec3 position{0.0f, 0.0f, 5.0f};
    vec3 target{0.0f};
    vec3 up{0.0f, 1.0f, 0.0f};
    float vfov_degrees = 45.0f;  ///< full vertical field of view, in (0, 180)
    std::uint32_t width = 512;
    std::uint32_t height = 512;

    /// The per-frame constants. Throws std::invalid_argument for a zero-sized
    /// image, a field of view outside (0, 180), non-finite vectors, position
    /// == target, or `up` parallel to the viewing direction.
    CameraFrame frame() const {
        if (width == 0 || height == 0) throw std::invalid_argument("raykit::Camera: image size must be positive");
        if (!(vfov_degrees > 0.0f && vfov_degrees < 180.0f))
            throw std::invalid_argument("raykit::Camera: vfov_degrees must be in (0, 180)");
        if (!is_finite(position) || !is_finite(target) || !is_finite(up))
            throw std::invalid_argument("raykit::Camera: position, target and up must be finite");
        const dvec3 f0 = dvec3(target) - dvec3(position);
        const double fl = glm::length(f0);
        if (!(fl > 0.0)) throw std::invalid_argument("raykit::Camera: position equals target");
        const dvec3 fwd = f0 / fl;
        const dvec3 r0 = glm::cross(fwd, dvec3(up));
        const double rl = glm::length(r0);
        if (!(rl > 1e-12 * glm::length(dvec3(up))) || !(rl > 0.0))
            throw std::invalid_argument("raykit::Camera: up is parallel to the viewing direction");
        const dvec3 right = r0 / rl;
        const dvec3 upv = glm::cross(right, fwd);
        const double half_h = std::tan(0.5 * double(vfov_degrees) * 3.14159265358979323846 / 180.0);
        const double half_w = half_h * double(width) / double(height);
        CameraFrame f;
        f.origin = position;
        f.corner = vec3(fwd - right * half_w + upv * half_h);
        f.du = vec3(right * (2.0 * half_w / double(width)));
        f.dv = vec3(upv * (-2.0 * half_h / double(height)));
        f.width = width;
        f.height = height;
        return f;
    }

    /// Ray through the image point (x + jx, y + jy); computes frame() each
    /// call — use frame().ray() or camera_rays() for many rays.
    Ray ray(std::uint32_t x, std::uint32_t y, float jx = 0.5f, float jy = 0.5f) const {
        return frame().ray(x, y, jx, jy);
    }
};

/// All width·height rays through the pixel points (x + jx, y + jy), row-major
/// (index y·width + x).
inline std::vector<Ray> camera_rays(const Camera& cam, float jx = 0.5f, float jy = 0.5f) {
    const CameraFrame f = cam.frame();
    std::vector<Ray> rays(std::size_t(f.width) * f.height);
    for (std::uint32_t y = 0; y < f.height; ++y)
        for (std::uint32_t x = 0; x < f.width; ++x) rays[std::size_t(y) * f.width + x] = f.ray(x, y, jx, jy);
    return rays;
}

/// A camera looking at `box` from direction `from` (need not be normalised),
/// far enough for the bounding sphere to fit the vertical field of view.
inline Camera camera_looking_at(const AABB& box, std::uint32_t width, std::uint32_t height,
                                vec3 from = vec3(1.0f, 0.6f, 0.8f), float vfov_degrees = 45.0f) {
    Camera c;
    const vec3 center = box.is_empty() ? vec3(0.0f) : box.center();
    const float radius = box.is_empty() ? 1.0f : std::max(0.5f * glm::length(box.max - box.min), 1e-6f);
    const float dist = radius / std::sin(0.5f * vfov_degrees * 3.14159265f / 180.0f) * 1.05f;
    c.position = center + glm::normalize(from) * dist;
    c.target = center;
    c.up = std::fabs(glm::normalize(from).y) > 0.999f ? vec3(0.0f, 0.0f, 1.0f) : vec3(0.0f, 1.0f, 0.0f);
    c.vfov_degrees = vfov_degrees;
    c.width = width;
    c.height = height;
    return c;
}

}  // namespace raykit
