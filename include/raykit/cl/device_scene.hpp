// raykit/cl/device_scene.hpp — a raykit::Scene on the device: the frame pipeline.
//
//   Scene scene;  ... add objects (static / dynamic) and instances ...
//   raykit::cl::DeviceScene<WaveHook> ds(raykit::cl::Device::shared(), scene);
//   ds.set_hook<WaveHook>(cloth, {.time = 0.0f});          // which hook moves which dynamic object
//   per frame:
//     ds.set_hook<WaveHook>(cloth, {.time = t});            // new parameters
//     scene.set_transform(...);                             // instances are read from the Scene
//     FrameTimes ft = ds.update();                          // vertex stage, refit, top level
//     ds.camera_rays(cam.frame(), rays);  ds.closest(rays, hits, n);
//
// Upload: every object's tree in the device's form (device_tree() of its
// BlockBvh8: the 8-wide tree and the 4-triangle blocks the CPU walks,
// cl/device_tree.hpp), triangles, positions and vertex records
// (rk_vertex: position, normal, uv — what the renderer shades with) go into
// concatenated device arrays once, dynamic objects first. Static objects are
// never written again. A dynamic object also gets its rest vertices; the
// vertex stage writes its moved vertices over its records.
//
// update() runs only the stages the scene needs:
//   vertex stage  one launch per hook that moves at least one object (the
//                 hook's objects are concatenated into one launch); each vertex
//                 is computed from its rest copy;
//   refit         when a vertex stage ran or set_positions() was called:
//                 every dynamic tree, level-wise or one-pass (cl/refit.hpp),
//                 its leaves rewriting their blocks from the moved vertices;
//   rebuild       with DeviceRebuild::enabled, after a refit: each dynamic tree's
//                 SAH cost (one launch, a float per object read back), the
//                 RebuildPolicy per object, and a device build (cl/device_build.hpp,
//                 PLOC or sort by axis) of each decided one into its ranges, with
//                 its refit tables; the CPU twin builds it only when the device
//                 builder gives up (FrameTimes::rebuilt_on_host);
//   quantize      with NodeForm::quantized, after a refit or rebuild: the dynamic
//                 trees' nodes quantized again (kernels/raykit/kernels/quantize.hpp,
//                 one launch), the static ones were on the host at upload;
//   top level     dynamic root boxes gathered (one launch + one small read,
//                 only after a refit), instance world boxes from the Scene's
//                 transforms (transformed_box), the top-level tree built (or
//                 refitted) on the host with the Scene's builder settings and
//                 uploaded with the instance records.
// Hooks with global buffers (H::buffers, cl/hook.hpp) get them bound after
// the vertex-stage kernel's own arguments from set_hook_buffer<H>(slot, data).
// A scene with no dynamic object never launches a vertex or refit kernel;
// a hook no object uses is not even compiled (the program holds only the
// used hooks' sources and stages). launches() counts every launch by stage.
//
// Tracing (closest / any, one work item per ray) is the twin of
// Scene::intersect_closest / intersect_any: same object-space rays (the
// same fma formulation), same traversal and tie rules.
//
// The Scene must outlive the DeviceScene and keep its objects (instances may
// be added or moved between updates; objects may not be added). The device
// holds its own copy of the instances and top level, which only update()
// refreshes (Scene::update_top_level() does not): tracing, or rendering with
// cl/render.hpp, after Scene::add_instance or set_transform without update()
// throws std::logic_error, as the CPU Scene throws until update_top_level(),
// instead of showing the instances where the last update() left them (it
// used to). A throw, not an update on the renderer's behalf: update() runs
// the hooks' vertex stage and takes the refit and top-level methods, the
// caller's choices. A
// DeviceScene is not thread-safe: use it from one thread at a time.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

#include "raykit/bvh/rebuild_policy.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/device_build.hpp"
#include "raykit/cl/device_tree.hpp"
#include "raykit/cl/hook.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/cl/refit.hpp"
#include "raykit/cl/trace.hpp"
#include "raykit/kernels/camera.hpp"
#include "raykit/kernels/quantize.hpp"
#include "raykit/kernels/trace.hpp"
#include "raykit/scene/scene.hpp"

namespace raykit::cl {

/// Kernel launches of a DeviceScene, by stage.
struct LaunchCounts {
    std::size_t vertex = 0;     ///< vertex-stage launches
    std::size_t refit = 0;      ///< refit launches
    std::size_t top_level = 0;  ///< root-box gathers
    std::size_t trace = 0;      ///< closest / any launches
    std::size_t camera = 0;     ///< camera-ray launches
    std::size_t quantize = 0;   ///< dynamic nodes quantized again (NodeForm::quantized)
    std::size_t total() const noexcept { return vertex + refit + top_level + trace + camera + quantize; }
};

/// Wall-clock milliseconds of one update(), each stage waited for, and what its rebuild stage did.
struct FrameTimes {
    double vertex_ms = 0.0;
    double refit_ms = 0.0;
    double rebuild_ms = 0.0;        ///< the policy's cost measure and any rebuilds (DeviceRebuild)
    double quantize_ms = 0.0;       ///< the dynamic nodes quantized again (NodeForm::quantized)
    double top_level_ms = 0.0;
    std::uint32_t rebuilt = 0;          ///< dynamic objects rebuilt this update
    std::uint32_t rebuilt_on_host = 0;  ///< of those, built on the CPU (too deep for the device builder)
    double worst_growth = 1.0;          ///< largest cost growth (refit / last build) the policy saw
    double total_ms() const noexcept { return vertex_ms + refit_ms + rebuild_ms + quantize_ms + top_level_ms; }
};

/// Rebuilding dynamic objects' trees on the device when refitting has made them poor
/// (DeviceScene's rebuild stage). Off by default: with it, each dynamic object's ranges of
/// the node and block arrays hold any tree over its triangles (DeviceBuilder::node_capacity,
/// block_capacity: about 420 bytes per triangle), and refits run one-pass.
struct DeviceRebuild {
    bool enabled = false;
    /// Per object: rebuild when the refitted tree's SAH cost (rk_tree_cost: the wide tree's,
    /// blocks as leaf weight) over the cost after its last build passes the threshold.
    RebuildPolicy policy{};
    DeviceBuildConfig build{};  ///< what the device builds (PLOC; cl/device_build.hpp)
};

/// A DeviceScene's device arrays and top level, whatever its hooks: what other
/// device stages (the renderer, cl/render.hpp) bind. Made only by DeviceScene.
class DeviceSceneArrays {
public:
    DeviceSceneArrays(const DeviceSceneArrays&) = delete;
    DeviceSceneArrays& operator=(const DeviceSceneArrays&) = delete;

    /// The device its arrays live on.
    Device& device() const noexcept { return *dev_; }
    /// The Scene it mirrors (instances are read from it at each update()).
    const Scene& scene() const noexcept { return *scene_; }
    /// Where each object lies in the concatenated arrays (object order).
    const std::vector<ObjectRecord>& object_records() const noexcept { return records_; }
    /// Object root boxes as of the last update() (device-refitted for dynamic objects).
    const std::vector<AABB>& root_boxes() const noexcept { return roots_; }
    /// The top-level tree of the last update().
    const Bvh& top_level() const noexcept { return top_; }

    // The arrays as kernels bind them (kernels/raykit/kernels/trace.hpp's RK_SCENE_PARAMS order).
    /// Every object's tree nodes (device_tree()), at its node_offset; with quantized nodes only
    /// the dynamic objects' (they come first).
    const Buffer<DeviceNode>& nodes() const noexcept { return nodes_; }
    /// The form of the nodes the walks read (NodeForm::full unless asked for and possible).
    NodeForm node_form() const noexcept { return form_; }
    /// The nodes quantized (NodeForm::quantized; empty otherwise), at the same indices.
    const Buffer<QuantizedNode>& quantized_nodes() const noexcept { return qnodes_; }
    /// The nodes the walks read, in node_form(): the trace kernels' node argument.
    const ::cl::Buffer& walk_nodes() const noexcept {
        return form_ == NodeForm::quantized ? qnodes_.handle() : nodes_.handle();
    }
    /// Every object's leaves' triangle blocks (DeviceTree::blocks), at its block_offset.
    const Buffer<TriangleBlock4>& blocks() const noexcept { return blocks_; }
    /// Every object's triangles (vertex indices relative to the object), at its triangle_offset.
    const Buffer<Triangle>& triangles() const noexcept { return triangles_; }
    /// Every object's current positions (3 floats each), at its vertex_offset.
    const Buffer<float>& positions() const noexcept { return positions_; }
    /// Every object's vertex records at its vertex_offset (moved ones as last moved).
    const Buffer<Vertex>& vertices() const noexcept { return vertices_; }
    /// One ObjectRecord per object, in object order.
    const Buffer<ObjectRecord>& objects() const noexcept { return objects_; }
    /// The top-level tree's nodes (top_count() of them) as of the last update().
    const Buffer<Node>& top_nodes() const noexcept { return top_nodes_; }
    /// The top-level tree's leaf slots: instance indices.
    const Buffer<std::uint32_t>& top_ids() const noexcept { return top_ids_; }
    /// One InstanceRecord per instance, as of the last update().
    const Buffer<InstanceRecord>& instances() const noexcept { return instances_; }
    /// Nodes of the top-level tree (0: nothing to trace).
    std::uint32_t top_count() const noexcept { return top_count_; }

    /// Throws std::logic_error unless update() ran and no instance was added or moved since.
    void require_fresh() const {
        if (!fresh_) throw std::logic_error("raykit::cl::DeviceScene: call update() before tracing");
        if (scene_->instances().size() != instance_count_)
            throw std::logic_error("raykit::cl::DeviceScene: instances changed since update()");
        if (scene_->instance_revision() != instance_revision_)
            throw std::logic_error("raykit::cl::DeviceScene: an instance moved (Scene::set_transform) since "
                                   "update(); call update() before tracing");
    }

protected:
    DeviceSceneArrays(Device& dev, const Scene& scene) : dev_(&dev), scene_(&scene) {}
    ~DeviceSceneArrays() = default;

    Device* dev_;
    const Scene* scene_;
    std::vector<ObjectRecord> records_;
    std::vector<AABB> roots_;
    bool fresh_ = false;
    NodeForm form_ = NodeForm::full;
    Buffer<DeviceNode> nodes_;
    Buffer<QuantizedNode> qnodes_;
    Buffer<TriangleBlock4> blocks_;
    Buffer<Triangle> triangles_;
    Buffer<float> positions_;
    Buffer<ObjectRecord> objects_;
    Buffer<Vertex> vertices_;  ///< every object's vertex records (at vertex_offset), moved ones included
    Bvh top_;
    std::uint32_t top_count_ = 0;
    std::size_t instance_count_ = 0;
    std::uint64_t instance_revision_ = 0;  ///< Scene::instance_revision() as of the last update()
    Buffer<Node> top_nodes_;
    Buffer<std::uint32_t> top_ids_;
    Buffer<InstanceRecord> instances_;
};

template <VertexHook... Hooks>
class DeviceScene : public DeviceSceneArrays {
    using HookList = std::tuple<Hooks...>;
    static constexpr std::size_t kHooks = sizeof...(Hooks);

    template <class H, std::size_t... I>
    static constexpr std::size_t index_of(std::index_sequence<I...>) {
        std::size_t r = kHooks;
        ((std::is_same_v<H, std::tuple_element_t<I, HookList>> ? (r = I, 0) : 0), ...);
        return r;
    }
    template <class H>
    static constexpr std::size_t hook_index = index_of<H>(std::make_index_sequence<kHooks>{});

public:
    /// Uploads `scene` (see the top of this file); the walks read nodes of the form `form`
    /// where every tree allows it (leaves of at most 255 blocks, and device rebuilds that make
    /// none larger), else full ones: node_form().
    DeviceScene(Device& dev, const Scene& scene, const DeviceRebuild& rebuild = {}, NodeForm form = NodeForm::full)
        : DeviceSceneArrays(dev, scene), rebuild_(rebuild) {
        if (rebuild_.enabled && !dev.info().fp64)
            throw std::invalid_argument("raykit::cl::DeviceScene: device rebuilds need cl_khr_fp64 (DeviceBuilder)");
        const auto& objs = scene.objects();
        if (objs.size() >= 0xFFFFFFFFu) throw std::length_error("raykit::cl::DeviceScene: too many objects");
        records_.resize(objs.size());
        block_count_.resize(objs.size());
        hook_of_.assign(objs.size(), kNoHook);
        params_.resize(objs.size());
        std::vector<DeviceNode> nodes;
        std::vector<TriangleBlock4> blocks;
        std::vector<Triangle> tris;
        std::vector<float> pos;
        std::vector<std::vector<DeviceNode>> dynamic_trees;
        std::vector<Vertex> verts, rest;
        std::vector<RefitTree> trees;
        auto add = [&](std::uint32_t i) {
            const SceneObject& o = objs[i];
            ObjectRecord& r = records_[i];
            DeviceTree tree = device_tree(o.blocks);
            r.node_offset = checked(nodes.size());
            r.node_count = checked(tree.nodes.size());
            r.block_offset = checked(blocks.size());
            r.triangle_offset = checked(tris.size());
            r.vertex_offset = checked(pos.size() / 3);
            r.vertex_count = checked(o.mesh.positions.size());
            r.triangle_count = checked(o.mesh.triangles.size());
            nodes.insert(nodes.end(), tree.nodes.begin(), tree.nodes.end());
            blocks.insert(blocks.end(), tree.blocks.begin(), tree.blocks.end());
            block_count_[i] = checked(tree.blocks.size());
            std::uint32_t capacity = 0;
            if (o.dynamic() && rebuild_.enabled) {  // room for any tree over its triangles
                DeviceNode empty;
                for (int c = 0; c < kDeviceWidth; ++c) empty.clear(c);
                capacity = checked(DeviceBuilder::node_capacity(o.mesh.triangles.size()));
                nodes.resize(r.node_offset + std::size_t(capacity), empty);
                blocks.resize(r.block_offset + DeviceBuilder::block_capacity(o.mesh.triangles.size()), TriangleBlock4{});
            }
            tris.insert(tris.end(), o.mesh.triangles.begin(), o.mesh.triangles.end());
            for (const vec3& p : o.mesh.positions) pos.insert(pos.end(), {p.x, p.y, p.z});
            checked(pos.size() / 3);
            for (std::size_t v = 0; v < o.mesh.positions.size(); ++v)
                verts.push_back({o.mesh.positions[v], o.mesh.normals.empty() ? vec3(0.0f) : o.mesh.normals[v],
                                 o.mesh.texcoords.empty() ? vec2(0.0f) : o.mesh.texcoords[v]});
            if (o.dynamic()) {
                dynamic_.push_back(i);
                rest_offset_.push_back(checked(rest.size()));
                rest.insert(rest.end(), o.rest.begin(), o.rest.end());
                trees.push_back({{}, i, r.node_offset, capacity});
                dynamic_trees.push_back(std::move(tree.nodes));
            }
        };
        for (std::uint32_t i = 0; i < objs.size(); ++i)
            if (objs[i].dynamic()) add(i);
        dynamic_node_end_ = checked(nodes.size());  // the dynamic trees' ranges, capacity included
        for (std::uint32_t i = 0; i < objs.size(); ++i)
            if (!objs[i].dynamic()) add(i);
        roots_.resize(objs.size());
        for (std::uint32_t i = 0; i < objs.size(); ++i) roots_[i] = objs[i].bounds();

        for (std::size_t d = 0; d < trees.size(); ++d) trees[d].nodes = dynamic_trees[d];
        if (form == NodeForm::quantized &&
            !(rebuild_.enabled && (rebuild_.build.leaf.leaf_limit() + 3) / 4 > 255u)) {
            if (std::optional<std::vector<QuantizedNode>> q = quantize_nodes(nodes)) {
                qnodes_ = Buffer<QuantizedNode>(dev, *q);
                form_ = NodeForm::quantized;
            }
        }
        // quantized: the full nodes only for the dynamic trees, which refit (and rebuild) them
        nodes_ = Buffer<DeviceNode>(dev, std::span<const DeviceNode>(nodes.data(), form_ == NodeForm::quantized
                                                                                      ? dynamic_node_end_
                                                                                      : nodes.size()));
        blocks_ = Buffer<TriangleBlock4>(dev, blocks);
        triangles_ = Buffer<Triangle>(dev, tris, CL_MEM_READ_ONLY);
        positions_ = Buffer<float>(dev, pos);
        objects_ = Buffer<ObjectRecord>(dev, records_, CL_MEM_READ_ONLY);
        vertices_ = Buffer<Vertex>(dev, verts);
        if (!dynamic_.empty()) {
            rest_ = Buffer<Vertex>(dev, rest, CL_MEM_READ_ONLY);
            refit_plan_ = RefitPlan(dev, trees);
            which_roots_ = Buffer<std::uint32_t>(dev, dynamic_, CL_MEM_READ_ONLY);
            root_boxes_ = Buffer<AABB>(dev, dynamic_.size());
            if (rebuild_.enabled) {
                policies_.assign(dynamic_.size(), rebuild_.policy);
                costs_ = Buffer<float>(dev, dynamic_.size());
                std::vector<std::uint32_t> counts;
                for (std::uint32_t o : dynamic_) counts.push_back(records_[o].node_count);
                node_counts_ = Buffer<std::uint32_t>(dev, counts);
                baselines_pending_ = true;
            }
        }
    }
    DeviceScene(const DeviceScene&) = delete;
    DeviceScene& operator=(const DeviceScene&) = delete;

    /// Hook H (one of Hooks...) moves dynamic object `object` with `params`
    /// from the next update() on (calling it again just changes the params).
    template <class H>
    void set_hook(std::uint32_t object, const typename H::Params& params) {
        static_assert(hook_index<H> < kHooks, "H is not one of this DeviceScene's hooks");
        require_dynamic(object, "set_hook");
        if (hook_of_[object] != hook_index<H>) {
            hook_of_[object] = hook_index<H>;
            tables_dirty_ = true;
        }
        params_[object].resize(sizeof(params));
        std::memcpy(params_[object].data(), &params, sizeof(params));
    }
    /// Uploads global buffer `slot` of buffer hook H (see H::buffers in
    /// cl/hook.hpp): the elements must have the layout of the OpenCL C type
    /// H::buffers[slot]. Reuses the device allocation when it is large
    /// enough (no allocation for a per-frame upload of the same size).
    /// Takes effect from the next update(). Throws std::out_of_range for a
    /// slot >= the hook's buffer count.
    template <class H, class T>
    void set_hook_buffer(std::size_t slot, std::span<const T> data) {
        static_assert(hook_index<H> < kHooks, "H is not one of this DeviceScene's hooks");
        static_assert(std::is_trivially_copyable_v<T>, "hook buffers hold trivially copyable types");
        if (slot >= hook_buffer_count<H>())
            throw std::out_of_range(std::string("raykit::cl::DeviceScene::set_hook_buffer: hook ") + H::name + " has " +
                                    std::to_string(hook_buffer_count<H>()) + " buffers, no slot " + std::to_string(slot));
        HookState& hs = hooks_[hook_index<H>];
        if (hs.buffers.size() < hook_buffer_count<H>()) {
            hs.buffers.resize(hook_buffer_count<H>());
            hs.buffer_set.resize(hook_buffer_count<H>(), false);
        }
        const std::span<const std::byte> bytes(reinterpret_cast<const std::byte*>(data.data()), data.size_bytes());
        hs.buffers[slot].reserve(*dev_, bytes.size(), CL_MEM_READ_ONLY);
        hs.buffers[slot].write(*dev_, bytes);
        hs.buffer_set[slot] = true;
    }
    template <class H, class T>
    void set_hook_buffer(std::size_t slot, const std::vector<T>& data) {
        set_hook_buffer<H, T>(slot, std::span<const T>(data));
    }

    /// Object no longer moved by a hook (it keeps its current vertices).
    void clear_hook(std::uint32_t object) {
        require_dynamic(object, "clear_hook");
        if (hook_of_[object] != kNoHook) {
            hook_of_[object] = kNoHook;
            tables_dirty_ = true;
        }
    }
    /// Writes a dynamic object's positions directly (e.g. CPU skinning); the
    /// next update() refits.
    void set_positions(std::uint32_t object, std::span<const vec3> positions) {
        require_dynamic(object, "set_positions");
        if (positions.size() != records_[object].vertex_count)
            throw std::invalid_argument("raykit::cl::DeviceScene::set_positions: wrong vertex count");
        positions_.write(*dev_, float_span(positions), std::size_t(records_[object].vertex_offset) * 3);
        moved_by_host_ = true;
    }

    /// Runs the frame's stages (see the top of this file).
    FrameTimes update(RefitMethod method = RefitMethod::one_pass, TopLevelUpdate top = TopLevelUpdate::rebuild) {
        if (rebuild_.enabled && method == RefitMethod::level_wise)
            throw std::invalid_argument("raykit::cl::DeviceScene::update: device rebuilds refit one-pass (level-wise "
                                        "refit needs the host's level tables)");
        using clock = std::chrono::steady_clock;
        auto ms = [](clock::time_point a) { return std::chrono::duration<double, std::milli>(clock::now() - a).count(); };
        if (!dynamic_.empty()) ensure_program();  // a static scene launches nothing here (built at its first trace)
        if (baselines_pending_) {  // the uploaded trees' costs start the rebuild policies
            const std::vector<float> cost = tree_costs();
            for (std::size_t d = 0; d < dynamic_.size(); ++d) policies_[d].reset(cost[d]);
            baselines_pending_ = false;
        }
        FrameTimes ft;
        auto t0 = clock::now();
        const bool moved = run_vertex_stage() || moved_by_host_;
        moved_by_host_ = false;
        dev_->finish();
        ft.vertex_ms = ms(t0);
        t0 = clock::now();
        if (moved) {
            launches_.refit += refit_plan_.run(*dev_, refit_kernels_, method, refit_buffers());
            dev_->finish();
        }
        ft.refit_ms = ms(t0);
        t0 = clock::now();
        if (moved && rebuild_.enabled) rebuild_stage(ft);
        ft.rebuild_ms = ms(t0);
        t0 = clock::now();
        if (moved && form_ == NodeForm::quantized) {
            quantize_dynamic();
            dev_->finish();
        }
        ft.quantize_ms = ms(t0);
        t0 = clock::now();
        if (moved) gather_roots();
        update_top_level(top);
        dev_->finish();
        ft.top_level_ms = ms(t0);
        fresh_ = true;
        return ft;
    }

    /// Only the refit stage (all dynamic trees), e.g. to time or compare methods.
    void refit(RefitMethod method) {
        ensure_program();
        launches_.refit += refit_plan_.run(*dev_, refit_kernels_, method, refit_buffers());
        quantize_dynamic();
    }

    // ------------------------------------------------------------ tracing

    /// Whether closest() and any() walk rays as packets (packet_walk_default: on CPU devices);
    /// the answers are the same either way.
    bool packet_walk() const noexcept { return packets_; }
    /// Turns the packet walk on or off (the program is rebuilt with it when first needed).
    void set_packet_walk(bool on) noexcept { packets_ = on; }

    void closest(const Buffer<Ray>& rays, Buffer<Hit>& hits, std::size_t n) {
        prepare_trace(rays, n);
        hits.reserve(*dev_, n);
        ::cl::Kernel& k = trace_kernels_.pick(false, packets_);
        set_args(k, top_nodes_, top_count_, top_ids_, instances_, objects_, walk_nodes(), blocks_, triangles_, rays,
                 hits, static_cast<std::uint32_t>(n));
        launches_.trace += launch(dev_->queue(), k, trace_items(n, packets_), kTraceGroupSize);
    }
    void any(const Buffer<Ray>& rays, Buffer<std::uint32_t>& occluded, std::size_t n) {
        prepare_trace(rays, n);
        occluded.reserve(*dev_, n);
        ::cl::Kernel& k = trace_kernels_.pick(true, packets_);
        set_args(k, top_nodes_, top_count_, top_ids_, instances_, objects_, walk_nodes(), blocks_, triangles_, rays,
                 occluded, static_cast<std::uint32_t>(n));
        launches_.trace += launch(dev_->queue(), k, trace_items(n, packets_), kTraceGroupSize);
    }
    std::vector<Hit> closest(std::span<const Ray> rays) {
        Buffer<Ray> r(*dev_, rays, CL_MEM_READ_ONLY);
        Buffer<Hit> h(*dev_, rays.size(), CL_MEM_WRITE_ONLY);
        closest(r, h, rays.size());
        return h.read(*dev_);
    }
    std::vector<std::uint32_t> any(std::span<const Ray> rays) {
        Buffer<Ray> r(*dev_, rays, CL_MEM_READ_ONLY);
        Buffer<std::uint32_t> o(*dev_, rays.size(), CL_MEM_WRITE_ONLY);
        any(r, o, rays.size());
        return o.read(*dev_);
    }
    /// Camera rays on the device (bit-identical to CameraFrame::ray).
    void camera_rays(const CameraFrame& frame, Buffer<Ray>& rays, float jx = 0.5f, float jy = 0.5f) {
        ensure_program();
        cl::camera_rays(*dev_, k_camera_, frame, rays, jx, jy);
        ++launches_.camera;
    }

    // ------------------------------------------------------------ inspection

    // the whole arrays (DeviceSceneArrays), next to the per-object reads below
    using DeviceSceneArrays::blocks;
    using DeviceSceneArrays::nodes;
    using DeviceSceneArrays::positions;
    using DeviceSceneArrays::quantized_nodes;

    const LaunchCounts& launches() const noexcept { return launches_; }
    const Program& program() {
        ensure_program();
        return program_;
    }
    /// Names of the hooks compiled into the current program.
    std::vector<std::string> compiled_hooks() {
        ensure_program();
        std::vector<std::string> n;
        for_each_hook([&]<std::size_t I>() {
            if (used_ & (1ull << I)) n.push_back(std::tuple_element_t<I, HookList>::name);
        });
        return n;
    }
    /// An object's current device positions / tree nodes / moved vertices.
    std::vector<vec3> positions(std::uint32_t object) {
        const ObjectRecord& r = records_.at(object);
        std::vector<vec3> out(r.vertex_count);
        if (!out.empty()) positions_.read(*dev_, std::span<float>(reinterpret_cast<float*>(out.data()), out.size() * 3), std::size_t(r.vertex_offset) * 3);
        return out;
    }
    /// (With quantized nodes a static object has no full nodes on the device: std::logic_error.)
    std::vector<DeviceNode> nodes(std::uint32_t object) {
        const ObjectRecord& r = records_.at(object);  // node_count: the current tree's (after device rebuilds too)
        if (form_ == NodeForm::quantized && r.node_offset >= dynamic_node_end_ && r.node_count > 0)
            throw std::logic_error("raykit::cl::DeviceScene::nodes: a static object's nodes are only quantized "
                                   "on the device (quantized_nodes)");
        std::vector<DeviceNode> out(r.node_count);
        if (!out.empty()) nodes_.read(*dev_, std::span<DeviceNode>(out), r.node_offset);
        return out;
    }
    /// An object's current tree nodes as the walk reads them when node_form() is quantized.
    std::vector<QuantizedNode> quantized_nodes(std::uint32_t object) {
        if (form_ != NodeForm::quantized) throw std::logic_error("raykit::cl::DeviceScene::quantized_nodes: full nodes");
        const ObjectRecord& r = records_.at(object);
        std::vector<QuantizedNode> out(r.node_count);
        if (!out.empty()) qnodes_.read(*dev_, std::span<QuantizedNode>(out), r.node_offset);
        return out;
    }
    /// An object's current triangle blocks (its tree's leaves).
    std::vector<TriangleBlock4> blocks(std::uint32_t object) {
        const ObjectRecord& r = records_.at(object);
        std::vector<TriangleBlock4> out(block_count_.at(object));
        if (!out.empty()) blocks_.read(*dev_, std::span<TriangleBlock4>(out), r.block_offset);
        return out;
    }
    std::vector<Vertex> moved_vertices(std::uint32_t object) {
        (void)dynamic_slot(object, "moved_vertices");
        std::vector<Vertex> out(records_[object].vertex_count);
        vertices_.read(*dev_, std::span<Vertex>(out), records_[object].vertex_offset);
        return out;
    }
    const RefitPlan& refit_plan() const noexcept { return refit_plan_; }
    /// The rebuild settings it was made with.
    const DeviceRebuild& rebuild_settings() const noexcept { return rebuild_; }
    /// Launches of the device builder so far (its stages are many small kernels).
    std::size_t build_launches() const noexcept { return builder_.launches(); }
    std::size_t dynamic_object_count() const noexcept { return dynamic_.size(); }

private:
    static constexpr std::size_t kNoHook = ~std::size_t(0);

    template <class Fn>
    static void for_each_hook(Fn&& fn) {
        [&]<std::size_t... I>(std::index_sequence<I...>) { (fn.template operator()<I>(), ...); }(std::make_index_sequence<kHooks>{});
    }

    static std::uint32_t checked(std::size_t n) {
        if (n >= 0xFFFFFFFFu) throw std::length_error("raykit::cl::DeviceScene: scene too large for 32-bit indices");
        return static_cast<std::uint32_t>(n);
    }
    std::size_t dynamic_slot(std::uint32_t object, const char* what) const {
        for (std::size_t d = 0; d < dynamic_.size(); ++d)
            if (dynamic_[d] == object) return d;
        if (object >= records_.size())
            throw std::out_of_range(std::string("raykit::cl::DeviceScene::") + what + ": no object " + std::to_string(object));
        throw std::logic_error(std::string("raykit::cl::DeviceScene::") + what + ": object " + std::to_string(object) +
                               " is static");
    }
    void require_dynamic(std::uint32_t object, const char* what) const { (void)dynamic_slot(object, what); }
    RefitBuffers refit_buffers() {
        return {&nodes_, &blocks_, &triangles_, &positions_, &objects_};
    }

    std::uint64_t used_hooks() const {
        std::uint64_t m = 0;
        for (std::uint32_t o : dynamic_)
            if (hook_of_[o] != kNoHook) m |= 1ull << hook_of_[o];
        return m;
    }

    void ensure_program() {
        static_assert(kHooks <= 64, "at most 64 hooks");
        const std::uint64_t used = used_hooks();
        if (have_program_ && used == used_ && (!packets_ || trace_kernels_.packets)) return;
        std::vector<SourcePart> parts = base_parts();
        parts.push_back({"raykit/kernels/camera.hpp", kernels::kCamera});
        for (SourcePart& p : trace_parts(packets_, TraceKernels::scene, form_)) parts.push_back(std::move(p));
        if (!dynamic_.empty()) parts.push_back(refit_part());
        const bool requantize = !dynamic_.empty() && form_ == NodeForm::quantized;
        if (requantize) parts.push_back({"raykit/kernels/quantize.hpp", kernels::kQuantize});
        if (!dynamic_.empty() && rebuild_.enabled)
            for (SourcePart& b : build_parts(rebuild_.build.method)) parts.push_back(std::move(b));
        for_each_hook([&]<std::size_t I>() {
            if (used & (1ull << I)) {
                const auto hp = hook_parts<std::tuple_element_t<I, HookList>>();
                parts.insert(parts.end(), hp.begin(), hp.end());
            }
        });
        program_ = build_program(*dev_, assemble(parts), raykit_build_options(*dev_));
        trace_kernels_ = TraceKernelSet(program_, TraceKernels::scene, packets_);
        k_camera_ = program_.kernel("rk_camera_rays");
        if (requantize) k_quantize_ = program_.kernel("rk_quantize_nodes");
        if (!dynamic_.empty()) {
            refit_kernels_ = RefitKernels(program_);
            k_roots_ = program_.kernel("rk_gather_roots");
            if (rebuild_.enabled) {
                builder_ = DeviceBuilder(*dev_, program_, rebuild_.build);
                k_cost_ = program_.kernel("rk_tree_cost");
            }
        }
        for_each_hook([&]<std::size_t I>() {
            hooks_[I].kernel = (used & (1ull << I))
                                   ? program_.kernel(std::string("rk_vertex_stage_") + std::tuple_element_t<I, HookList>::name)
                                   : ::cl::Kernel();
        });
        used_ = used;
        have_program_ = true;
        tables_dirty_ = true;
    }

    /// Launches the vertex stage of every used hook; true when one ran.
    bool run_vertex_stage() {
        bool ran = false;
        for_each_hook([&]<std::size_t I>() {
            if (!(used_ & (1ull << I))) return;
            using H = std::tuple_element_t<I, HookList>;
            HookState& hs = hooks_[I];
            if (tables_dirty_) {
                std::vector<std::uint32_t> begin{0}, rest_off, pos_off;
                hs.objects.clear();
                for (std::size_t d = 0; d < dynamic_.size(); ++d) {
                    const std::uint32_t o = dynamic_[d];
                    if (hook_of_[o] != I) continue;
                    hs.objects.push_back(o);
                    rest_off.push_back(rest_offset_[d]);
                    pos_off.push_back(records_[o].vertex_offset);
                    begin.push_back(begin.back() + records_[o].vertex_count);
                }
                hs.total = begin.back();
                hs.begin = Buffer<std::uint32_t>(*dev_, begin, CL_MEM_READ_ONLY);
                hs.rest_offset = Buffer<std::uint32_t>(*dev_, rest_off, CL_MEM_READ_ONLY);
                hs.pos_offset = Buffer<std::uint32_t>(*dev_, pos_off, CL_MEM_READ_ONLY);
            }
            std::vector<typename H::Params> params(hs.objects.size());
            for (std::size_t k = 0; k < hs.objects.size(); ++k)
                std::memcpy(&params[k], params_[hs.objects[k]].data(), sizeof(typename H::Params));
            hs.params.reserve(*dev_, params.size() * sizeof(typename H::Params));
            hs.params.write(*dev_, std::span<const std::byte>(reinterpret_cast<const std::byte*>(params.data()),
                                                              params.size() * sizeof(typename H::Params)));
            set_args(hs.kernel, rest_, vertices_, positions_, hs.begin, hs.rest_offset, hs.pos_offset, hs.params,
                     static_cast<std::uint32_t>(hs.objects.size()), hs.total);
            if constexpr (hook_buffer_count<H>() > 0) {
                constexpr cl_uint kFirstBufferArg = 9;  // after `total` (kernels/raykit/kernels/vertex.hpp)
                for (std::size_t b = 0; b < hook_buffer_count<H>(); ++b) {
                    if (b >= hs.buffer_set.size() || !hs.buffer_set[b])
                        throw std::logic_error(std::string("raykit::cl::DeviceScene::update: hook ") + H::name +
                                               " buffer " + std::to_string(b) + " was never set (set_hook_buffer)");
                    detail::set_arg(hs.kernel, kFirstBufferArg + static_cast<cl_uint>(b), hs.buffers[b]);
                }
            }
            const bool l = launch(dev_->queue(), hs.kernel, hs.total, 64);
            launches_.vertex += l;
            ran = ran || l;
        });
        tables_dirty_ = false;
        return ran;
    }

    /// The dynamic trees' SAH costs (rk_tree_cost; one launch, one read of a float each).
    std::vector<float> tree_costs() {
        const auto m = static_cast<std::uint32_t>(dynamic_.size());
        set_args(k_cost_, nodes_, objects_, which_roots_, node_counts_, costs_, m);
        launches_.refit += launch(dev_->queue(), k_cost_, m, 64);
        return costs_.read(*dev_);
    }

    /// The rebuild stage: the policy per dynamic object, then a device build of each decided one
    /// (on the CPU when the device builder gives up), then the new trees' costs as baselines.
    void rebuild_stage(FrameTimes& ft) {
        std::vector<float> cost = tree_costs();
        bool any = false;
        rebuilt_now_.assign(dynamic_.size(), 0);
        for (std::size_t d = 0; d < dynamic_.size(); ++d) {
            ft.worst_growth = std::max(ft.worst_growth, policies_[d].growth(cost[d]));
            if (!policies_[d].should_rebuild(cost[d])) continue;
            rebuild_object(d, ft);
            any = true;
        }
        if (!any) return;
        cost = tree_costs();
        for (std::size_t d = 0; d < dynamic_.size(); ++d)
            if (rebuilt_now_[d]) policies_[d].reset(cost[d]);
    }

    void rebuild_object(std::size_t d, FrameTimes& ft) {
        const std::uint32_t o = dynamic_[d];
        ObjectRecord& r = records_[o];
        const DeviceBuildResult res =
            builder_.build(triangles_, positions_, r, o, {&nodes_, &blocks_, refit_plan_.tables()});
        std::uint32_t node_count = res.nodes, block_count = res.blocks;
        if (res.built) {
            refit_plan_.mark_rebuilt_on_device();
        } else {  // too deep for the device: the CPU twin (reads the positions back)
            const std::vector<vec3> pos = positions(o);
            const MeshView mesh(pos, scene_->objects()[o].mesh.triangles);
            const DeviceTree tree = device_tree(cpu_twin_build(mesh, rebuild_.build));
            nodes_.write(*dev_, std::span<const DeviceNode>(tree.nodes), r.node_offset);
            blocks_.write(*dev_, std::span<const TriangleBlock4>(tree.blocks), r.block_offset);
            refit_plan_.write_tree(*dev_, {tree.nodes, o, r.node_offset, checked(DeviceBuilder::node_capacity(r.triangle_count))});
            node_count = checked(tree.nodes.size());
            block_count = checked(tree.blocks.size());
            ++ft.rebuilt_on_host;
        }
        ++ft.rebuilt;
        rebuilt_now_[d] = 1;
        r.node_count = node_count;
        block_count_[o] = block_count;
        objects_.write(*dev_, std::span<const ObjectRecord>(&r, 1), o);
        node_counts_.write(*dev_, std::span<const std::uint32_t>(&node_count, 1), d);
    }

    /// With quantized nodes: the dynamic trees' current nodes quantized again (one launch over
    /// their ranges; nodes past a tree's count are left).
    void quantize_dynamic() {
        if (form_ != NodeForm::quantized || dynamic_.empty()) return;
        set_args(k_quantize_, nodes_, qnodes_, objects_, which_roots_, static_cast<std::uint32_t>(dynamic_.size()),
                 dynamic_node_end_);
        launches_.quantize += launch(dev_->queue(), k_quantize_, dynamic_node_end_, 64);
    }

    void gather_roots() {
        if (dynamic_.empty()) return;
        const auto n = static_cast<std::uint32_t>(dynamic_.size());
        set_args(k_roots_, nodes_, objects_, which_roots_, root_boxes_, n);
        launches_.top_level += launch(dev_->queue(), k_roots_, n, 64);
        const std::vector<AABB> boxes = root_boxes_.read(*dev_);
        for (std::size_t d = 0; d < dynamic_.size(); ++d) roots_[dynamic_[d]] = boxes[d];
    }

    void update_top_level(TopLevelUpdate mode) {
        const auto& insts = scene_->instances();
        std::vector<AABB> boxes(insts.size());
        std::vector<InstanceRecord> recs(insts.size());
        for (std::size_t i = 0; i < insts.size(); ++i) {
            if (insts[i].object >= records_.size())
                throw std::logic_error("raykit::cl::DeviceScene: an instance refers to an object added after the DeviceScene");
            boxes[i] = transformed_box(roots_[insts[i].object], insts[i].transform);
            recs[i].world_to_object = insts[i].to_object;
            recs[i].object_to_world = insts[i].to_world;
            recs[i].object = insts[i].object;
            recs[i].identity = insts[i].identity ? 1u : 0u;
        }
        if (mode == TopLevelUpdate::refit && top_.prim_ids.size() == insts.size() && !insts.empty())
            raykit::refit(top_, [&](std::uint32_t i) { return boxes[i]; });
        else
            top_ = Scene::build_top_level(boxes, scene_->top_level_config());
        top_count_ = checked(top_.nodes.size());
        top_nodes_.reserve(*dev_, top_.nodes.size());
        top_nodes_.write(*dev_, std::span<const Node>(top_.nodes.data(), top_.nodes.size()));
        top_ids_.reserve(*dev_, top_.prim_ids.size());
        top_ids_.write(*dev_, top_.prim_ids);
        instances_.reserve(*dev_, recs.size());
        instances_.write(*dev_, recs);
        instance_count_ = insts.size();
        instance_revision_ = scene_->instance_revision();
    }

    void prepare_trace(const Buffer<Ray>& rays, std::size_t n) {
        require_fresh();
        if (n > rays.size()) throw std::out_of_range("raykit::cl::DeviceScene: more rays asked for than the buffer holds");
        if (n > 0xFFFFFFFFu) throw std::length_error("raykit::cl::DeviceScene: more than 2^32 rays in one launch");
        ensure_program();
    }

    struct HookState {
        std::vector<std::uint32_t> objects;
        std::uint32_t total = 0;
        Buffer<std::uint32_t> begin, rest_offset, pos_offset;
        Buffer<std::byte> params;
        std::vector<Buffer<std::byte>> buffers;  ///< H::buffers, set by set_hook_buffer
        std::vector<bool> buffer_set;
        ::cl::Kernel kernel;
    };

    std::vector<std::uint32_t> dynamic_;      ///< scene object indices of dynamic objects
    std::vector<std::uint32_t> rest_offset_;  ///< per dynamic slot, into rest_/moved_
    std::vector<std::size_t> hook_of_;        ///< per object: hook index or kNoHook
    std::vector<std::vector<std::byte>> params_;
    std::array<HookState, kHooks> hooks_{};
    bool tables_dirty_ = true, have_program_ = false, moved_by_host_ = false;
    std::uint64_t used_ = 0;

    Program program_;
    TraceKernelSet trace_kernels_;
    ::cl::Kernel k_camera_, k_roots_, k_quantize_;
    std::uint32_t dynamic_node_end_ = 0;  ///< nodes [0, this) belong to dynamic objects (capacity included)
    bool packets_ = packet_walk_default(*dev_);  ///< see packet_walk()
    RefitKernels refit_kernels_;
    RefitPlan refit_plan_;
    DeviceRebuild rebuild_;
    DeviceBuilder builder_;
    ::cl::Kernel k_cost_;
    std::vector<RebuildPolicy> policies_;      ///< per dynamic slot
    std::vector<std::uint8_t> rebuilt_now_;    ///< per dynamic slot, this update
    std::vector<std::uint32_t> block_count_;   ///< per object: blocks of its current tree
    Buffer<float> costs_;
    Buffer<std::uint32_t> node_counts_;        ///< per dynamic slot: nodes of its current tree
    bool baselines_pending_ = false;

    Buffer<Vertex> rest_;
    Buffer<std::uint32_t> which_roots_;
    Buffer<AABB> root_boxes_;

    LaunchCounts launches_;
};

}  // namespace raykit::cl
