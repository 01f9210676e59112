// raykit/anim/interpolate.hpp — sampling a skeletal animation between key frames.
//
// Interface
// ---------
//   enum class Interpolation { slerp, euler };
//       slerp (default): local rotations as quaternions, spherical linear
//           interpolation along the shorter arc; translations lerped.
//       euler: the thesis's scheme — each Euler angle (x, y, z) moves along
//           its shortest signed difference, wrapped into [-pi, pi], then the
//           rotation is rebuilt as Rz*Ry*Rx; translations lerped. It agrees
//           with slerp for a rotation about one axis and differs when several
//           angles change at once.
//   enum class WrapMode { clamp, loop };
//       clamp: frames before 0 / after N-1 hold the first / last frame.
//       loop: the animation repeats with period N frames; between frame N-1
//           and N it blends frame N-1 into frame 0.
//
//   struct FrameBlend { std::size_t from, to; double t; };
//   FrameBlend frame_blend(std::size_t frame_count, double frame, WrapMode mode);
//       Which two key frames a (fractional) frame number lies between and the
//       blend factor t in [0, 1). Throws std::invalid_argument for
//       frame_count == 0 or a non-finite frame.
//   double shortest_angle_lerp(double a, double b, double t);
//       a + t * d, d = (b - a) wrapped into [-pi, pi] (radians).
//   glm::dquat slerp_shortest(glm::dquat a, glm::dquat b, double t);
//       Unit-quaternion slerp along the shorter arc (b is negated when
//       dot(a, b) < 0); falls back to a normalized lerp for nearly equal
//       inputs. t = 0 gives a exactly.
//   BoneTransform interpolate_pose(const BonePose& a, const BonePose& b, double t, Interpolation);
//   void interpolate_poses(std::span<const BonePose> a, std::span<const BonePose> b, double t,
//                          Interpolation, std::span<BoneTransform> out);       // equal sizes
//   std::vector<BoneTransform> sample_frame(const SmdSkeletonAnim&, double frame,
//                                           Interpolation = slerp, WrapMode = clamp);
//   std::vector<BoneTransform> sample_time(const SmdSkeletonAnim&, double seconds,
//                                          Interpolation = slerp, WrapMode = clamp);
//       The local transforms of every bone at a fractional frame number, or
//       at a time in seconds (frame = seconds * anim.fps). Feed them to
//       Skeleton::skinning_matrices. Frames are the animation's frame
//       numbers 0 .. frame_count() - 1, gaps included: frame_blend over
//       frame_count(), then the two frames' poses are anim.frame(from) and
//       anim.frame(to) (a frame inside a gap shows the key before it, so
//       the blend across a gap's last frame is the hold-then-move of the
//       file repeating that key).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <numbers>
#include <span>
#include <stdexcept>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "raykit/anim/skeleton.hpp"
#include "raykit/scene/skeleton_data.hpp"

namespace raykit {

enum class Interpolation { slerp, euler };
enum class WrapMode { clamp, loop };

struct FrameBlend {
    std::size_t from = 0;
    std::size_t to = 0;
    double t = 0.0;  ///< weight of `to`, in [0, 1)
};

inline FrameBlend frame_blend(std::size_t frame_count, double frame, WrapMode mode) {
    if (frame_count == 0) throw std::invalid_argument("frame_blend: the animation has no frames");
    if (!std::isfinite(frame)) throw std::invalid_argument("frame_blend: frame number is not finite");
    const auto n = static_cast<double>(frame_count);
    FrameBlend fb;
    if (mode == WrapMode::loop) {
        double f = std::fmod(frame, n);
        if (f < 0.0) f += n;
        if (f >= n) f = 0.0;  // -tiny + n rounds to n
        const double base = std::floor(f);
        fb.from = static_cast<std::size_t>(base);
        if (fb.from >= frame_count) fb.from = frame_count - 1;
        fb.to = (fb.from + 1) % frame_count;
        fb.t = f - base;
    } else {
        const double f = std::clamp(frame, 0.0, n - 1.0);
        const double base = std::floor(f);
        fb.from = static_cast<std::size_t>(base);
        fb.to = std::min(fb.from + 1, frame_count - 1);
        fb.t = fb.to == fb.from ? 0.0 : f - base;
    }
    if (fb.t >= 1.0) fb.t = std::nextafter(1.0, 0.0);
    return fb;
}

inline double shortest_angle_lerp(double a, double b, double t) noexcept {
    const double d = std::remainder(b - a, 2.0 * std::numbers::pi);
    return a + t * d;
}

inline glm::dquat slerp_shortest(glm::dquat a, glm::dquat b, double t) noexcept {
    double c = glm::dot(a, b);
    if (c < 0.0) {
        b = -b;
        c = -c;
    }
    if (t == 0.0) return a;
    double wa, wb;
    if (c > 1.0 - 1e-12) {
        wa = 1.0 - t;
        wb = t;
    } else {
        const double angle = std::acos(c);
        const double s = std::sin(angle);
        wa = std::sin((1.0 - t) * angle) / s;
        wb = std::sin(t * angle) / s;
    }
    return glm::normalize(glm::dquat(wa * a.w + wb * b.w, wa * a.x + wb * b.x, wa * a.y + wb * b.y,
                                     wa * a.z + wb * b.z));
}

inline BoneTransform interpolate_pose(const BonePose& a, const BonePose& b, double t, Interpolation mode) noexcept {
    BoneTransform out;
    const glm::dvec3 pa(a.position), pb(b.position);
    out.translation = pa + t * (pb - pa);
    const glm::dvec3 ra(a.rotation), rb(b.rotation);
    if (mode == Interpolation::euler) {
        const glm::dvec3 r(shortest_angle_lerp(ra.x, rb.x, t), shortest_angle_lerp(ra.y, rb.y, t),
                           shortest_angle_lerp(ra.z, rb.z, t));
        out.rotation = euler_xyz_quat(r);
    } else {
        out.rotation = slerp_shortest(euler_xyz_quat(ra), euler_xyz_quat(rb), t);
    }
    return out;
}

inline void interpolate_poses(std::span<const BonePose> a, std::span<const BonePose> b, double t, Interpolation mode,
                              std::span<BoneTransform> out) {
    if (a.size() != b.size() || a.size() != out.size()) {
        throw std::invalid_argument("interpolate_poses: poses and output need the same number of bones");
    }
    for (std::size_t i = 0; i < a.size(); ++i) out[i] = interpolate_pose(a[i], b[i], t, mode);
}

inline std::vector<BoneTransform> sample_frame(const SmdSkeletonAnim& anim, double frame,
                                               Interpolation mode = Interpolation::slerp,
                                               WrapMode wrap = WrapMode::clamp) {
    const FrameBlend fb = frame_blend(anim.frame_count(), frame, wrap);
    const std::vector<BonePose>& from = anim.frame(fb.from);
    const std::vector<BonePose>& to = anim.frame(fb.to);
    std::vector<BoneTransform> out(from.size());
    interpolate_poses(from, to, fb.t, mode, out);
    return out;
}

inline std::vector<BoneTransform> sample_time(const SmdSkeletonAnim& anim, double seconds,
                                              Interpolation mode = Interpolation::slerp,
                                              WrapMode wrap = WrapMode::clamp) {
    if (!(anim.fps > 0.0f) || !std::isfinite(anim.fps)) throw std::invalid_argument("sample_time: fps must be > 0");
    return sample_frame(anim, seconds * static_cast<double>(anim.fps), mode, wrap);
}

}  // namespace raykit
