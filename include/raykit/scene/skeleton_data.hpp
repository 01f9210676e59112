// raykit/scene/skeleton_data.hpp — the format-independent data of a skinned
// model: bones, bone poses, per-vertex bone weights and the key frames of a
// skeletal animation.
//
// Why here and not in anim/: the SMD parser (io/smd.hpp) fills these types,
// and io/ sits below anim/ (anim/ includes io/ for the loaders), so the types
// must live at or below io/. They are plain data beside the mesh they skin,
// and need nothing but math, so they sit in scene/ next to mesh.hpp. What
// works on them (Skeleton, interpolation, skinning, the skinning vertex hook)
// is in anim/; what is SMD's own (the file's record SmdModel, the parser, the
// texture rule) stays in io/smd.hpp.
//
// SmdSkeletonAnim keeps its name (users' code spells it) although nothing in
// it is SMD's own: key frames, each one pose per bone of a reference skeleton,
// at increasing frame numbers; a frame between two keys shows the earlier key,
// so a hold costs one key, not one copy per held frame (a 4 KB SMD with a
// `time` gap used to expand to 2.6 GB; io/smd.hpp). anim/interpolate.hpp
// samples it between frames.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "raykit/math/types.hpp"

namespace raykit {

/// A node of the skeleton. parent is the index of the parent bone, -1 for a root.
struct Bone {
    std::string name;  ///< unique within a skeleton
    int parent = -1;   ///< index of the parent bone, -1 for a root
};

/// Local pose of a bone relative to its parent, as SMD stores it: translation
/// and Euler angles in radians. The rotation matrix is Rz(z) * Ry(y) * Rx(x)
/// (anim/skeleton.hpp: euler_xyz_quat).
struct BonePose {
    vec3 position{0.0f};  ///< translation relative to the parent
    vec3 rotation{0.0f};  ///< Euler XYZ angles in radians
};

/// One bone influence of a vertex.
struct BoneWeight {
    std::uint32_t bone = 0;  ///< bone index
    float weight = 0.0f;     ///< > 0
};

/// The bone influences of one vertex: distinct bones, weights > 0 summing to 1
/// (up to float rounding); the SMD loader keeps file order with Valve's parent
/// remainder last.
struct VertexWeights {
    std::vector<BoneWeight> links;  ///< the influences
};

/// A skeletal animation: key frames frames[k][bone] at frame numbers times[k]
/// (times[0] == 0, strictly increasing; empty: key k is frame k).
struct SmdSkeletonAnim {
    std::vector<std::vector<BonePose>> frames;  ///< key frames, one pose per reference bone
    std::vector<std::uint32_t> times;           ///< frame number of each key; empty: key k is frame k
    float fps = 30.0f;                          ///< frames per second (SMD stores none: 30)
    std::vector<std::string> warnings;          ///< the loader's non-fatal remarks, "FILE:LINE: message"

    /// Key frames stored.
    std::size_t key_count() const noexcept { return frames.size(); }
    /// Frames the animation spans: the last key's frame number + 1.
    std::size_t frame_count() const noexcept {
        if (times.empty() || frames.empty()) return frames.size();
        return static_cast<std::size_t>(times.back()) + 1;
    }
    /// Index of the key that frame `f` shows: the last key at or before f.
    /// Throws std::out_of_range for f >= frame_count(), std::invalid_argument
    /// when times is neither empty nor one entry per key starting at 0.
    std::size_t key_of_frame(std::size_t f) const {
        if (f >= frame_count()) {
            throw std::out_of_range("SmdSkeletonAnim: frame " + std::to_string(f) + " of " +
                                    std::to_string(frame_count()));
        }
        if (times.empty()) return f;
        if (times.size() != frames.size() || times.front() != 0) {
            throw std::invalid_argument("SmdSkeletonAnim: times must be empty or one per key frame, starting at 0");
        }
        const auto it = std::upper_bound(times.begin(), times.end(), f,
                                         [](std::size_t v, std::uint32_t t) { return v < t; });
        return static_cast<std::size_t>(it - times.begin()) - 1;
    }
    /// The poses of frame f (one per reference bone).
    const std::vector<BonePose>& frame(std::size_t f) const { return frames[key_of_frame(f)]; }
};

}  // namespace raykit
