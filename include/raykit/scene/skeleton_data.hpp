// raykit/scene/skeleton_data.hpp — the format-independent data of a skinned
// model: bones, bone poses and per-vertex bone weights.
//
// Why here and not in anim/: the SMD parser (io/smd.hpp) fills these types,
// and io/ sits below anim/ (anim/ includes io/ for the loaders), so the types
// must live at or below io/. They are plain data beside the mesh they skin,
// and need nothing but math, so they sit in scene/ next to mesh.hpp. What
// works on them (Skeleton, interpolation, skinning, the skinning vertex hook)
// is in anim/; what is SMD's own (the file's record SmdModel, the parser, the
// texture rule) stays in io/smd.hpp.
#pragma once

#include <cstdint>
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

}  // namespace raykit
