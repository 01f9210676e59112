// raykit/scene/block_bvh.hpp — a wide BVH whose leaves are blocks of four triangles, for CPU tracing.
//
//   BlockBvh8 blocks = BlockBvh8::build(mesh);       // a tree built for blocks (fastest), or from any tree:
//   BlockBvh8 same = BlockBvh8::build(mesh, bvh);     // from any tree (or build(mesh, WideBvh8::build(bvh)))
//   Hit h = intersect_closest(blocks, ray);          // same answers as intersect_closest(mesh, bvh, ray)
//   bool occluded = intersect_any(blocks, ray);
//
// The fastest CPU path, and a trade: the WideBvh's nodes (leaf slots now
// naming a first block and a block count) plus, per leaf, its triangles'
// vertices copied into TriangleBlock4s (intersect/triangle4.hpp: 160 bytes per
// four triangles, a leaf of n triangles takes ceil(n / 4) blocks; unused lanes
// repeat the leaf's last triangle). A leaf is then tested in one 4-lane
// watertight test per block, reading contiguous memory, instead of one scalar
// test per triangle through prim_ids → triangle → three vertices.
//
// Trees built with Config::leaf.leaf_block = 4 (sah_config(), any builder's
// leaf_block) fill the blocks: their leaves hold 4-12 triangles instead of
// 1-8, so a ray visits fewer nodes and tests full blocks.
//
// Answers: the tree's boxes and leaves are the binary tree's, and each lane is
// the scalar watertight test bit for bit, with the same tie rule (equal t:
// smaller triangle index), so hits equal those of the indexed mesh + Bvh.
// Only the default (watertight) test is offered on blocks.
//
// Memory: the wide nodes, 160 bytes per block, and nothing else (no prim_ids,
// no mesh access while tracing). After vertices move, refit(mesh) rewrites the
// blocks from the mesh and the boxes bottom-up in place: the same tree, bit for
// bit, as refitting the binary tree, collapsing and making again, without the
// two allocations (bench_anim, BM_BlockRefit).
//
// Queries are closest_hit / any_hit of scene/trace.hpp over BlockLeaves: the
// one traversal of every tree shape and leaf store.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "raykit/bvh/binned_sah.hpp"
#include "raykit/bvh/refit.hpp"
#include "raykit/bvh/traverse_wide.hpp"
#include "raykit/bvh/wide.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/math/limits.hpp"
#include "raykit/scene/build.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/scene/trace.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

/// W = 2: the binary Bvh; 4, 8: a WideBvhT<W>.
template <int W>
using BlockTreeOf = std::conditional_t<W == 2, Bvh, WideBvhT<W == 2 ? 4 : W>>;

template <int W>
struct BlockBvhT {
    static constexpr int kWidth = W;
    using Tree = BlockTreeOf<W>;
    /// The tree; a leaf's index is its first block and its count the number
    /// of blocks (so its prim_ids is empty: the blocks carry the triangle
    /// indices).
    Tree tree;
    std::vector<TriangleBlock4, CacheLineAllocator<TriangleBlock4>> blocks;

    bool empty() const noexcept { return tree.nodes.empty(); }
    std::size_t memory_bytes() const noexcept {
        return tree.nodes.size() * sizeof(tree.nodes[0]) + blocks.size() * sizeof(TriangleBlock4);
    }

    /// Blocks for `src`'s leaves, vertices from `mesh` (which `src` was built
    /// over). Throws std::domain_error for a vertex beyond ±2^32 (math/limits.hpp).
    static BlockBvhT build(const MeshView& mesh, const Tree& src, unsigned threads = 0) {
        check_positions(mesh.positions, "raykit::BlockBvh::build");
        return assemble(mesh, src, threads);
    }
    /// Builds a tree for blocks over `mesh` (binned SAH, sah_config()) and makes them.
    /// (primitive_arrays has checked the range: the blocks are assembled without a second pass.)
    static BlockBvhT build(const MeshView& mesh, unsigned threads = 0) {
        const detail::PrimitiveArrays r = detail::primitive_arrays(mesh, threads);
        Bvh bvh = BinnedSahBuilder::build(r.boxes, r.centers, sah_config(threads));
        if constexpr (W == 2) return assemble(mesh, std::move(bvh), threads);
        else return assemble(mesh, WideBvhT<W>::build(std::move(bvh)), threads);
    }

    /// The leaf store the queries walk.
    BlockLeaves leaves() const noexcept { return {blocks.data()}; }

    /// After `mesh`'s vertices moved (same triangles, the mesh this was made
    /// over): rewrites every block from the mesh and every box bottom-up, in
    /// place. Equal to build(mesh, refitted source tree). No range check: the
    /// caller checks the root box (Scene::move_vertices does).
    void refit(const MeshView& mesh, unsigned threads = 0) {
        if (empty()) return;
        TriangleBlock4* RAYKIT_RESTRICT bl = blocks.data();
        for (const TriangleBlock4& b : blocks)
            for (int i = 0; i < 4; ++i)
                if (b.prim[i] >= mesh.size()) throw std::invalid_argument("BlockBvh::refit: a block names a triangle outside the mesh");
        // below ~16k triangles starting threads costs more than the pass takes
        parallel_for(
            blocks.size(), threads,
            [&](std::size_t k) {
                for (int i = 0; i < 4; ++i) {
                    const std::uint32_t p = bl[k].prim[i];
                    bl[k].set(i, mesh.vertex(p, 0), mesh.vertex(p, 1), mesh.vertex(p, 2), p);
                }
            },
            4096);
        const auto leaf_box = [&](std::uint32_t first, std::uint32_t count) {
            AABB b;  // lanes past a leaf's size repeat its last triangle: the union is the leaf's
            for (std::uint32_t k = first; k < first + count; ++k)
                for (int i = 0; i < 4; ++i) b.grow(mesh.bounds(bl[k].prim[i]));
            return b;
        };
        if constexpr (W == 2) {
            for (std::size_t i = tree.nodes.size(); i-- > 0;) {
                Node& n = tree.nodes[i];
                n.box = n.is_leaf() ? leaf_box(n.index, n.count)
                                    : merge(tree.nodes[n.index].box, tree.nodes[n.index + 1].box);
            }
        } else {
            tree.bounds = detail::refit_wide_nodes(tree.nodes, leaf_box);
        }
    }

  private:
    /// build(mesh, tree) without the range check (the nodes moved from a tree the build made).
    template <class T>
    static BlockBvhT assemble(const MeshView& mesh, T&& src, unsigned threads) {
        BlockBvhT b;
        b.tree.nodes = std::forward<T>(src).nodes;
        if constexpr (W != 2) b.tree.bounds = src.bounds;
        // first pass: number the blocks leaf by leaf, in node order
        struct Leaf {
            std::uint32_t first_slot, count, first_block;
        };
        std::vector<Leaf> leaves;
        std::uint32_t nblocks = 0;
        const auto renumber = [&](std::uint32_t& index, std::uint32_t& count) {
            if (std::size_t(index) + count > src.prim_ids.size())
                throw std::invalid_argument("BlockBvh::make: leaf range outside prim_ids");
            const std::uint32_t nb = (count + 3) / 4;
            leaves.push_back({index, count, nblocks});
            index = nblocks;
            count = nb;
            nblocks += nb;
        };
        for (auto& n : b.tree.nodes) {
            if constexpr (W == 2) {
                if (n.count != 0) renumber(n.index, n.count);
            } else {
                for (int c = 0; c < W; ++c)
                    if (n.count[c] != 0) renumber(n.index[c], n.count[c]);
            }
        }
        for (const std::uint32_t p : src.prim_ids)
            if (p >= mesh.size()) throw std::invalid_argument("BlockBvh::make: prim id outside the mesh");
        b.blocks.resize(nblocks);
        parallel_for(leaves.size(), threads, [&](std::size_t i) {
            const Leaf& l = leaves[i];
            for (std::uint32_t k = 0; k < (l.count + 3) / 4 * 4; ++k) {
                const std::uint32_t slot = l.first_slot + (k < l.count ? k : l.count - 1);
                const std::uint32_t p = src.prim_ids[slot];
                b.blocks[l.first_block + k / 4].set(int(k % 4), mesh.vertex(p, 0), mesh.vertex(p, 1), mesh.vertex(p, 2),
                                                    p);
            }
        });
        return b;
    }

  public:
    /// Builder settings for trees traced through blocks: the SAH counts leaf
    /// cost in blocks of 4 (Config::leaf.leaf_block) and leaves hold up to 3 blocks.
    /// On the bunny and the generated tori this takes random rays from
    /// 0.4-0.5x to 0.7-0.85x Embree's speed (README, bench_trace).
    static BinnedSahBuilder::Config sah_config(unsigned threads = 0) {
        BinnedSahBuilder::Config c;
        c.leaf.leaf_block = 4;
        c.leaf.max_leaf_size = 12;
        c.threads = threads;
        return c;
    }
    /// Collapses `bvh` to W wide and makes the blocks.
    static BlockBvhT build(const MeshView& mesh, const Bvh& bvh, unsigned threads = 0)
        requires(W != 2)
    {
        return build(mesh, WideBvhT<W>::build(bvh), threads);
    }
    /// The name build(mesh, tree) had before 0.2 (every raykit tree is now made by a `build`).
    [[deprecated("raykit: use BlockBvhT::build(mesh, tree)")]] static BlockBvhT make(const MeshView& mesh, const Tree& src,
                                                                                    unsigned threads = 0) {
        return build(mesh, src, threads);
    }
    [[deprecated("raykit: use BlockBvhT::build(mesh, bvh)")]] static BlockBvhT make(const MeshView& mesh, const Bvh& bvh,
                                                                                   unsigned threads = 0)
        requires(W != 2)
    {
        return build(mesh, bvh, threads);
    }
};

using BlockBvh2 = BlockBvhT<2>;  ///< binary nodes, 4-triangle blocks
using BlockBvh = BlockBvhT<4>;   ///< 4-wide nodes, 4-triangle blocks
using BlockBvh8 = BlockBvhT<8>;  ///< 8-wide nodes, 4-triangle blocks

/// Closest hit: the same answer as intersect_closest(mesh, bvh, ray) on the
/// tree `b` was made from (watertight test, ties to the smaller index).
template <int W, class Stats = std::nullptr_t, class Keep = AcceptAll>
Hit intersect_closest(const BlockBvhT<W>& b, const Ray& ray, Stats stats = nullptr, const Keep& keep = {}) {
    return closest_hit(b.tree, b.leaves(), ray, keep, stats);
}

/// Any hit within [ray.tmin, ray.tmax].
template <int W, class Stats = std::nullptr_t, class Keep = AcceptAll>
bool intersect_any(const BlockBvhT<W>& b, const Ray& ray, Stats stats = nullptr, const Keep& keep = {}) {
    return any_hit(b.tree, b.leaves(), ray, keep, stats);
}

namespace detail {
/// fn(first, n) for the packets of a batch of `size` rays (kPacketWidth at a time), spread
/// over `threads` (0: all cores) when the batch is large enough to pay for them.
template <class Fn>
void for_each_packet(std::size_t size, unsigned threads, Fn&& fn) {
    const std::size_t packets = (size + kPacketWidth - 1) / kPacketWidth;
    parallel_for(
        packets, threads,
        [&](std::size_t i) {
            const std::size_t first = i * kPacketWidth;
            fn(first, static_cast<unsigned>(std::min<std::size_t>(kPacketWidth, size - first)));
        },
        256);
}
inline void check_batch(std::size_t rays, std::size_t results, const char* what) {
    if (results < rays)
        throw std::invalid_argument(std::string("raykit::") + what + ": fewer results than rays (" +
                                    std::to_string(results) + " < " + std::to_string(rays) + ")");
}
}  // namespace detail

/// Closest hits of a batch: hits[i] is intersect_closest(b, rays[i]) bit for bit. Rays go
/// kPacketWidth at a time through one packet walk (bvh/traverse_packet.hpp: coherent rays,
/// such as a camera's tiles, share node fetches and box tests), packets spread over `threads`
/// (0: all cores). Throws std::invalid_argument when hits is shorter than rays.
template <int W, class Keep = AcceptAll>
void intersect_closest(const BlockBvhT<W>& b, std::span<const Ray> rays, std::span<Hit> hits, unsigned threads = 0,
                       const Keep& keep = {}) {
    detail::check_batch(rays.size(), hits.size(), "intersect_closest");
    detail::for_each_packet(rays.size(), threads, [&](std::size_t first, unsigned n) {
        closest_hit_packet(b.tree, b.leaves(), rays.data() + first, nullptr, n, hits.data() + first, keep);
    });
}

/// Any hits of a batch: occluded[i] is intersect_any(b, rays[i]) (1 or 0), as packets.
template <int W, class Keep = AcceptAll>
void intersect_any(const BlockBvhT<W>& b, std::span<const Ray> rays, std::span<std::uint8_t> occluded,
                   unsigned threads = 0, const Keep& keep = {}) {
    detail::check_batch(rays.size(), occluded.size(), "intersect_any");
    detail::for_each_packet(rays.size(), threads, [&](std::size_t first, unsigned n) {
        const unsigned m = any_hit_packet(b.tree, b.leaves(), rays.data() + first, n, keep);
        for (unsigned k = 0; k < n; ++k) occluded[first + k] = std::uint8_t((m >> k) & 1u);
    });
}

}  // namespace raykit
