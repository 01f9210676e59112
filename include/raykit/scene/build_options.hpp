// raykit/scene/build_options.hpp — choose a builder and its settings at run time.
//
//   BuildOptions o;                                   // binned SAH, leaf ≤ 8, all threads
//   o.builder = BuildOptions::Builder::sortaxis;
//   o.window = 16;
//   Bvh bvh = build_bvh(mesh, o);
//
// Settings left unset (metric, pairing, optimize) take the chosen builder's
// Config default, so BuildOptions{} with a builder picked gives the same tree
// as that builder's default Config.
//
// Compile-time use stays available and pays only for the builder it names:
// build_bvh<SortAxisBuilder>(mesh, cfg). This header includes all four.
#pragma once

#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

#include "raykit/bvh/binned_sah.hpp"
#include "raykit/bvh/pairwise.hpp"
#include "raykit/bvh/ploc.hpp"
#include "raykit/bvh/sortaxis.hpp"
#include "raykit/scene/build.hpp"

namespace raykit {

struct BuildOptions {
    enum class Builder { sah, pairwise, sortaxis, ploc };
    enum class Axis { x, longest, morton };
    enum class Metric { centre, area };
    enum class Pairing { greedy, mutual };

    Builder builder = Builder::sah;
    LeafCost leaf;               ///< all builders: max leaf size, Ct, Ci, leaf_block (4 for BlockBvh tracing)
    unsigned threads = 0;        ///< all builders; 0 = all hardware threads, at most kMaxThreads (else std::invalid_argument)
    unsigned window = SortAxisBuilder::Config{}.window;  ///< sortaxis: W
    Axis axis = Axis::morton;    ///< sortaxis
    std::optional<Metric> metric;    ///< pairwise, sortaxis (unset: the builder's default)
    std::optional<Pairing> pairing;  ///< sortaxis (unset: the builder's default)
    unsigned radius = PlocBuilder::Config{}.radius;  ///< ploc: R
    /// Post-pass (bvh/optimize.hpp) for sortaxis and ploc (unset: the
    /// builder's default: on for ploc, off for sortaxis).
    std::optional<OptimizeConfig> optimize;

    static Builder parse_builder(std::string_view s) {
        if (s == "sah") return Builder::sah;
        if (s == "pairwise") return Builder::pairwise;
        if (s == "sortaxis") return Builder::sortaxis;
        if (s == "ploc") return Builder::ploc;
        throw std::invalid_argument("unknown builder '" + std::string(s) + "' (known: sah, pairwise, sortaxis, ploc)");
    }
    static Axis parse_axis(std::string_view s) {
        if (s == "x") return Axis::x;
        if (s == "longest") return Axis::longest;
        if (s == "morton") return Axis::morton;
        throw std::invalid_argument("unknown axis '" + std::string(s) + "' (known: x, longest, morton)");
    }
    static Metric parse_metric(std::string_view s) {
        if (s == "centre" || s == "center") return Metric::centre;
        if (s == "area") return Metric::area;
        throw std::invalid_argument("unknown metric '" + std::string(s) + "' (known: centre, area)");
    }
    static const char* name(Builder b) {
        switch (b) {
            case Builder::pairwise: return "pairwise";
            case Builder::sortaxis: return "sortaxis";
            case Builder::ploc: return "ploc";
            default: return "sah";
        }
    }
    static const char* name(Axis a) { return a == Axis::x ? "x" : a == Axis::longest ? "longest" : "morton"; }
    static const char* name(Metric m) { return m == Metric::area ? "area" : "centre"; }
    static const char* name(const std::optional<Metric>& m) { return m ? name(*m) : "default"; }
    static const char* name(Pairing p) { return p == Pairing::greedy ? "greedy" : "mutual"; }
    static Pairing parse_pairing(std::string_view s) {
        if (s == "greedy") return Pairing::greedy;
        if (s == "mutual") return Pairing::mutual;
        throw std::invalid_argument("unknown pairing '" + std::string(s) + "' (known: greedy, mutual)");
    }
};

/// Builds with the builder and settings named in `o`.
inline Bvh build_bvh(std::span<const AABB> boxes, std::span<const vec3> centers, const BuildOptions& o) {
    check_threads(o.threads, "build_bvh");
    using B = BuildOptions::Builder;
    switch (o.builder) {
        case B::pairwise: {
            PairwiseBuilder::Config c;
            c.leaf = o.leaf;
            c.threads = o.threads;
            if (o.metric)
                c.metric = *o.metric == BuildOptions::Metric::area ? PairwiseBuilder::Config::Metric::area
                                                                    : PairwiseBuilder::Config::Metric::centre;
            return PairwiseBuilder::build(boxes, centers, c);
        }
        case B::sortaxis: {
            SortAxisBuilder::Config c;
            c.leaf = o.leaf;
            c.threads = o.threads;
            c.window = o.window;
            c.axis = o.axis == BuildOptions::Axis::x         ? SortAxisBuilder::Config::Axis::x
                     : o.axis == BuildOptions::Axis::longest ? SortAxisBuilder::Config::Axis::longest
                                                             : SortAxisBuilder::Config::Axis::morton;
            if (o.metric)
                c.metric = *o.metric == BuildOptions::Metric::area ? SortAxisBuilder::Config::Metric::area
                                                                    : SortAxisBuilder::Config::Metric::centre;
            if (o.pairing)
                c.pairing = *o.pairing == BuildOptions::Pairing::greedy ? SortAxisBuilder::Config::Pairing::greedy
                                                                        : SortAxisBuilder::Config::Pairing::mutual;
            if (o.optimize) c.optimize = *o.optimize;
            return SortAxisBuilder::build(boxes, centers, c);
        }
        case B::ploc: {
            PlocBuilder::Config c;
            c.leaf = o.leaf;
            c.threads = o.threads;
            c.radius = o.radius;
            if (o.optimize) c.optimize = *o.optimize;
            return PlocBuilder::build(boxes, centers, c);
        }
        default: {
            BinnedSahBuilder::Config c;
            c.leaf = o.leaf;
            c.threads = o.threads;
            return BinnedSahBuilder::build(boxes, centers, c);
        }
    }
}

inline Bvh build_bvh(const MeshView& mesh, const BuildOptions& o) {
    check_threads(o.threads, "build_bvh");  // before primitive_arrays spends the time
    const detail::PrimitiveArrays r = detail::primitive_arrays(mesh, o.threads);
    return build_bvh(r.boxes, r.centers, o);
}

}  // namespace raykit
