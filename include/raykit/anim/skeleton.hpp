// raykit/anim/skeleton.hpp — bone hierarchy, local and world transforms,
// inverse bind matrices.
//
// Interface
// ---------
//   struct BoneTransform { glm::dquat rotation; glm::dvec3 translation; };
//       A rigid local transform x -> rotation * x + translation (double, so
//       that world * inverse(bind) of the bind pose is the identity to ~1e-15).
//   glm::dquat euler_xyz_quat(const glm::dvec3& r);
//   glm::dmat3 euler_xyz_matrix(const glm::dvec3& r);
//       SMD / Valve convention: R = Rz(r.z) * Ry(r.y) * Rx(r.x) (column
//       vectors: the X rotation is applied first). Angles in radians.
//   BoneTransform bone_transform(const BonePose& pose);
//   glm::dmat4 transform_matrix(const BoneTransform& t);      // T(translation) * R
//   glm::dmat4 rigid_inverse(const glm::dmat4& m);             // for rotation+translation only
//
//   class Skeleton
//       Skeleton(std::vector<Bone> bones, std::span<const BonePose> bind_pose);
//       explicit Skeleton(const SmdModel& reference);
//           Throws std::invalid_argument when bind_pose has the wrong length, a
//           parent is not a bone or the parents form a cycle. Bones may come
//           in any order (a child before its parent) and there may be several
//           roots.
//       size(), bones(), order() (every parent before its children),
//       bind_world() (world matrices of the bind pose), inverse_bind().
//       world_matrices(local, out): world(b) = world(parent(b)) * local(b),
//           world(root) = local(root); `local` and `out` have size() entries.
//       skinning_matrices(local, out): world(b) * inverse_bind(b), the matrix
//           that carries a bind-pose (model space) vertex of bone b to the pose.
//       bind_transforms(): the bind pose as BoneTransforms.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>

#include "raykit/io/smd.hpp"
#include "raykit/math/types.hpp"
#include "raykit/scene/skeleton_data.hpp"

namespace raykit {

/// A rigid transform: x -> rotation * x + translation.
struct BoneTransform {
    glm::dquat rotation{1.0, 0.0, 0.0, 0.0};  // (w, x, y, z)
    glm::dvec3 translation{0.0};
};

/// Quaternion of Rz(r.z) * Ry(r.y) * Rx(r.x).
inline glm::dquat euler_xyz_quat(const glm::dvec3& r) noexcept {
    const double cx = std::cos(0.5 * r.x), sx = std::sin(0.5 * r.x);
    const double cy = std::cos(0.5 * r.y), sy = std::sin(0.5 * r.y);
    const double cz = std::cos(0.5 * r.z), sz = std::sin(0.5 * r.z);
    return glm::dquat(cz * cy * cx + sz * sy * sx,   // w
                      cz * cy * sx - sz * sy * cx,   // x
                      cz * sy * cx + sz * cy * sx,   // y
                      sz * cy * cx - cz * sy * sx);  // z
}

/// Rotation matrix Rz(r.z) * Ry(r.y) * Rx(r.x).
inline glm::dmat3 euler_xyz_matrix(const glm::dvec3& r) noexcept {
    return glm::mat3_cast(euler_xyz_quat(r));
}

inline BoneTransform bone_transform(const BonePose& pose) noexcept {
    return BoneTransform{euler_xyz_quat(glm::dvec3(pose.rotation)), glm::dvec3(pose.position)};
}

/// T(translation) * R(rotation) as a 4x4 matrix.
inline glm::dmat4 transform_matrix(const BoneTransform& t) noexcept {
    glm::dmat4 m(glm::mat3_cast(t.rotation));
    m[3] = glm::dvec4(t.translation, 1.0);
    return m;
}

/// Inverse of a rotation + translation matrix: [R^T | -R^T t].
inline glm::dmat4 rigid_inverse(const glm::dmat4& m) noexcept {
    const glm::dmat3 rt = glm::transpose(glm::dmat3(m));
    glm::dmat4 inv(rt);
    inv[3] = glm::dvec4(-(rt * glm::dvec3(m[3])), 1.0);
    return inv;
}

class Skeleton {
public:
    Skeleton() = default;

    Skeleton(std::vector<Bone> bones, std::span<const BonePose> bind_pose) : bones_(std::move(bones)) {
        const std::size_t n = bones_.size();
        if (bind_pose.size() != n) throw std::invalid_argument("Skeleton: bind pose needs one pose per bone");
        for (std::size_t i = 0; i < n; ++i) {
            const int p = bones_[i].parent;
            if (p < -1 || p >= static_cast<int>(n)) {
                throw std::invalid_argument("Skeleton: parent of bone " + std::to_string(i) + " is not a bone");
            }
        }
        // Depth of each bone (parents first = increasing depth); a walk longer
        // than n steps means a cycle.
        std::vector<std::size_t> depth(n, 0);
        for (std::size_t i = 0; i < n; ++i) {
            std::size_t d = 0;
            for (int b = bones_[i].parent; b >= 0; b = bones_[static_cast<std::size_t>(b)].parent) {
                if (++d > n) throw std::invalid_argument("Skeleton: parent cycle through bone " + std::to_string(i));
            }
            depth[i] = d;
        }
        order_.resize(n);
        for (std::size_t i = 0; i < n; ++i) order_[i] = static_cast<std::uint32_t>(i);
        std::stable_sort(order_.begin(), order_.end(),
                         [&](std::uint32_t a, std::uint32_t b) { return depth[a] < depth[b]; });
        std::vector<BoneTransform> local(n);
        for (std::size_t i = 0; i < n; ++i) local[i] = bone_transform(bind_pose[i]);
        bind_world_.resize(n);
        world_matrices(local, bind_world_);
        inverse_bind_.resize(n);
        for (std::size_t i = 0; i < n; ++i) inverse_bind_[i] = rigid_inverse(bind_world_[i]);
        bind_local_ = std::move(local);
    }

    explicit Skeleton(const SmdModel& reference) : Skeleton(reference.bones, reference.bind_pose) {}

    std::size_t size() const noexcept { return bones_.size(); }
    const std::vector<Bone>& bones() const noexcept { return bones_; }
    /// Bone indices with every parent before its children.
    const std::vector<std::uint32_t>& order() const noexcept { return order_; }
    const std::vector<glm::dmat4>& bind_world() const noexcept { return bind_world_; }
    const std::vector<glm::dmat4>& inverse_bind() const noexcept { return inverse_bind_; }
    const std::vector<BoneTransform>& bind_transforms() const noexcept { return bind_local_; }

    /// world(b) = world(parent) * local(b). `local` and `world` have size() entries.
    void world_matrices(std::span<const BoneTransform> local, std::span<glm::dmat4> world) const {
        check_sizes(local.size(), world.size());
        for (const std::uint32_t b : order_) {
            const glm::dmat4 m = transform_matrix(local[b]);
            const int p = bones_[b].parent;
            world[b] = p < 0 ? m : world[static_cast<std::size_t>(p)] * m;
        }
    }
    std::vector<glm::dmat4> world_matrices(std::span<const BoneTransform> local) const {
        std::vector<glm::dmat4> w(size());
        world_matrices(local, w);
        return w;
    }

    /// world(b) * inverse_bind(b): bind-pose model space -> posed model space.
    void skinning_matrices(std::span<const BoneTransform> local, std::span<glm::dmat4> out) const {
        world_matrices(local, out);
        for (std::size_t b = 0; b < size(); ++b) out[b] = out[b] * inverse_bind_[b];
    }
    std::vector<glm::dmat4> skinning_matrices(std::span<const BoneTransform> local) const {
        std::vector<glm::dmat4> m(size());
        skinning_matrices(local, m);
        return m;
    }

private:
    void check_sizes(std::size_t in, std::size_t out) const {
        if (in != size() || out != size()) {
            throw std::invalid_argument("Skeleton: pose and output need one entry per bone");
        }
    }

    std::vector<Bone> bones_;
    std::vector<std::uint32_t> order_;
    std::vector<glm::dmat4> bind_world_;
    std::vector<glm::dmat4> inverse_bind_;
    std::vector<BoneTransform> bind_local_;
};

}  // namespace raykit
