// raykit/cl/device_build.hpp — building an object's tree on the device (PLOC), no read-back.
//
//   DeviceBuilder builder(dev);                        // its own program, or share one that holds build_part()
//   DeviceBuildResult r = builder.build(triangles, positions, record, object, target);
//   if (!r.built) ...                                  // too deep for the device walk: build on the CPU
//
// The device makes, from the object's current vertices, the very tree the CPU makes with
// cpu_twin_build(): PlocBuilder (bvh/ploc.hpp, radius and leaf cost of DeviceBuildConfig, no
// post-pass) collapsed by BlockBvh8::build and put in the device's form by device_tree() —
// the same wide nodes, slot boxes and triangle blocks bit for bit; only the numbering of
// wide nodes and blocks differs (descending merge id and left-to-right leaf order here, the
// CPU's stack order there). The stages are in kernels/raykit/kernels/build.hpp.
//
// The nodes and blocks go straight into the scene's arrays at the object's offsets, with the
// refit tables of the new topology (RefitPlan's parents, needs and one-pass starts), so the
// next refit and trace use the new tree and nothing crosses back. The host only reads small
// counters: the cluster count every few rounds of PLOC (to know when it is done), and at the
// end the height, node and block counts (32 bytes).
//
// Space: the object's regions hold any tree over its triangles (n + 1 nodes, n blocks), see
// node_capacity() / block_capacity(). When the merge tree would be deeper than
// RAYKIT_BVH_MAX_DEPTH (the CPU's back end then rebuilds the deep part with median splits,
// bvh/bottom_up.hpp) or PLOC takes more than kMaxRounds rounds (chains of coincident
// primitives, which the CPU finishes incrementally), build() returns built = false and
// writes nothing: the caller builds that one on the CPU (DeviceScene does).
#pragma once

#include <bit>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "raykit/bvh/ploc.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/device_tree.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/cl/refit.hpp"
#include "raykit/kernels/build.hpp"
#include "raykit/scene/block_bvh.hpp"
#include "raykit/scene/build.hpp"

namespace raykit::cl {

/// What the device builder builds: PLOC with this radius, leaves by this cost.
struct DeviceBuildConfig {
    unsigned radius = 4;                       ///< PlocBuilder::Config::radius (1..1024)
    LeafCost leaf = BlockBvh8::sah_config().leaf;  ///< blocks of 4, leaves up to 12 triangles
};

/// The CPU twin of a device build: the tree DeviceBuilder::build makes, made on the CPU.
inline BlockBvh8 cpu_twin_build(const MeshView& mesh, const DeviceBuildConfig& cfg = {}, unsigned threads = 0) {
    PlocBuilder::Config c;
    c.radius = cfg.radius;
    c.leaf = cfg.leaf;
    c.optimize = OptimizeConfig::off();
    c.threads = threads;
    return BlockBvh8::build(mesh, build_bvh<PlocBuilder>(mesh, c), threads);
}

/// Program part with the build kernels (needs refit_part() before it, for the box helpers).
inline SourcePart build_part() {
    return {"raykit/kernels/build.hpp", std::string("#define RK_BUILD_GROUP 256\n#define RK_SORT_LOCAL 512\n"
                                                    "#define RK_SCAN_GROUP 64\n#define RK_SCAN_BLOCK 1024\n") +
                                            kernels::kBuild};
}

/// Where a build writes: the scene's node and block arrays and the refit tables, at the
/// object's offsets (ObjectRecord).
struct DeviceBuildTarget {
    Buffer<DeviceNode>* nodes;
    Buffer<TriangleBlock4>* blocks;
    RefitTables tables;
};

/// What one build did.
struct DeviceBuildResult {
    bool built = false;        ///< false: nothing written, build this one on the CPU (see the header comment)
    std::uint32_t nodes = 0;   ///< wide nodes written (node 0, the root box, included)
    std::uint32_t blocks = 0;  ///< triangle blocks written
    std::uint32_t rounds = 0;  ///< PLOC rounds
    std::uint32_t height = 0;  ///< height of the merge tree
};

class DeviceBuilder {
public:
    /// PLOC rounds after which the build gives up (built = false); measured: 36 on the
    /// Stanford bunny, 51 on the thesis scene.
    static constexpr std::uint32_t kMaxRounds = 256;

    /// Nodes and blocks an object of n triangles may need (its regions in the scene's arrays).
    static std::size_t node_capacity(std::size_t n) noexcept { return n == 0 ? 0 : n + 1; }
    static std::size_t block_capacity(std::size_t n) noexcept { return n; }

    DeviceBuilder() = default;
    /// A builder with its own program.
    explicit DeviceBuilder(Device& dev, const DeviceBuildConfig& cfg = {})
        : DeviceBuilder(dev, build_program(dev, assemble(parts()), raykit_build_options(dev)), cfg) {}
    /// A builder on a program that holds parts() (e.g. a scene's).
    DeviceBuilder(Device& dev, const Program& p, const DeviceBuildConfig& cfg = {}) : dev_(&dev), cfg_(cfg) {
        if (!dev.info().fp64)
            throw std::invalid_argument("raykit::cl::DeviceBuilder: the device has no cl_khr_fp64 (the builder's areas "
                                        "are computed in double to match the CPU bit for bit)");
        if (cfg.radius < 1 || cfg.radius > 1024) throw std::invalid_argument("raykit::cl::DeviceBuilder: radius must be in [1, 1024]");
        check_leaf_block(cfg.leaf.leaf_block, "raykit::cl::DeviceBuilder");
        if (cfg.leaf.leaf_block != 4) throw std::invalid_argument("raykit::cl::DeviceBuilder: leaves are blocks of 4 (leaf_block 4)");
        const char* names[] = {"rk_build_refs", "rk_build_bounds", "rk_build_morton", "rk_sort_local", "rk_sort_global",
                               "rk_ploc_init",  "rk_ploc_nn",      "rk_ploc_flags",   "rk_scan_blocks", "rk_scan_sums",
                               "rk_scan_add",   "rk_ploc_merge",   "rk_ploc_advance", "rk_tree_parents", "rk_tree_up",
                               "rk_tree_slots", "rk_tree_blocks",  "rk_tree_roots",   "rk_tree_wide"};
        for (std::size_t i = 0; i < kKernels; ++i) k_[i] = p.kernel(names[i]);
        state_ = Buffer<std::uint32_t>(dev, 8);
        fstate_ = Buffer<float>(dev, 8);
        total_ = Buffer<cl_uint2>(dev, 1);
    }

    /// Program parts a builder's program needs.
    static std::vector<SourcePart> parts() {
        std::vector<SourcePart> p = base_parts();
        p.push_back(refit_part());
        p.push_back(build_part());
        return p;
    }

    const DeviceBuildConfig& config() const noexcept { return cfg_; }
    /// Kernel launches so far.
    std::size_t launches() const noexcept { return launches_; }

    /// Builds object `object`'s tree from `positions` (see the header comment).
    DeviceBuildResult build(const Buffer<Triangle>& triangles, const Buffer<float>& positions, const ObjectRecord& rec,
                            std::uint32_t object, const DeviceBuildTarget& out) {
        DeviceBuildResult res;
        const std::uint32_t n = rec.triangle_count;
        if (n == 0) {
            res.built = true;
            return res;
        }
        if (n >= 0x7FFFFFFFu) throw std::length_error("raykit::cl::DeviceBuilder: too many triangles");
        reserve(n);
        const std::uint32_t padded = std::max<std::uint32_t>(std::bit_ceil(n), kSortLocal);
        go(k(Refs), n, triangles, positions, rec.triangle_offset, rec.vertex_offset, n, rbox_, cen_);
        set_args(k(Bounds), cen_, n, fstate_, state_);
        launch_n(k(Bounds), kBoundsGroup, kBoundsGroup);
        go(k(Morton), padded, cen_, fstate_, n, padded, keys_, ids_);
        sort(padded);
        go(k(Init), n, ids_, rbox_, cen_, fstate_, n, cl_[0], cnode_[0]);
        std::uint32_t st[8] = {};
        int cur = 0;
        if (n > 1) {
            for (;;) {
                for (int r = 0; r < kRoundsPerRead; ++r, cur ^= 1) round(n, cur);
                state_.read(*dev_, std::span<std::uint32_t>(st, 8));
                if (st[0] <= 1) break;
                if (st[2] > kMaxRounds) {
                    res.rounds = st[2];
                    return res;
                }
            }
            go(k(Parents), n - 1, kids_, n, parent_);
            go(k(Up), n, kids_, parent_, counters_, rbox_, ibox_, icnt_, n, cfg_.leaf.traversal_cost,
               cfg_.leaf.intersection_cost, cfg_.leaf.leaf_limit(), std::uint32_t(std::countr_zero(cfg_.leaf.leaf_block)),
               state_);
            state_.read(*dev_, std::span<std::uint32_t>(st, 8));
            res.rounds = st[2];
            res.height = st[5];
            if (st[5] > std::uint32_t(RAYKIT_BVH_MAX_DEPTH)) return res;
        } else {
            const std::uint32_t none = kInvalidIndex;
            parent_.write(*dev_, std::span<const std::uint32_t>(&none, 1));
        }
        go(k(Slots), n, kids_, parent_, icnt_, n, prims_, leaf_of_, bflag_, first_);
        scan(bflag_, bpos_, n);
        const std::uint32_t cap = static_cast<std::uint32_t>(node_capacity(n) - 1);
        go(k(Blocks), n, prims_, leaf_of_, bflag_, bpos_, n, triangles, positions, rec.triangle_offset, rec.vertex_offset,
           *out.blocks, rec.block_offset, state_);
        if (n > 1) {
            go(k(Roots), n - 1, kids_, parent_, rbox_, ibox_, icnt_, n, wflag_);
            scan(wflag_, wpos_, n - 1);
        }
        go(k(Wide), cap, kids_, rbox_, ibox_, icnt_, first_, wflag_, wpos_, bpos_, n, cap, rec.node_offset, object,
           *out.nodes, *out.tables.parents, *out.tables.needs, *out.tables.starts, state_);
        state_.read(*dev_, std::span<std::uint32_t>(st, 8));
        res.built = true;
        res.nodes = st[3];
        res.blocks = st[4];
        return res;
    }

private:
    enum Kernel {
        Refs, Bounds, Morton, SortLocal, SortGlobal, Init, Nn, Flags, ScanBlocks, ScanSums, ScanAdd, Merge, Advance,
        Parents, Up, Slots, Blocks, Roots, Wide, kKernels
    };
    static constexpr std::size_t kBoundsGroup = 256, kSortLocal = 512, kScanGroup = 64, kScanBlock = 1024;
    static constexpr int kRoundsPerRead = 2;
    static constexpr std::size_t kGroup = 64;

    ::cl::Kernel& k(Kernel i) noexcept { return k_[i]; }
    void launch_n(::cl::Kernel& kk, std::size_t global, std::size_t local) {
        launches_ += launch(dev_->queue(), kk, global, local);
    }
    template <class... Args>
    void go(::cl::Kernel& kk, std::size_t items, const Args&... args) {
        set_args(kk, args...);
        launch_n(kk, items, kGroup);
    }

    void reserve(std::uint32_t n) {
        if (n <= cap_) return;
        Device& d = *dev_;
        const std::size_t m = n, inner = n > 1 ? n - 1 : 1, padded = std::max<std::size_t>(std::bit_ceil(m), kSortLocal);
        rbox_.allocate(d, 6 * m);
        cen_.allocate(d, 3 * m);
        keys_.allocate(d, padded);
        ids_.allocate(d, padded);
        for (int i = 0; i < 2; ++i) {
            cl_[i].allocate(d, 6 * m);
            cnode_[i].allocate(d, m);
        }
        nn_.allocate(d, m);
        flags_.allocate(d, m);
        pos_.allocate(d, m);
        sums_.allocate(d, (m + kScanBlock - 1) / kScanBlock);
        kids_.allocate(d, inner);
        parent_.allocate(d, 2 * m);
        counters_ = Buffer<std::uint32_t>(d, std::vector<std::uint32_t>(inner, 0u));
        ibox_.allocate(d, 6 * inner);
        icnt_.allocate(d, 4 * inner);
        prims_.allocate(d, m);
        leaf_of_.allocate(d, m);
        bflag_.allocate(d, m);
        bpos_.allocate(d, m);
        first_.allocate(d, 2 * m);
        wflag_.allocate(d, inner);
        wpos_.allocate(d, inner);
        cap_ = n;
    }

    /// Bitonic sort of (key, index) over `padded` entries (a power of two, at least kSortLocal).
    void sort(std::uint32_t padded) {
        set_args(k(SortLocal), keys_, ids_, std::uint32_t(0));
        launch_n(k(SortLocal), padded / 2, kSortLocal / 2);
        for (std::uint32_t kk = 2 * kSortLocal; kk <= padded; kk <<= 1) {
            for (std::uint32_t j = kk / 2; j >= kSortLocal; j >>= 1) {
                set_args(k(SortGlobal), keys_, ids_, kk, j);
                launch_n(k(SortGlobal), padded / 2, kGroup);
            }
            set_args(k(SortLocal), keys_, ids_, kk);
            launch_n(k(SortLocal), padded / 2, kSortLocal / 2);
        }
    }

    /// Exclusive sums of `in`'s first `count` entries into `out`; the total into total_.
    void scan(const Buffer<cl_uint2>& in, Buffer<cl_uint2>& out, std::uint32_t count) {
        const std::uint32_t blocks = static_cast<std::uint32_t>((count + kScanBlock - 1) / kScanBlock);
        set_args(k(ScanBlocks), in, out, sums_, count);
        launch_n(k(ScanBlocks), std::size_t(blocks) * kScanGroup, kScanGroup);
        set_args(k(ScanSums), sums_, blocks, total_);
        launch_n(k(ScanSums), 1, 1);
        go(k(ScanAdd), count, out, sums_, count);
    }

    /// One PLOC round from cluster set `cur` into the other.
    void round(std::uint32_t n, int cur) {
        go(k(Nn), n, cl_[cur], n, state_, std::uint32_t(cfg_.radius), nn_);
        go(k(Flags), n, nn_, state_, n, flags_);
        scan(flags_, pos_, n);
        go(k(Merge), n, cl_[cur], cnode_[cur], cl_[cur ^ 1], cnode_[cur ^ 1], n, nn_, pos_, state_, n, kids_);
        set_args(k(Advance), state_, total_);
        launch_n(k(Advance), 1, 1);
    }

    Device* dev_ = nullptr;
    DeviceBuildConfig cfg_;
    ::cl::Kernel k_[kKernels];
    std::size_t launches_ = 0;
    std::uint32_t cap_ = 0;
    Buffer<std::uint32_t> state_;
    Buffer<float> fstate_;
    Buffer<cl_uint2> total_;
    Buffer<float> rbox_, cen_, cl_[2], ibox_;
    Buffer<cl_ulong> keys_;
    Buffer<std::uint32_t> ids_, cnode_[2], nn_, parent_, counters_, icnt_, prims_, first_;
    Buffer<cl_uint2> flags_, pos_, sums_, kids_, leaf_of_, bflag_, bpos_, wflag_, wpos_;
};

}  // namespace raykit::cl
