// raykit/bvh/traverse_packet.hpp — a packet of rays walking a WideBvh / WideBvh8 together.
//
// The coherent-ray form of traverse<Mode> (bvh/traverse_wide.hpp): up to kPacketLanes rays
// (16 with AVX-512, else 8) share one walk. At a node each child box is slab-tested against
// every ray of the packet in one vector operation, the node is fetched once for all of them,
// and a child is entered by the rays whose own test enters it (a lane mask travels with every
// stack entry). Leaves get the mask and test those rays one by one with the single-ray leaf
// store, so what each ray tests is what its own walk could test.
//
// Why answers stay bit-identical to single rays: each lane's box test is the single-ray
// test's arithmetic on that lane (the same (plane − origin)·(1/d), max/min chains whose NaN
// operands never decide, exit distance widened by the same factor), and a closest hit is the
// smallest (t, triangle index) over the triangles a ray tests whose boxes it enters — which
// does not depend on the order nodes are visited or on how far other rays pruned. So the walk
// may visit in packet order, not per-ray order, and return every ray's single-ray answer
// (tests/test_bvh.cpp checks it against single rays on random, camera and mixed-octant rays).
//
// All lanes of a walk share one octant (the signs of the direction pick the near planes, as a
// single ray's do): one_octant() tests it, and scene/trace.hpp walks packets whose rays point
// into several octants ray by ray (they are not coherent).
//
// The frustum: where every lane's origin and reciprocal direction are finite (and the
// reciprocals non-zero), a node first tests its W child boxes against the packet's frustum in
// one W-wide test (detail::frustum_enter: per axis the extreme origin and reciprocal that bound
// every lane's slab distances, the argument is there), which keeps a superset of the children
// some lane enters. The nearest of them by the frustum's entry bound is tested lane by lane at
// once; the others are pushed with the node's lanes and tested lane by lane when popped. So a
// child no lane can enter costs a share of one W-wide test instead of a 16-lane test, and a
// pushed child is tested once instead of twice. Measured against the walk without it
// (bench_trace, BlockBvh8 batch, 1 thread, two interleaved runs, ms): camera tiles bunny closest
// 7.49-7.68 -> 7.13-7.47, 100k torus 9.01-9.41 -> 8.40, any 7.84-7.93 -> 7.30; rows of 16
// 3-5 % faster; the CPU renderer's thesis frame with shadows 53.1-54.6 -> 51.5-51.8.
// Otherwise (a zero or non-finite direction component, a non-finite origin) children are
// tested lane by lane at the node and entered nearest first by the entry distance of the
// packet's first active ray.
//
// A popped entry is re-tested against its lanes' current tmax (its box is read again from the
// parent node, still in cache), so lanes that found nearer hits drop out before its leaf.
//
// Thinning out: a packet reaching a wide node with kPacketSwitchLanes active rays or fewer walks
// on below it ray by ray (traverse_from, the single-ray walk from that node), as Embree's hybrid
// packet walks do. It changes no answer, by the argument above: every ray still tests the
// triangles of the leaves its own box tests enter. Measured against the walk without it
// (bench_trace camera rays in rows of 16, 1 thread, interleaved): 1M torus closest 20.3-20.8 ->
// 18.7 ms, any 19.3-19.6 -> 16.3-16.5 ms, bunny and 100k torus 2-4 % faster; a switch at 3 lanes
// was fastest on the bunny and the 100k torus, 7 (Embree's for 16 lanes) on the 1M torus.
// Tried and dropped: Embree's leaf test of one triangle against all 16 rays (permuted per lane to
// each ray's shear axes, bit-identical): on rows no faster where packets reach leaves with 6 or
// more rays (bunny closest 6.14-6.20 ms without it, 6.29-6.51 with it), slower from 4; on 4x4
// tiles, where Embree's packets gain most, it is not yet measured in a quiet run.
//
// Stack: as the single-ray walk, at most W − 1 entries per wide level.
//
// The walk is compiled once per instruction-set level: the part of this header below
// RAYKIT_ISA_PASS is its per-level part (scene/trace_level.inc includes it per level; the
// public packet walks are scene/trace.hpp's). A level walks kPacketLanes rays at once (16 with
// AVX-512, else 8); callers hand out kPacketWidth (16) and each level splits them.
#ifndef RAYKIT_BVH_TRAVERSE_PACKET_HPP
#define RAYKIT_BVH_TRAVERSE_PACKET_HPP

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <type_traits>

#include "raykit/bvh/traverse_wide.hpp"
#include "raykit/simd/isa.hpp"

namespace raykit {

/// Rays per packet a batch hands to closest_hit_packet / any_hit_packet: the widest any level
/// walks at once (AVX-512's 16; levels without it walk two packets of 8).
inline constexpr int kPacketWidth = 16;

/// True when rays[0, n) point into one octant (the signs of their directions agree), which a
/// packet walk needs: the signs pick the near planes for all lanes at once. It is also the test
/// for a coherent packet: rays into several octants (random rays, ambient-occlusion rays from one
/// point) share few nodes, and walked as packets they ran at 0.5x their single-ray speed
/// (bench_trace, bunny random rays, 3.4 against 6.2 Mrays/s), so callers walk them one by one.
inline bool one_octant(const Ray* rays, unsigned n) noexcept {
    const auto signs = [](const Ray& r) {
        return unsigned(std::signbit(r.dir.x)) | unsigned(std::signbit(r.dir.y)) << 1 |
               unsigned(std::signbit(r.dir.z)) << 2;
    };
    const unsigned s0 = signs(rays[0]);
    for (unsigned k = 1; k < n; ++k)
        if (signs(rays[k]) != s0) return false;
    return true;
}

}  // namespace raykit

#endif  // RAYKIT_BVH_TRAVERSE_PACKET_HPP

#ifdef RAYKIT_ISA_PASS
namespace raykit::RAYKIT_ISA_NS {

/// Rays one packet walk takes at this level: 16 with AVX-512 (one register per lane quantity), else 8.
inline constexpr int kPacketLanes = RAYKIT_ISA_AVX512 ? 16 : 8;

namespace detail {

template <int N>
struct PacketLanes;
template <>
struct PacketLanes<4> {
    typedef float f __attribute__((vector_size(16)));
    typedef std::int32_t i __attribute__((vector_size(16)));
};
template <>
struct PacketLanes<8> {
    typedef float f __attribute__((vector_size(32)));
    typedef std::int32_t i __attribute__((vector_size(32)));
};
template <>
struct PacketLanes<16> {
    typedef float f __attribute__((vector_size(64)));
    typedef std::int32_t i __attribute__((vector_size(64)));
};

/// One bit per lane of a comparison result (lanes are 0 or −1).
template <int N>
RAYKIT_INLINE unsigned lane_bits(const typename PacketLanes<N>::i& m) noexcept {
#if RAYKIT_ISA_AVX512
    if constexpr (N == 16) return _mm512_cmplt_epi32_mask(reinterpret_cast<__m512i>(m), _mm512_setzero_si512());
#endif
#if RAYKIT_ISA_AVX
    if constexpr (N == 8) return static_cast<unsigned>(_mm256_movemask_ps(reinterpret_cast<__m256>(m)));
#endif
#if RAYKIT_ISA_SSE2
    if constexpr (N == 4) return static_cast<unsigned>(_mm_movemask_ps(reinterpret_cast<__m128>(m)));
#endif
    unsigned b = 0;
    for (int k = 0; k < N; ++k) b |= unsigned(m[k] & 1) << k;
    return b;
}

/// The smallest lane of `v` (the largest when kMax), lanes halved vector-wide down to 4, then
/// taken in order; with NaN lanes the result is some lane's value.
template <int N, bool kMax>
RAYKIT_INLINE float lane_extreme(const typename PacketLanes<N>::f& v) noexcept {
    if constexpr (N <= 4) {
        float m = v[0];
        for (int k = 1; k < N; ++k) m = (kMax ? v[k] > m : v[k] < m) ? v[k] : m;
        return m;
    } else {
        using vh = typename PacketLanes<N / 2>::f;
        vh a, b;
        __builtin_memcpy(&a, &v, sizeof(vh));
        __builtin_memcpy(&b, reinterpret_cast<const char*>(&v) + sizeof(vh), sizeof(vh));
        const vh m = kMax ? (b > a ? b : a) : (b < a ? b : a);
        return lane_extreme<N / 2, kMax>(m);
    }
}

}  // namespace detail

/// The per-lane state of a packet walk: origins, reciprocal directions, intervals, for rays of
/// one octant (one_octant). Lanes past the rays given hold a copy of lane 0.
template <int N = kPacketLanes>
struct RayPacket {
    using vf = typename detail::PacketLanes<N>::f;
    static constexpr int kLanes = N;
    vf org[3], inv[3], tmin;
    alignas(64) float tmax[std::size_t(N)];  ///< per lane; closest-hit leaves shrink it
    int near_row[3], far_row[3];             ///< WideNode::planes rows of the near / far planes
    /// The packet's frustum (detail::frustum_enter), per axis: the lanes' origin that makes
    /// every lane's near-plane distance smallest and the one that makes its far-plane distance
    /// largest, the smallest and largest reciprocal; the smallest tmin. Only where `frustum`.
    float fr_org_near[3], fr_org_far[3], fr_inv_lo[3], fr_inv_hi[3], fr_tmin;
    bool frustum;  ///< every lane's origin finite and reciprocal finite and non-zero

    RayPacket(const Ray* rays, unsigned n) noexcept {
        // the rays' fields gathered into lane arrays, then every lane quantity computed
        // vector-wide: the reciprocals (RayInv's division, lane by lane) and the frustum's
        // extremes (a per-lane loop with 3 divisions and 12 compares per ray took 7 % of a camera
        // batch's time in perf)
        alignas(64) float o[3][std::size_t(N)], d[3][std::size_t(N)], t0[std::size_t(N)];
        for (int k = 0; k < N; ++k) {
            const Ray& r = rays[unsigned(k) < n ? k : 0];
            for (int a = 0; a < 3; ++a) {
                o[a][k] = r.org[a];
                d[a][k] = r.dir[a];
            }
            t0[k] = r.tmin;
            tmax[k] = r.tmax;
        }
        using vi = typename detail::PacketLanes<N>::i;
        constexpr unsigned kAll = N == 32 ? ~0u : (1u << N) - 1u;
        const vf inf = kInf - vf{};
        __builtin_memcpy(&tmin, t0, sizeof(tmin));
        // the smallest tmin; a NaN tmin (that lane enters nothing) counts as +inf
        const vf tmin_or_inf = tmin < inf ? tmin : inf;
        fr_tmin = detail::lane_extreme<N, false>(tmin_or_inf);
        frustum = true;
        for (int a = 0; a < 3; ++a) {
            vf dir;
            __builtin_memcpy(&org[a], o[a], sizeof(vf));
            __builtin_memcpy(&dir, d[a], sizeof(vf));
            inv[a] = 1.0f / dir;
            const int neg = std::signbit(d[a][0]) ? 1 : 0;  // the packet's octant: lane 0's (RayInv's rule)
            near_row[a] = 2 * a + neg;
            far_row[a] = 2 * a + 1 - neg;
            // x − x is 0 exactly when x is finite
            const vi finite = (org[a] - org[a] == 0.0f) & (inv[a] - inv[a] == 0.0f) & (inv[a] != 0.0f);
            frustum = frustum && detail::lane_bits<N>(finite) == kAll;
            // (plane − o)·v falls as o grows where v > 0, rises where v < 0 (one octant: one sign);
            // with every lane finite the extremes do not depend on the order they are taken in
            const float olo = detail::lane_extreme<N, false>(org[a]), ohi = detail::lane_extreme<N, true>(org[a]);
            fr_org_near[a] = neg ? olo : ohi;
            fr_org_far[a] = neg ? ohi : olo;
            fr_inv_lo[a] = detail::lane_extreme<N, false>(inv[a]);
            fr_inv_hi[a] = detail::lane_extreme<N, true>(inv[a]);
        }
    }
};

namespace detail {

/// Lanes of `mask` whose rays enter the box with near planes `lo` and far planes `hi` (per
/// axis, already chosen by the packet's octant) within their [tmin, tmax]: the single-ray test
/// (WideSlabRay::test) lane by lane; entry distances to tn_out when not null.
template <int N>
RAYKIT_INLINE unsigned packet_enter(const RayPacket<N>& p, const float* near, const float* far, unsigned mask,
                                    float* tn_out) noexcept {
    // vectors stay local (no vector parameters or returns: a consumer without AVX would get
    // -Wpsabi for 32-byte ones); x > y ? x : y is MAXPS (a NaN x gives y), as the single ray's
    using vf = typename RayPacket<N>::vf;
    vf tmax;
    __builtin_memcpy(&tmax, p.tmax, sizeof(tmax));
    const vf tnx = (near[0] - p.org[0]) * p.inv[0];
    const vf tny = (near[1] - p.org[1]) * p.inv[1];
    const vf tnz = (near[2] - p.org[2]) * p.inv[2];
    const vf tfx = (far[0] - p.org[0]) * p.inv[0];
    const vf tfy = (far[1] - p.org[1]) * p.inv[1];
    const vf tfz = (far[2] - p.org[2]) * p.inv[2];
    const vf n1 = tnz > p.tmin ? tnz : p.tmin;
    const vf n2 = tny > n1 ? tny : n1;
    const vf tn = tnx > n2 ? tnx : n2;
    const vf f1 = tfz < tmax ? tfz : tmax;
    const vf f2 = tfy < f1 ? tfy : f1;
    const vf tf = (tfx < f2 ? tfx : f2) * kSlabExitScale;
    if (tn_out) __builtin_memcpy(tn_out, &tn, sizeof(tn));
    return lane_bits<N>(tn <= tf) & mask;
}

/// The children of wide node `n` that some lane of `p` may enter: a superset of the lanes'
/// packet_enter_child over all children, W children in one vector test (needs p.frustum).
/// Each lane's entry distance is fl(fl(plane − o)·v), which rounding keeps monotone in o and,
/// for a fixed plane − o, in v; so the extreme origin and the smaller or larger of the two
/// extreme reciprocals bound it below for near planes and above for far planes, and the max/min
/// chains and the exit widening keep the order: a lane that enters a box enters its frustum
/// box. tmax is left out (a pushed child's lanes are tested at its pop, against their tmax).
/// Writes the lower bounds of the entry distances to tn_out (W floats).
template <int W, int N>
RAYKIT_INLINE unsigned frustum_enter(const RayPacket<N>& p, const WideNodeT<W>& n, float* tn_out) noexcept {
    using vw = typename PacketLanes<W>::f;
    vw lo[3], hi[3];
    for (int a = 0; a < 3; ++a) {
        vw pn, pf;
        __builtin_memcpy(&pn, n.planes[p.near_row[a]], sizeof(pn));
        __builtin_memcpy(&pf, n.planes[p.far_row[a]], sizeof(pf));
        const vw dn = pn - p.fr_org_near[a], df = pf - p.fr_org_far[a];
        const vw n0 = dn * p.fr_inv_lo[a], n1 = dn * p.fr_inv_hi[a];
        const vw f0 = df * p.fr_inv_lo[a], f1 = df * p.fr_inv_hi[a];
        lo[a] = n0 < n1 ? n0 : n1;  // both NaN or neither (a NaN plane)
        hi[a] = f0 > f1 ? f0 : f1;
    }
    const vw tmin = p.fr_tmin - vw{}, inf = kInf - vw{};
    const vw n1 = lo[2] > tmin ? lo[2] : tmin;
    const vw n2 = lo[1] > n1 ? lo[1] : n1;
    const vw tn = lo[0] > n2 ? lo[0] : n2;
    const vw f1 = hi[2] < inf ? hi[2] : inf;
    const vw f2 = hi[1] < f1 ? hi[1] : f1;
    const vw tf = (hi[0] < f2 ? hi[0] : f2) * kSlabExitScale;
    __builtin_memcpy(tn_out, &tn, sizeof(tn));
    return lane_bits<W>(tn <= tf);
}

/// packet_enter for child `i` of wide node `n`.
template <int W, int N>
RAYKIT_INLINE unsigned packet_enter_child(const RayPacket<N>& p, const WideNodeT<W>& n, int i, unsigned mask,
                                          float* tn_out) noexcept {
    const float near[3] = {n.planes[p.near_row[0]][i], n.planes[p.near_row[1]][i], n.planes[p.near_row[2]][i]};
    const float far[3] = {n.planes[p.far_row[0]][i], n.planes[p.far_row[1]][i], n.planes[p.far_row[2]][i]};
    return packet_enter(p, near, far, mask, tn_out);
}

}  // namespace detail

/// A packet that reaches a wide node with this many active lanes or fewer walks on below it ray
/// by ray: a packet node test costs W lane-vector tests whatever the number of lanes, a single
/// ray's one W-wide test.
inline constexpr int kPacketSwitchLanes = 3;

/// Walks `bvh` with the lanes `lanes` of packet `p`. `leaf(first, count, mask)` tests the
/// leaf's slots for the rays of `mask` and returns the lanes it finished (any-hit: lanes that
/// found a hit, which then leave the walk; closest-hit: 0, the leaf shrinks p.tmax instead).
/// `single(index, mask)` walks each ray of `mask` alone below wide node `index` (whose box they
/// enter; traverse_from) and returns the lanes it finished, as leaf does. Returns the lanes
/// finished.
template <class Mode = ClosestHit, int W, int N, class LeafFn, class SingleFn>
unsigned traverse_packet(const WideBvhT<W>& bvh, const RayPacket<N>& p, unsigned lanes, LeafFn&& leaf,
                         SingleFn&& single) {
    if (bvh.nodes.empty() || lanes == 0) return 0;
    const WideNodeT<W>* RAYKIT_RESTRICT nodes = bvh.nodes.data();
    // the root box first, as the single-ray walk tests it
    const float* lo = &bvh.bounds.min.x;
    const float* hi = &bvh.bounds.max.x;
    float root_near[3], root_far[3];
    for (int a = 0; a < 3; ++a) {
        const bool neg = p.near_row[a] & 1;
        root_near[a] = neg ? hi[a] : lo[a];
        root_far[a] = neg ? lo[a] : hi[a];
    }
    unsigned active = detail::packet_enter(p, root_near, root_far, lanes, nullptr);
    if (!active) return 0;

    struct Entry {
        std::uint32_t index, count;  // count 0: a wide node; else a leaf's first slot and slot count
        std::uint32_t parent;        // the node holding its box, and the slot
        std::uint32_t slot_mask;     // slot << 24 | lane mask (N <= 16)
    };
    constexpr int kStack = (W - 1) * RAYKIT_BVH_MAX_DEPTH + 1;
    Entry stack[std::size_t(kStack)];
    int sp = 0;
    unsigned finished = 0;
    std::uint32_t cur_index = 0, cur_count = 0;
    unsigned cur_mask = active;
    for (;;) {
        if (cur_count == 0 && std::popcount(cur_mask) <= kPacketSwitchLanes) {
            const unsigned done = single(cur_index, cur_mask);
            if constexpr (Mode::any_hit) {
                finished |= done;
                active &= ~done;
                if (!active) return finished;
            }
        } else if (cur_count == 0) {
            const WideNodeT<W>& n = nodes[cur_index];
            float key[std::size_t(W)];
            unsigned mask[std::size_t(W)];
            int entered[std::size_t(W)];
            int k = 0;
            // children to enter, nearest first by `t` (stable: ties keep slot order)
            const auto insert = [&](int i, float t, unsigned m) RAYKIT_LAMBDA_INLINE {
                int j = k++;
                while (j > 0 && key[j - 1] > t) {
                    key[j] = key[j - 1];
                    mask[j] = mask[j - 1];
                    entered[j] = entered[j - 1];
                    --j;
                }
                key[j] = t;
                mask[j] = m;
                entered[j] = i;
            };
            if (p.frustum) {
                // the children some lane may enter, by the frustum's entry bound, with the node's
                // lanes: each is tested lane by lane when taken (the first, below) or popped
                alignas(64) float tn[std::size_t(W)];
                for (unsigned cand = detail::frustum_enter(p, n, tn); cand; cand &= cand - 1) {
                    const int i = std::countr_zero(cand);
                    insert(i, tn[i], cur_mask);
                }
            } else {
                const int lead = std::countr_zero(cur_mask);  // the ray whose distances order the children
                for (int i = 0; i < W; ++i) {
                    // unused slots hold an empty box no lane enters: testing them is cheaper than
                    // branching on unused(i), whose pattern varies node to node (render_cpu, thesis
                    // camera rays, 1 thread: trace 15.1-15.3 ms with the branch, 12.5-12.7 without)
                    alignas(64) float tn[std::size_t(N)];
                    const unsigned m = detail::packet_enter_child(p, n, i, cur_mask, tn);
                    if (m) insert(i, tn[lead], m);
                }
            }
            if (k > 0) {
                if (sp + k - 1 > kStack)
                    throw std::length_error("raykit::traverse_packet: wide tree deeper than RAYKIT_BVH_MAX_DEPTH");
                for (int j = k - 1; j >= 1; --j) {
                    const int i = entered[j];
                    stack[sp++] = {n.index[i], n.count[i], cur_index, std::uint32_t(i) << 24 | mask[j]};
                }
                const unsigned m = p.frustum ? detail::packet_enter_child(p, n, entered[0], mask[0], nullptr) : mask[0];
                if (m) {
                    cur_index = n.index[entered[0]];
                    cur_count = n.count[entered[0]];
                    cur_mask = m;
                    continue;
                }
            }
        } else {
            const unsigned done = leaf(cur_index, cur_count, cur_mask);
            if constexpr (Mode::any_hit) {
                finished |= done;
                active &= ~done;
                if (!active) return finished;
            }
        }
        for (;;) {
            if (sp == 0) return finished;
            const Entry e = stack[--sp];
            unsigned m = e.slot_mask & 0xFFFFFFu & active;
            if (!m) continue;
            m = detail::packet_enter_child(p, nodes[e.parent], int(e.slot_mask >> 24), m, nullptr);
            if (m) {
                cur_index = e.index;
                cur_count = e.count;
                cur_mask = m;
                break;
            }
        }
    }
}

}  // namespace raykit::RAYKIT_ISA_NS
#endif  // RAYKIT_ISA_PASS
