// raykit/render/frame.hpp — the thesis's frame as a library type: vertex stage → refit or
// rebuild → top-level tree → camera rays → trace and shade → pixels, with per-stage timings.
//
//   RenderScene rs;                                        // render/render_cpu.hpp
//   const auto town = rs.add_object(load_obj("town.obj"));                     // static
//   const auto body = rs.add_object(model.mesh, ObjectKind::dynamic);          // moved per frame
//   rs.scene.add_instance(town);  rs.scene.add_instance(body);
//   FrameLoop loop(rs, settings);
//   per frame:
//     Image img = loop.render(cam, vertex_hook([&](std::uint32_t object, const Vertex& v, std::uint32_t i) {
//         return SkinHook::apply(v, i, params, host);  // the CPU twin of the device vertex hook
//     }));
//     const FrameStats& st = loop.last();             // st.ms.vertex, .refit, .top, .trace, .shade, .total
//
// Stages, in order (times are wall-clock milliseconds of this frame):
//   vertex   the stage callable runs once per dynamic object: stage(scene, object) writes its
//            vertices (Scene::write_vertices from the rest copy, or Scene::set_positions with
//            positions from elsewhere, e.g. a device vertex stage). Static objects are never
//            touched. vertex_hook(fn) adapts a per-vertex fn(object, rest_vertex, index).
//   refit    every dynamic object's trees (binary and blocks) refitted in place; then the
//            RebuildPolicy (SAH cost of the refitted binary tree against the cost after its
//            last build) decides per object, and a decided object is rebuilt (binned SAH, its
//            config) in this stage too. FrameStats::rebuilt counts them.
//   top      the top-level tree over the instances' world boxes (refitted while the instance
//            count is unchanged, rebuilt otherwise).
//   render   render_cpu over the scene (trace + shade). With RenderSettings::time_stages, trace
//            and shade split the render wall time in the ratio of the workers' traversal and
//            shading thread times; without it (the default) trace = render and shade = 0: the
//            two time-stamp reads per query cost 15-25 % of a goblin frame (bench_render, the
//            animate variant with and without them).
// The policy runs on the CPU twin; the device frame (cl/) follows the same stages.
#pragma once

#include <chrono>
#include <cstdint>
#include <vector>

#include "raykit/bvh/rebuild_policy.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/scene/scene.hpp"

namespace raykit {

/// Wall time of each stage of one frame, in milliseconds.
struct FrameTimes {
    double vertex = 0.0, refit = 0.0, top = 0.0, render = 0.0, trace = 0.0, shade = 0.0, total = 0.0;
};

/// What one frame did.
struct FrameStats {
    FrameTimes ms;
    RenderStats render;         ///< the renderer's own statistics
    std::uint32_t rebuilt = 0;  ///< dynamic objects rebuilt this frame (the rest were refitted)
    double worst_growth = 1.0;  ///< largest SAH growth (refit / last build) before the decision
};

/// A stage callable from a per-vertex function fn(object, rest_vertex, index) -> Vertex.
template <class Fn>
auto vertex_hook(Fn fn, unsigned threads = 0) {
    return [fn = std::move(fn), threads](Scene& scene, std::uint32_t object) {
        scene.write_vertices(
            object, [&](const Vertex& v, std::uint32_t i) { return fn(object, v, i); }, threads);
    };
}

/// The frame loop over a RenderScene (which must outlive it). Not thread-safe.
class FrameLoop {
public:
    explicit FrameLoop(RenderScene& rs, const RenderSettings& settings = {}, RebuildPolicy policy = {})
        : rs_(&rs), set_(settings), policy_(policy) {
        policies_.assign(rs.scene.objects().size(), policy);
        for (std::uint32_t o = 0; o < rs.scene.objects().size(); ++o)
            if (rs.scene.objects()[o].dynamic()) policies_[o].reset(sah_cost(rs.scene.objects()[o].bvh));
    }

    /// Moves the dynamic objects with `stage` and brings every tree up to date (vertex, refit
    /// and top stages); fills last()'s times for them.
    template <class Stage>
    void update(Stage&& stage) {
        using Clock = std::chrono::steady_clock;
        const auto ms = [](Clock::time_point a) { return std::chrono::duration<double, std::milli>(Clock::now() - a).count(); };
        Scene& sc = rs_->scene;
        if (policies_.size() != sc.objects().size()) {  // objects added since: start their policies
            const std::size_t old = policies_.size();
            policies_.resize(sc.objects().size(), policy_);
            for (std::size_t o = old; o < policies_.size(); ++o)
                if (sc.objects()[o].dynamic()) policies_[o].reset(sah_cost(sc.objects()[o].bvh));
        }
        last_ = FrameStats{};
        auto t = Clock::now();
        for (std::uint32_t o = 0; o < sc.objects().size(); ++o)
            if (sc.objects()[o].dynamic()) stage(sc, o);
        last_.ms.vertex = ms(t);
        t = Clock::now();
        for (std::uint32_t o = 0; o < sc.objects().size(); ++o) {
            if (!sc.objects()[o].dynamic()) continue;
            sc.update_object(o, TreeUpdate::refit, set_.threads);
            const double cost = sah_cost(sc.objects()[o].bvh);
            last_.worst_growth = std::max(last_.worst_growth, policies_[o].growth(cost));
            if (policies_[o].should_rebuild(cost)) {
                sc.rebuild_object(o);
                policies_[o].reset(sah_cost(sc.objects()[o].bvh));
                ++last_.rebuilt;
            }
        }
        last_.ms.refit = ms(t);
        t = Clock::now();
        sc.update_top_level(TopLevelUpdate::refit);
        last_.ms.top = ms(t);
    }

    /// Renders the scene as it stands (the render stage); fills last()'s render times.
    Image render(const Camera& cam) {
        RenderStats st;
        Image img = render_cpu(rs_->view(), cam, set_, &st);
        const double thread_all = st.trace_thread_ms + st.shadow_thread_ms + st.shade_thread_ms;
        const double trace_share = thread_all > 0.0 ? (st.trace_thread_ms + st.shadow_thread_ms) / thread_all : 1.0;
        last_.render = st;
        last_.ms.render = st.render_ms;
        last_.ms.trace = st.render_ms * trace_share;
        last_.ms.shade = st.render_ms - last_.ms.trace;
        last_.ms.total = last_.ms.vertex + last_.ms.refit + last_.ms.top + st.total_ms;
        return img;
    }

    /// One whole frame: update(stage), then render(cam).
    template <class Stage>
    Image render(const Camera& cam, Stage&& stage) {
        update(stage);
        return render(cam);
    }

    /// The statistics of the last frame.
    const FrameStats& last() const noexcept { return last_; }
    RenderSettings& settings() noexcept { return set_; }
    RenderScene& scene() noexcept { return *rs_; }

private:
    RenderScene* rs_;
    RenderSettings set_;
    RebuildPolicy policy_;
    std::vector<RebuildPolicy> policies_;  ///< one per object (used for dynamic ones)
    FrameStats last_;
};

}  // namespace raykit
