// raykit/cl/device_build.hpp — building an object's tree on the device (PLOC or sort by axis),
// no read-back.
//
//   DeviceBuilder builder(dev, cfg);                   // its own program, or share one that holds parts(method)
//   DeviceBuildResult r = builder.build(triangles, positions, record, object, target);
//   if (!r.built) ...                                  // too deep or too many rounds: build on the CPU
//
// The device makes, from the object's current vertices, the very tree the CPU makes with
// cpu_twin_build(): PlocBuilder (radius of DeviceBuildConfig, no post-pass) or SortAxisBuilder
// (its default: Morton axis, area metric, mutual pairing, window of DeviceBuildConfig), with
// the leaf cost of DeviceBuildConfig, collapsed by BlockBvh8::build and put in the device's
// form by device_tree() — the same wide nodes, slot boxes and triangle blocks bit for bit; only
// the numbering of wide nodes and blocks differs (descending merge id and left-to-right leaf
// order here, the CPU's stack order there). The stages are in kernels/raykit/kernels/build.hpp
// (shared, back end), build_ploc.hpp and build_sortaxis.hpp (the builders; a program holds the
// one it uses).
//
// The nodes and blocks go straight into the scene's arrays at the object's offsets, with the
// refit tables of the new topology (RefitPlan's parents, needs and one-pass starts), so the
// next refit and trace use the new tree and nothing crosses back. The host only reads small
// counters: the element count after each round or level (to size the next and know when it is
// done), the number of nodes on each wide level, and at the end the height, node and block
// counts (32 bytes).
//
// Space: the object's regions hold any tree over its triangles (n + 1 nodes, n blocks), see
// node_capacity() / block_capacity(). When the merge tree would be deeper than
// RAYKIT_BVH_MAX_DEPTH (the CPU's back end then rebuilds the deep part with median splits,
// bvh/bottom_up.hpp) or the builder takes more than kMaxRounds rounds or levels (PLOC on
// chains of coincident primitives, which the CPU finishes incrementally), build() returns
// built = false and writes nothing: the caller builds that one on the CPU (DeviceScene does).
#pragma once

#include <bit>
#include <iterator>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "raykit/bvh/ploc.hpp"
#include "raykit/bvh/sortaxis.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/device_tree.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/cl/refit.hpp"
#include "raykit/kernels/build.hpp"
#include "raykit/kernels/build_ploc.hpp"
#include "raykit/kernels/build_sortaxis.hpp"
#include "raykit/scene/block_bvh.hpp"
#include "raykit/scene/build.hpp"

namespace raykit::cl {

/// The device's builders: the twins of PlocBuilder and SortAxisBuilder.
enum class DeviceBuildMethod { ploc, sortaxis };

/// What the device builder builds: PLOC with this radius, or sort-by-axis (SortAxisBuilder's
/// default: Morton axis, area metric, mutual pairing) with this window; leaves by this cost.
struct DeviceBuildConfig {
    DeviceBuildMethod method = DeviceBuildMethod::ploc;
    unsigned radius = 4;                           ///< PlocBuilder::Config::radius (1..1024)
    unsigned window = 2;                           ///< SortAxisBuilder::Config::window (1..kMaxWindow)
    LeafCost leaf = BlockBvh8::sah_config().leaf;  ///< blocks of 4, leaves up to 12 triangles
    static constexpr unsigned kMaxWindow = 16;     ///< the device's greedy fallback keeps W + 1 in registers
};

/// The CPU twin of a device build: the tree DeviceBuilder::build makes, made on the CPU.
inline BlockBvh8 cpu_twin_build(const MeshView& mesh, const DeviceBuildConfig& cfg = {}, unsigned threads = 0) {
    if (cfg.method == DeviceBuildMethod::sortaxis) {
        SortAxisBuilder::Config c;
        c.window = cfg.window;
        c.leaf = cfg.leaf;
        c.threads = threads;
        return BlockBvh8::build(mesh, build_bvh<SortAxisBuilder>(mesh, c), threads);
    }
    PlocBuilder::Config c;
    c.radius = cfg.radius;
    c.leaf = cfg.leaf;
    c.optimize = OptimizeConfig::off();
    c.threads = threads;
    return BlockBvh8::build(mesh, build_bvh<PlocBuilder>(mesh, c), threads);
}

/// Program parts with the build kernels of `method`: the shared stages and back end, then the
/// builder's (a program holds only the builder it uses). They need refit_part() before them,
/// for the box helpers.
inline std::vector<SourcePart> build_parts(DeviceBuildMethod method) {
    std::vector<SourcePart> p;
    p.push_back({"raykit/kernels/build.hpp",
                 "#define RK_BUILD_GROUP 256\n#define RK_RADIX_BLOCK 512\n#define RK_SCAN_GROUP 64\n"
                 "#define RK_SCAN_BLOCK 1024\n" +
                     std::string(kernels::kBuild)});
    if (method == DeviceBuildMethod::ploc) {
        p.push_back({"raykit/kernels/build_ploc.hpp", kernels::kBuildPloc});
    } else {
        p.push_back({"raykit/kernels/build_sortaxis.hpp",
                     "#define RK_SA_CHUNK " + std::to_string(SortAxisBuilder::kChunk) + "u\n#define RK_SA_GREEDY_MIN " +
                         std::to_string(SortAxisBuilder::kGreedyFallbackMin) + "u\n#define RK_SA_MUTUAL_SHARE " +
                         std::to_string(SortAxisBuilder::kMinMutualShare) + "u\n#define RK_SA_MAX_WINDOW " +
                         std::to_string(DeviceBuildConfig::kMaxWindow) + "u\n" + kernels::kBuildSortAxis});
    }
    return p;
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
    std::uint32_t rounds = 0;  ///< PLOC rounds or sort-by-axis levels
    std::uint32_t height = 0;  ///< height of the merge tree
};

class DeviceBuilder {
public:
    /// Rounds (PLOC) or levels (sort by axis) after which the build gives up (built = false);
    /// measured: 36 / 31 on the Stanford bunny, 51 / 45 on the thesis scene.
    static constexpr std::uint32_t kMaxRounds = 256;

    /// Nodes and blocks an object of n triangles may need (its regions in the scene's arrays).
    static std::size_t node_capacity(std::size_t n) noexcept { return n == 0 ? 0 : n + 1; }
    static std::size_t block_capacity(std::size_t n) noexcept { return n; }

    DeviceBuilder() = default;
    /// A builder with its own program.
    explicit DeviceBuilder(Device& dev, const DeviceBuildConfig& cfg = {})
        : DeviceBuilder(dev, build_program(dev, assemble(parts(cfg.method)), raykit_build_options(dev)), cfg) {}
    /// A builder on a program that holds parts(cfg.method) (e.g. a scene's).
    DeviceBuilder(Device& dev, const Program& p, const DeviceBuildConfig& cfg = {}) : dev_(&dev), cfg_(cfg) {
        if (!dev.info().fp64)
            throw std::invalid_argument("raykit::cl::DeviceBuilder: the device has no cl_khr_fp64 (the builder's areas "
                                        "are computed in double to match the CPU bit for bit)");
        if (cfg.radius < 1 || cfg.radius > 1024) throw std::invalid_argument("raykit::cl::DeviceBuilder: radius must be in [1, 1024]");
        if (cfg.window < 1 || cfg.window > DeviceBuildConfig::kMaxWindow)
            throw std::invalid_argument("raykit::cl::DeviceBuilder: window must be in [1, " +
                                        std::to_string(DeviceBuildConfig::kMaxWindow) + "]");
        check_leaf_block(cfg.leaf.leaf_block, "raykit::cl::DeviceBuilder");
        if (cfg.leaf.leaf_block != 4) throw std::invalid_argument("raykit::cl::DeviceBuilder: leaves are blocks of 4 (leaf_block 4)");
        // in Kernel order; the other builder's kernels are not in the program
        const char* names[] = {"rk_build_refs", "rk_build_bounds", "rk_build_morton", "rk_radix_count", "rk_radix_scatter",
                               "rk_ploc_init", "rk_ploc_nn", "rk_ploc_count", "rk_ploc_sums", "rk_scan_blocks",
                               "rk_scan_sums", "rk_scan_add", "rk_scan_one_group", "rk_ploc_merge", "rk_tree_parents",
                               "rk_tree_up", "rk_tree_top", "rk_tree_down", "rk_tree_slots", "rk_tree_blocks",
                               "rk_tree_roots_init", "rk_tree_roots", "rk_tree_wide", "rk_sa_init", "rk_sa_keys",
                               "rk_sa_gather", "rk_sa_nearest", "rk_sa_count", "rk_sa_plan", "rk_sa_pair"};
        static_assert(std::size(names) == kKernels);
        const bool ploc = cfg.method == DeviceBuildMethod::ploc;
        for (std::size_t i = 0; i < kKernels; ++i) {
            const std::string name = names[i];
            const bool ploc_only = name == "rk_build_morton" || name.rfind("rk_ploc_", 0) == 0;
            const bool sortaxis_only = name.rfind("rk_sa_", 0) == 0;
            if ((ploc_only && !ploc) || (sortaxis_only && ploc)) continue;
            k_[i] = p.kernel(name);
        }
        state_ = Buffer<std::uint32_t>(dev, 8);
        level_counts_ = Buffer<std::uint32_t>(dev, RAYKIT_BVH_MAX_DEPTH + 2);
        fstate_ = Buffer<float>(dev, 8);
        total_ = Buffer<cl_uint2>(dev, 1);
    }

    /// Program parts a builder's program needs.
    static std::vector<SourcePart> parts(DeviceBuildMethod method) {
        std::vector<SourcePart> p = base_parts();
        p.push_back(refit_part());
        for (SourcePart& b : build_parts(method)) p.push_back(std::move(b));
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
        go(k(Refs), n, triangles, positions, rec.triangle_offset, rec.vertex_offset, n, rbox_, cen_);
        set_args(k(Bounds), cen_, n, fstate_, state_);
        launch_n(k(Bounds), kBoundsGroup, kBoundsGroup);
        const bool sortaxis = cfg_.method == DeviceBuildMethod::sortaxis;
        if (sortaxis) {
            go(k(SaInit), n, rbox_, cen_, fstate_, n, cl_[0], cnode_[0], ekey_[0]);
        } else {
            go(k(Morton), n, cen_, fstate_, n, keys_[0], ids_[0]);
            sort(n, 8);
            go(k(Init), n, ids_[0], rbox_, cen_, fstate_, n, cl_[0], cnode_[0]);
        }
        std::uint32_t st[8] = {};
        int cur = 0;
        bases_.assign(1, 0u);  // one triangle: no round, no rk_tree_down
        if (n > 1) {
            // one round (PLOC) or level (sort by axis) per launch set, sized by the element
            // count read after the previous one
            for (std::uint32_t m = n; m > 1; cur ^= 1) {
                if (sortaxis) level(m, n, cur);
                else round(m, n, cur);
                state_.read(*dev_, std::span<std::uint32_t>(st, 8));
                m = st[0];
                bases_.push_back(st[1]);
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
        go(k(Top), 1, icnt_, n, first_, leaf_);
        for (std::size_t r = bases_.size(); r-- > 1;)
            go(k(Down), bases_[r] - bases_[r - 1], kids_, icnt_, n, bases_[r - 1], bases_[r], first_, leaf_);
        go(k(Slots), n, first_, leaf_, n, prims_, leaf_of_, bflag_);
        scan(bflag_, bpos_, n);
        const std::uint32_t cap = static_cast<std::uint32_t>(node_capacity(n) - 1);
        go(k(Blocks), n, prims_, leaf_of_, bflag_, bpos_, n, triangles, positions, rec.triangle_offset, rec.vertex_offset,
           *out.blocks, rec.block_offset, state_);
        if (n > 1) {
            go(k(RootsInit), n - 1, icnt_, n, wflag_, list_[0], level_counts_);
            std::uint32_t counts[RAYKIT_BVH_MAX_DEPTH + 2] = {};
            for (std::uint32_t level = 0; level + 1 < std::size(counts); ++level) {  // a wide level is a binary one at least
                level_counts_.read(*dev_, std::span<std::uint32_t>(counts + level, 1), level);
                if (counts[level] == 0) break;
                go(k(Roots), counts[level], kids_, rbox_, ibox_, icnt_, n, list_[level & 1], list_[(level & 1) ^ 1],
                   level_counts_, level, wflag_);
            }
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
        Refs, Bounds, Morton, RadixCount, RadixScatter, Init, Nn, Count, Sums, ScanBlocks, ScanSums, ScanAdd, ScanOne, Merge,
        Parents, Up, Top, Down, Slots, Blocks, RootsInit, Roots, Wide, SaInit, SaKeys, SaGather, SaNearest, SaCount, SaPlan, SaPair, kKernels
    };
    static constexpr std::size_t kBoundsGroup = 256, kRadixBlock = 512, kScanGroup = 64, kScanBlock = 1024;
    /// Scans up to this long run in one launch (rk_scan_one_group); longer ones in three.
    static constexpr std::uint32_t kOneGroupScan = 1u << 16;
    static constexpr std::size_t kGroup = 256;

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
        const std::size_t m = n, inner = n > 1 ? n - 1 : 1, digits = 256 * radix_blocks(n);
        rbox_.allocate(d, 6 * m);
        cen_.allocate(d, 3 * m);
        for (int i = 0; i < 2; ++i) {
            keys_[i].allocate(d, m);
            ids_[i].allocate(d, m);
        }
        digits_.allocate(d, digits);
        digit_pos_.allocate(d, digits);
        for (int i = 0; i < 2; ++i) {
            cl_[i].allocate(d, 6 * m);
            cnode_[i].allocate(d, m);
            ekey_[i].allocate(d, m);
        }
        srt_.allocate(d, 6 * m);
        snode_.allocate(d, m);
        chunk_.allocate(d, m / SortAxisBuilder::kChunk + 1);
        nn_.allocate(d, m);
        pos_.allocate(d, m);
        sums_.allocate(d, (std::max(m, digits) + kScanBlock - 1) / kScanBlock);
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
        leaf_.allocate(d, 2 * m);
        wflag_.allocate(d, inner);
        list_[0].allocate(d, inner);
        list_[1].allocate(d, inner);
        wpos_.allocate(d, inner);
        cap_ = n;
    }

    static std::uint32_t radix_blocks(std::uint32_t n) { return static_cast<std::uint32_t>((n + kRadixBlock - 1) / kRadixBlock); }

    /// Radix sort of (key, index), `passes` (even) of 8 bits; ends in keys_[0], ids_[0].
    void sort(std::uint32_t n, std::uint32_t passes) {
        const std::uint32_t blocks = radix_blocks(n);
        for (std::uint32_t pass = 0; pass < passes; ++pass) {
            const int from = int(pass & 1u), to = from ^ 1;
            const std::uint32_t shift = 8 * pass;
            go(k(RadixCount), blocks, keys_[from], n, shift, digits_, blocks);
            scan(digits_, digit_pos_, 256 * blocks);
            go(k(RadixScatter), blocks, keys_[from], ids_[from], keys_[to], ids_[to], n, shift, digit_pos_, blocks);
        }
    }

    /// Exclusive sums of `in`'s first `count` entries into `out`; the total into total_.
    void scan(const Buffer<cl_uint2>& in, Buffer<cl_uint2>& out, std::uint32_t count) {
        if (count <= kOneGroupScan) {
            set_args(k(ScanOne), in, out, count, total_);
            launch_n(k(ScanOne), kScanGroup, kScanGroup);
            return;
        }
        const std::uint32_t blocks = static_cast<std::uint32_t>((count + kScanBlock - 1) / kScanBlock);
        set_args(k(ScanBlocks), in, out, sums_, count);
        launch_n(k(ScanBlocks), std::size_t(blocks) * kScanGroup, kScanGroup);
        set_args(k(ScanSums), sums_, blocks, total_);
        launch_n(k(ScanSums), 1, 1);
        go(k(ScanAdd), count, out, sums_, count);
    }

    /// One sort-by-axis level over m of n elements from set `cur` into the other: the 30-bit keys
    /// sorted (4 passes), gathered in that order, nearest neighbours, pairs per chunk, the plan,
    /// the pairing.
    void level(std::uint32_t m, std::uint32_t n, int cur) {
        const std::uint32_t chunks = std::max<std::uint32_t>(1, m / std::uint32_t(SortAxisBuilder::kChunk));
        go(k(SaKeys), m, ekey_[cur], m, keys_[0], ids_[0]);
        sort(m, 4);
        go(k(SaGather), m, ids_[0], cl_[cur], cnode_[cur], n, m, srt_, snode_);
        go(k(SaNearest), m, srt_, n, m, std::uint32_t(cfg_.window), nn_);
        go(k(SaCount), chunks, nn_, m, chunk_);
        set_args(k(SaPlan), chunk_, m, state_);
        launch_n(k(SaPlan), 1, 1);
        go(k(SaPair), chunks, srt_, snode_, keys_[0], n, m, nn_, chunk_, state_, n, std::uint32_t(cfg_.window),
           cl_[cur ^ 1], cnode_[cur ^ 1], ekey_[cur ^ 1], kids_, fstate_);
    }

    /// One PLOC round over m of n clusters (the arrays' stride) from set `cur` into the other.
    void round(std::uint32_t m, std::uint32_t n, int cur) {
        const std::uint32_t blocks = static_cast<std::uint32_t>((m + kScanBlock - 1) / kScanBlock);
        go(k(Nn), m, cl_[cur], n, m, std::uint32_t(cfg_.radius), nn_);
        set_args(k(Count), nn_, m, pos_, sums_);
        launch_n(k(Count), std::size_t(blocks) * kScanGroup, kScanGroup);
        set_args(k(Sums), sums_, blocks, state_);
        launch_n(k(Sums), 1, 1);
        go(k(Merge), m, cl_[cur], cnode_[cur], cl_[cur ^ 1], cnode_[cur ^ 1], n, nn_, pos_, sums_, state_, n, m, kids_);
    }

    Device* dev_ = nullptr;
    DeviceBuildConfig cfg_;
    ::cl::Kernel k_[kKernels];
    std::size_t launches_ = 0;
    std::uint32_t cap_ = 0;
    Buffer<std::uint32_t> state_, level_counts_, list_[2];
    Buffer<float> fstate_;
    Buffer<cl_uint2> total_;
    Buffer<float> rbox_, cen_, cl_[2], srt_, ibox_;
    Buffer<cl_ulong> keys_[2];
    Buffer<std::uint32_t> ekey_[2], snode_, ids_[2], cnode_[2], nn_, parent_, counters_, icnt_, prims_, first_;
    std::vector<std::uint32_t> bases_;  ///< merge-tree size after each PLOC round (0 first)
    Buffer<cl_uint2> chunk_, leaf_, digits_, digit_pos_, pos_, sums_, kids_, leaf_of_, bflag_, bpos_, wflag_, wpos_;
};

}  // namespace raykit::cl
