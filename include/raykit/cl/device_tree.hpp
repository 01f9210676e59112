// raykit/cl/device_tree.hpp — an object's tree and triangles in the form the device walks.
//
// The device walks the CPU's fastest form (scene/block_bvh.hpp's BlockBvh8): 8-wide
// nodes whose leaves are runs of TriangleBlock4 (four triangles' vertices copied in
// leaf order, structure of arrays), each block tested in one 4-lane watertight test
// (kernels/raykit/kernels/common.hpp rk_wt4_intersect). The blocks themselves and the
// tree are uploaded as the CPU holds them, so the device's traversal steps equal the
// CPU's node and leaf counts for the same tree (figures: kernels/raykit/kernels/trace.hpp).
//
//   device_tree(blocks)     node 0 holds the root box alone in slot 0 (its inner child
//                           is node 1: the twin of the CPU's first test of
//                           WideBvhT::bounds, refitted like any node); nodes 1.. are the
//                           BlockBvh8's with inner indices + 1; leaves name block runs.
//                           DeviceScene uploads a Scene object's BlockBvh8 (the very
//                           tree the CPU's queries walk, refitted in place since it was
//                           made); MeshTracer makes one from the given Bvh.
// Dynamic objects rewrite their blocks on the device in the refit's leaf step
// (kernels/raykit/kernels/refit.hpp), after the vertex stage: no read-back.
//
//   quantize_node(n)        the node with its child boxes as bytes (QuantizedNode, 104 bytes
//                           against 256), in the spirit of Ylitie, Karras and Laine's compressed
//                           wide BVH: per axis an origin (the used children's lowest plane) and
//                           a power-of-two step, each plane rounded outward to a byte. Every
//                           step is float arithmetic whose result is exact or rounded once, the
//                           same on every host and device: origin + q·2^e (the product is exact),
//                           so the walk decodes the very planes checked here. A ray that enters
//                           a child's box enters its decoded box, so a walk over these nodes
//                           tests a superset of the triangles and returns the same closest hit
//                           (the tie rule does not depend on the visiting order) and the same
//                           any-hit answer. Leaves of more than 255 blocks cannot be
//                           quantized (std::nullopt).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "raykit/bvh/wide.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/scene/block_bvh.hpp"

namespace raykit::cl {

/// A tree in the device's form: nodes (node 0 the root box alone) and the leaves' blocks.
struct DeviceTree {
    std::vector<DeviceNode> nodes;
    std::vector<TriangleBlock4> blocks;
};

/// The device form of `b` (see the header comment); empty for an empty tree.
inline DeviceTree device_tree(const BlockBvhT<kDeviceWidth>& b) {
    DeviceTree out;
    if (b.tree.nodes.empty()) return out;
    out.blocks.assign(b.blocks.begin(), b.blocks.end());
    out.nodes.resize(b.tree.nodes.size() + 1);
    DeviceNode& root = out.nodes[0];
    for (int c = 0; c < kDeviceWidth; ++c) root.clear(c);
    root.set_box(0, b.tree.bounds);
    root.index[0] = 1;
    root.count[0] = 0;
    for (std::size_t i = 0; i < b.tree.nodes.size(); ++i) {
        DeviceNode& n = out.nodes[i + 1];
        n = b.tree.nodes[i];
        for (int c = 0; c < kDeviceWidth; ++c)
            if (n.count[c] == 0 && !b.tree.nodes[i].unused(c)) ++n.index[c];
    }
    return out;
}

/// 2^e as a float, for the exponents quantize_node stores ([-126, 127]).
inline float quantized_step(int e) noexcept { return std::ldexp(1.0f, e); }

/// The plane a quantized byte stands for (rk_qslab's decoding): origin + q·step, one rounding.
inline float quantized_plane(float origin, std::uint8_t q, float step) noexcept {
    return origin + static_cast<float>(q) * step;  // the product is exact: fusing changes nothing
}

/// The box of slot c of a quantized node, as the device decodes it.
inline AABB quantized_box(const QuantizedNode& n, int c) noexcept {
    AABB b;
    for (int a = 0; a < 3; ++a) {
        const float step = quantized_step(n.exponent[a]);
        b.min[a] = quantized_plane(n.origin[a], n.q[2 * a][c], step);
        b.max[a] = quantized_plane(n.origin[a], n.q[2 * a + 1][c], step);
    }
    return b;
}

namespace detail {
/// A child's plane as quantize_node reads it: NaN as unbounded on its side (the slab test
/// ignores a NaN plane), then clamped to ±kQuantizeLimit (±∞ too), so every point of the child
/// within the limit stays inside (an empty child, +∞ / −∞ after a refit of NaN vertices,
/// decodes to an inverted box).
inline float quantize_input(float x, bool high) noexcept {
    constexpr float m = kQuantizeLimit;
    if (std::isnan(x)) return high ? m : -m;
    return std::clamp(x, -m, m);
}
}  // namespace detail

/// `n` with its used children's boxes rounded outward to bytes (see the header comment);
/// std::nullopt when a leaf has more than 255 blocks. The result is canonical, so the
/// device's rk_quantize_nodes (kernels/raykit/kernels/quantize.hpp) gives the same bytes: per
/// axis the origin is the children's lowest plane, the exponent the smallest from
/// frexp(extent) − 8 up at which every high plane's byte fits, a low plane's byte the largest
/// whose plane is not above it, a high plane's the smallest whose plane is not below it.
inline std::optional<QuantizedNode> quantize_node(const DeviceNode& n) {
    QuantizedNode out{};
    for (int c = 0; c < kDeviceWidth; ++c) {
        if (n.unused(c)) continue;
        if (n.count[c] > 255u) return std::nullopt;
        out.used = static_cast<std::uint8_t>(out.used | (1u << c));
        out.index[c] = n.index[c];
        out.count[c] = static_cast<std::uint8_t>(n.count[c]);
    }
    if (out.used == 0) return out;
    for (int a = 0; a < 3; ++a) {
        float clo[kDeviceWidth] = {}, chi[kDeviceWidth] = {};
        float lo = std::numeric_limits<float>::infinity(), hi = -lo;
        for (int c = 0; c < kDeviceWidth; ++c)
            if ((out.used >> c) & 1u) {
                clo[c] = detail::quantize_input(n.planes[2 * a][c], false);
                chi[c] = detail::quantize_input(n.planes[2 * a + 1][c], true);
                lo = std::min(lo, clo[c]);
                hi = std::max(hi, chi[c]);
            }
        const float extent = hi - lo;  // at most 2^127; negative when every child is empty
        int e = -126;
        if (extent > 0.0f) {
            int x = 0;
            std::frexp(extent, &x);  // extent < 2^x, so 255·2^(x−7) > extent
            e = std::max(-126, std::min(kQuantizeMaxExponent, x - 8));
        }
        for (;; ++e) {
            const float step = quantized_step(e);
            const float inv = quantized_step(-e);  // a first guess only
            bool fits = true;
            for (int c = 0; c < kDeviceWidth && fits; ++c) {
                if (!((out.used >> c) & 1u)) continue;
                int ql = static_cast<int>(std::min(255.0f, std::floor((clo[c] - lo) * inv)));
                while (ql > 0 && quantized_plane(lo, std::uint8_t(ql), step) > clo[c]) --ql;
                while (ql < 255 && quantized_plane(lo, std::uint8_t(ql + 1), step) <= clo[c]) ++ql;
                int qh = static_cast<int>(std::min(255.0f, std::max(0.0f, std::ceil((chi[c] - lo) * inv))));
                while (qh > 0 && quantized_plane(lo, std::uint8_t(qh - 1), step) >= chi[c]) --qh;
                while (qh < 255 && quantized_plane(lo, std::uint8_t(qh), step) < chi[c]) ++qh;
                if (quantized_plane(lo, std::uint8_t(qh), step) < chi[c]) {
                    fits = false;
                    break;
                }
                out.q[2 * a][c] = static_cast<std::uint8_t>(ql);
                out.q[2 * a + 1][c] = static_cast<std::uint8_t>(qh);
            }
            if (fits || e == kQuantizeMaxExponent) break;  // 255 steps there span 2^127: it always fits
        }
        out.origin[a] = lo;
        out.exponent[a] = static_cast<std::int8_t>(e);
    }
    return out;
}

/// Every node of `nodes` quantized (quantize_node), or std::nullopt when one cannot be.
inline std::optional<std::vector<QuantizedNode>> quantize_nodes(const std::vector<DeviceNode>& nodes) {
    std::vector<QuantizedNode> out;
    out.reserve(nodes.size());
    for (const DeviceNode& n : nodes) {
        std::optional<QuantizedNode> q = quantize_node(n);
        if (!q) return std::nullopt;
        out.push_back(*q);
    }
    return out;
}

}  // namespace raykit::cl
