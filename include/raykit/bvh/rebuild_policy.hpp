// raykit/bvh/rebuild_policy.hpp — when a refitted tree should be rebuilt.
//
// Refit keeps the topology and only regrows boxes, so it is cheap (one linear
// sweep) but its quality decays when primitives move far from the neighbours
// they were grouped with (a hand thrown away from a body: its triangles stay in
// the body's subtrees, whose boxes now stretch across the gap). The SAH cost
// of the refitted tree measures that decay directly:
//
//   RebuildPolicy policy;                 // threshold 1.15, from the measurement below
//   policy.reset(sah_cost(bvh));          // after every (re)build
//   refit(bvh, boxes);
//   if (policy.should_rebuild(sah_cost(bvh))) { bvh = build(...); policy.reset(sah_cost(bvh)); }
//
// The default threshold comes from benchmarks/refit_vs_rebuild.cpp (100k-
// triangle bumpy torus; first a wave that keeps neighbourhoods, then a 60°
// sector thrown away rigidly; traversal steps per ray on 20k random rays):
//
//   SAH growth (refit / fresh)   1.04   1.06   1.12   1.21   1.31   1.88
//   traversal steps, refit/fresh 1.04   1.07   1.18   1.36   1.57   3.37
//
// The wave never passes 1.04, the thrown sector passes 1.15 three frames in.
// A rebuild costs about 60 refits there (85 ms against 1.4 ms on 2 threads),
// so at 1.15 (≈ +25 % trace work) a frame that traces a few hundred thousand
// rays or more recovers the rebuild within a frame or two. Scenes that trace
// few rays per frame should raise the threshold; see README ("refit or
// rebuild").
#pragma once

namespace raykit {

struct RebuildPolicy {
    /// Rebuild when cost / cost_after_last_build exceeds this.
    double threshold = 1.15;
    double baseline = 0.0;

    void reset(double cost_after_build) noexcept { baseline = cost_after_build; }
    /// Ratio of the current cost to the baseline (1 = as good as fresh).
    double growth(double current_cost) const noexcept { return baseline > 0.0 ? current_cost / baseline : 1.0; }
    bool should_rebuild(double current_cost) const noexcept { return growth(current_cost) > threshold; }
};

}  // namespace raykit
