// raykit/scene/scene.hpp — a two-level scene: objects, instances, top-level BVH.
//
//   Scene scene;
//   std::uint32_t rock = scene.add_object(make_icosphere(3));                 // static
//   std::uint32_t flag = scene.add_object(cloth, ObjectKind::dynamic);
//   scene.add_instance(rock, glm::translate(mat4(1), vec3(2, 0, 0)));
//   scene.add_instance(flag);
//   ...per frame:
//   scene.move_vertices(flag, [&](const Vertex& v, std::uint32_t i) { return wave(v, i, params); });
//   scene.set_transform(1, spin(time));
//   scene.update_top_level();                     // rebuild (or refit) over instance world boxes
//   Hit h = scene.intersect_closest(ray);         // h.inst = instance, h.prim = triangle of its object
//
// An object is a Mesh with its own bottom-level tree, built once by
// BinnedSahBuilder (by default with BlockBvh8::sah_config(): leaf cost in
// blocks of 4, leaves up to 12) and kept in two forms: the binary Bvh and
// the BlockBvh8 made from it (8-wide nodes, 4-triangle blocks: what every CPU
// query walks, the fastest CPU path, and what the device uploads and refits;
// see scene/block_bvh.hpp, cl/device_tree.hpp). A static object never changes after add_object(). A
// dynamic object keeps an untouched rest copy of its vertices (position,
// normal, uv): move_vertices() computes every current vertex from its rest
// vertex — never from last frame's — and refits both forms in place (topology
// kept); rebuild_object() builds both anew from the current vertices.
//
// An instance places an object with an affine transform (mat4 whose last row
// is 0 0 0 1). Rays are traced in object space: the world ray is mapped by
// the inverse transform (origin as a point, direction as a vector, not
// normalised), so t is the same parameter in both spaces and hits of
// different instances compare directly. Both maps are stored as row-major
// 3x4 float matrices (Affine) and applied with explicit fused multiply-adds,
// so the OpenCL kernels, which do the same, get the same object-space rays
// bit for bit.
//
// The top-level BVH is built with BinnedSahBuilder over the instances' world
// boxes (the object's root box, its 8 corners transformed in double, rounded
// outwards and padded by 2^-20 of the largest coordinate, so rounding in
// the object-space ray cannot lose a hit at the box boundary).
// update_top_level() must be called after add_instance(), set_transform() or
// move_vertices() and before tracing; tracing a stale scene throws.
//
// Ties: smaller t wins, then the smaller instance, then the smaller triangle
// (Hit::closer_than), whatever the tree.
//
// Queries are closest_hit / any_hit of scene/trace.hpp: the top-level tree
// over a leaf store of instances, whose leaves run closest_hit / any_hit on
// the object's tree (SceneTrees::blocks, the default, or the binary Bvh with
// SceneTrees::binary: the same answers, the binary tree's node counts). An
// optional filter keep(instance, prim, u, v) rejects candidate hits (alpha
// cut-outs); optional TraversalStats count the bottom-level trees' nodes and
// leaves (the top level is not counted, so a one-instance scene counts what
// its object's tree alone would). An instance whose transform is the identity
// traces the world ray itself (no mapping, so -0 stays -0).
//
// Range (math/limits.hpp): object vertices (add_object, move_vertices,
// set_positions) and instance world boxes (update_top_level) beyond ±2^32
// throw std::domain_error. Rays are traced in object space, so an instance
// whose inverse transform magnifies (an object scaled down) maps world rays
// to larger object-space origins and directions: keep those within the same
// rule (check_ray on object_ray()); it is not checked per ray.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "raykit/bvh/binned_sah.hpp"
#include "raykit/bvh/refit.hpp"
#include "raykit/bvh/traverse.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/math/limits.hpp"
#include "raykit/scene/block_bvh.hpp"
#include "raykit/scene/build.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/scene/trace.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

/// One vertex as vertex stages see it. 32 bytes; crosses to OpenCL as rk_vertex.
struct Vertex {
    vec3 position{0.0f};
    vec3 normal{0.0f};
    vec2 uv{0.0f};
};
static_assert(sizeof(Vertex) == 32 && alignof(Vertex) == 4);
static_assert(offsetof(Vertex, position) == 0 && offsetof(Vertex, normal) == 12 && offsetof(Vertex, uv) == 24);

/// Row-major 3x4 affine map: row r is m[4r .. 4r+3]; p' = M·(p, 1).
struct Affine {
    float m[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};

    /// The upper 3x4 of an affine mat4 (glm, column-major). Throws
    /// std::invalid_argument when the last row is not (0, 0, 0, 1) or an
    /// entry is not finite.
    static Affine from_mat4(const mat4& t) {
        check_affine(t);
        Affine a;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) a.m[4 * r + c] = t[c][r];
        return a;
    }
    /// The inverse of an affine mat4, computed in double and rounded once.
    /// Throws std::invalid_argument for a singular or non-affine matrix.
    static Affine inverse_of(const mat4& t) {
        check_affine(t);
        const glm::dmat4 d(t);
        const double det = glm::determinant(glm::dmat3(d));
        if (!(std::fabs(det) > 0.0) || !std::isfinite(det))
            throw std::invalid_argument("raykit::Affine: transform is singular");
        const glm::dmat4 inv = glm::inverse(d);
        Affine a;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) a.m[4 * r + c] = static_cast<float>(inv[c][r]);
        return a;
    }

    /// M·(p, 1), each row as fma(m0, x, fma(m1, y, fma(m2, z, m3))).
    vec3 point(const vec3& p) const noexcept {
        vec3 o;
        for (int r = 0; r < 3; ++r) {
            const float* row = m + 4 * r;
            o[r] = std::fma(row[0], p.x, std::fma(row[1], p.y, std::fma(row[2], p.z, row[3])));
        }
        return o;
    }
    /// M·(d, 0), each row as fma(m0, x, fma(m1, y, m2·z)).
    vec3 vector(const vec3& d) const noexcept {
        vec3 o;
        for (int r = 0; r < 3; ++r) {
            const float* row = m + 4 * r;
            o[r] = std::fma(row[0], d.x, std::fma(row[1], d.y, row[2] * d.z));
        }
        return o;
    }

private:
    static void check_affine(const mat4& t) {
        if (t[0][3] != 0.0f || t[1][3] != 0.0f || t[2][3] != 0.0f || t[3][3] != 1.0f)
            throw std::invalid_argument("raykit::Affine: transform is not affine (last row must be 0 0 0 1)");
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r)
                if (!std::isfinite(t[c][r])) throw std::invalid_argument("raykit::Affine: transform is not finite");
    }
};
static_assert(sizeof(Affine) == 48);

enum class ObjectKind { static_object, dynamic };

/// How a dynamic object's trees follow its moved vertices.
enum class TreeUpdate { refit, rebuild };

struct SceneObject {
    Mesh mesh;  ///< current geometry (for a dynamic object: as last moved)
    Bvh bvh;           ///< the built tree (blocks is made from it)
    BlockBvh8 blocks;  ///< made from bvh: what CPU queries walk
    BinnedSahBuilder::Config config;  ///< how bvh was built (rebuild_object builds the same way)
    ObjectKind kind = ObjectKind::static_object;
    std::vector<Vertex> rest;  ///< dynamic objects: the untouched rest vertices
    bool moved = false;        ///< vertices written, trees not yet updated (Scene::update_object)

    bool dynamic() const noexcept { return kind == ObjectKind::dynamic; }
    /// Root box of the bottom-level tree (empty for an empty object).
    AABB bounds() const noexcept { return bvh.nodes.empty() ? AABB{} : bvh.nodes[0].box; }
};

struct SceneInstance {
    std::uint32_t object = 0;
    mat4 transform{1.0f};
    Affine to_world;   ///< transform
    Affine to_object;  ///< its inverse
    bool identity = true;  ///< transform is the identity: rays are not mapped
};

/// Which bottom-level form a Scene query walks (same answers; see the header comment).
enum class SceneTrees { blocks, binary };

/// How update_top_level() brings the top-level tree up to date.
enum class TopLevelUpdate { rebuild, refit };

/// World box of an object box under an affine transform: corners mapped in
/// double, rounded outwards, padded by 2^-20 of the largest magnitude.
inline AABB transformed_box(const AABB& box, const mat4& transform) {
    if (box.is_empty()) return {};
    const glm::dmat4 t(transform);
    glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-std::numeric_limits<double>::infinity());
    for (int k = 0; k < 8; ++k) {
        const glm::dvec4 c((k & 1) ? box.max.x : box.min.x, (k & 2) ? box.max.y : box.min.y,
                           (k & 4) ? box.max.z : box.min.z, 1.0);
        const glm::dvec3 w(t * c);
        lo = glm::min(lo, w);
        hi = glm::max(hi, w);
    }
    const double mag = std::max({std::fabs(lo.x), std::fabs(lo.y), std::fabs(lo.z), std::fabs(hi.x),
                                 std::fabs(hi.y), std::fabs(hi.z)});
    const double pad = mag * 0x1p-20;
    AABB out;
    for (int a = 0; a < 3; ++a) {
        out.min[a] = next_float_down(static_cast<float>(lo[a] - pad));
        out.max[a] = next_float_up(static_cast<float>(hi[a] + pad));
    }
    return out;
}

class Scene {
public:
    /// Adds an object; builds its trees with `cfg`. Returns its index.
    std::uint32_t add_object(Mesh mesh, ObjectKind kind = ObjectKind::static_object,
                             const BinnedSahBuilder::Config& cfg = BlockBvh8::sah_config()) {
        check_mesh(mesh);
        Bvh bvh = build_bvh<BinnedSahBuilder>(mesh, cfg);
        return add(std::move(mesh), std::move(bvh), kind, cfg);
    }
    /// Adds an object with a tree built elsewhere over `mesh` (any builder);
    /// rebuild_object() rebuilds it with BlockBvh8::sah_config(threads).
    /// Throws std::invalid_argument when the tree does not cover the mesh.
    std::uint32_t add_object(Mesh mesh, Bvh bvh, ObjectKind kind = ObjectKind::static_object, unsigned threads = 0) {
        check_mesh(mesh);
        if (bvh.prim_ids.size() != mesh.triangles.size())
            throw std::invalid_argument("raykit::Scene::add_object: the tree covers " +
                                        std::to_string(bvh.prim_ids.size()) + " triangles, the mesh has " +
                                        std::to_string(mesh.triangles.size()));
        return add(std::move(mesh), std::move(bvh), kind, BlockBvh8::sah_config(threads));
    }

    /// Places `object` with an affine `transform`. Returns the instance index.
    std::uint32_t add_instance(std::uint32_t object, const mat4& transform = mat4(1.0f)) {
        if (object >= objects_.size()) throw std::out_of_range("raykit::Scene::add_instance: no object " + std::to_string(object));
        SceneInstance in;
        in.object = object;
        set(in, transform);
        instances_.push_back(in);
        stale_ = true;
        ++instance_revision_;
        return static_cast<std::uint32_t>(instances_.size() - 1);
    }

    void set_transform(std::uint32_t instance, const mat4& transform) {
        if (instance >= instances_.size())
            throw std::out_of_range("raykit::Scene::set_transform: no instance " + std::to_string(instance));
        set(instances_[instance], transform);
        stale_ = true;
        ++instance_revision_;
    }

    /// Vertex stage of a dynamic object: vertex i becomes fn(rest[i], i)
    /// (a Vertex); positions (and normals/uvs where the mesh has them) are
    /// written, then the object's trees are refitted (write_vertices, then
    /// update_object). Throws std::logic_error for a static object, and
    /// std::domain_error when a moved position is beyond ±2^32
    /// (math/limits.hpp; the object is then put back to its rest vertices,
    /// refitted, so it stays consistent).
    template <class Fn>
    void move_vertices(std::uint32_t object, Fn&& fn, unsigned threads = 0) {
        write_vertices(object, fn, threads);
        update_object(object, TreeUpdate::refit, threads);
    }

    /// The vertex stage alone: vertex i becomes fn(rest[i], i). The object's
    /// trees are out of date until update_object(); tracing or
    /// update_top_level() before that throws std::logic_error.
    template <class Fn>
    void write_vertices(std::uint32_t object, Fn&& fn, unsigned threads = 0) {
        SceneObject& o = dynamic_object(object, "write_vertices");
        Mesh& m = o.mesh;
        o.moved = true;
        stale_ = true;
        // below ~16k vertices a thread costs more to start than it saves (the goblin's 1.7k
        // vertices skin in ~40 us on one thread; two threads took 0.1-4 ms on a busy machine)
        parallel_for(
            o.rest.size(), threads,
            [&](std::size_t i) {
                const Vertex v = fn(static_cast<const Vertex&>(o.rest[i]), static_cast<std::uint32_t>(i));
                m.positions[i] = v.position;
                if (!m.normals.empty()) m.normals[i] = v.normal;
                if (!m.texcoords.empty()) m.texcoords[i] = v.uv;
            },
            kSerialVertices);
    }

    /// Brings a dynamic object's trees up to date after its vertices moved:
    /// refit both in place, or rebuild both (its config). The range check is one
    /// test of the new root box, not a pass over the vertices; on failure the
    /// vertices are searched to name the culprit, the object goes back to its
    /// rest vertices (refitted) and std::domain_error is thrown.
    void update_object(std::uint32_t object, TreeUpdate how, unsigned threads = 0) {
        SceneObject& o = dynamic_object(object, "update_object");
        Mesh& m = o.mesh;
        if (how == TreeUpdate::rebuild) {
            // a vertex out of range would make the builder throw first: check the refit's box instead
            refit_object(object, threads);
            if (root_in_range(o)) rebuild_object(object);
        } else {
            refit_object(object, threads);
        }
        o.moved = false;
        if (root_in_range(o)) return;
        std::string why = "raykit::Scene::move_vertices: the object's box leaves [-2^32, 2^32] (raykit/math/limits.hpp)";
        try {
            check_positions(m.positions, "raykit::Scene::move_vertices");
        } catch (const std::domain_error& e) {
            why = e.what();
        }
        for (std::size_t i = 0; i < o.rest.size(); ++i) {
            m.positions[i] = o.rest[i].position;
            if (!m.normals.empty()) m.normals[i] = o.rest[i].normal;
            if (!m.texcoords.empty()) m.texcoords[i] = o.rest[i].uv;
        }
        refit_object(object, threads);
        throw std::domain_error(why);
    }

    /// Sets a dynamic object's current positions directly (one per vertex;
    /// e.g. read back from a device vertex stage) and refits its tree.
    /// Throws (changing nothing) for a wrong count or a position beyond ±2^32.
    void set_positions(std::uint32_t object, const std::vector<vec3>& positions) {
        SceneObject& o = dynamic_object(object, "set_positions");
        if (positions.size() != o.mesh.positions.size())
            throw std::invalid_argument("raykit::Scene::set_positions: wrong vertex count");
        check_positions(positions, "raykit::Scene::set_positions");
        o.mesh.positions = positions;
        refit_object(object);
    }

    /// Refits one object's trees (binary and blocks) to its current positions, in place.
    void refit_object(std::uint32_t object, unsigned threads = 0) {
        SceneObject& o = objects_.at(object);
        const MeshView view(o.mesh);
        refit(o.bvh, [&](std::uint32_t i) { return view.bounds(i); });
        o.blocks.refit(view, threads);
        stale_ = true;
    }

    /// Builds one object's trees anew from its current positions (its config).
    void rebuild_object(std::uint32_t object) {
        SceneObject& o = objects_.at(object);
        o.bvh = build_bvh<BinnedSahBuilder>(o.mesh, o.config);
        o.blocks = BlockBvh8::build(o.mesh, o.bvh, o.config.threads);
        stale_ = true;
    }

    /// World box of an instance (see transformed_box()).
    AABB world_box(std::uint32_t instance) const {
        const SceneInstance& in = instances_.at(instance);
        return transformed_box(objects_[in.object].bounds(), in.transform);
    }

    /// Brings the top-level tree up to date: a new BinnedSahBuilder tree over
    /// the instance world boxes, or (refit) the same topology with new boxes
    /// — only valid when no instance was added since the last rebuild (else
    /// it rebuilds).
    void update_top_level(TopLevelUpdate mode = TopLevelUpdate::rebuild) {
        std::vector<AABB> boxes(instances_.size());
        for (std::size_t i = 0; i < instances_.size(); ++i) boxes[i] = world_box(static_cast<std::uint32_t>(i));
        update_top_level(boxes, mode);
    }
    /// Same, from world boxes computed elsewhere (one per instance, e.g. from
    /// root boxes refitted on a device). A box reaching beyond ±2^32 (plus
    /// world_box()'s padding; math/limits.hpp) throws std::domain_error
    /// naming its instance, leaving the tree as it was.
    void update_top_level(const std::vector<AABB>& world_boxes, TopLevelUpdate mode = TopLevelUpdate::rebuild) {
        for (std::size_t i = 0; i < objects_.size(); ++i)
            if (objects_[i].moved)
                throw std::logic_error("raykit::Scene::update_top_level: object " + std::to_string(i) +
                                       " moved without update_object()");
        if (world_boxes.size() != instances_.size())
            throw std::invalid_argument("raykit::Scene::update_top_level: one box per instance needed");
        // world_box() pads by 2^-20 of the largest coordinate: an object at
        // the bound under the identity must still pass
        constexpr float kBoxLimit = kMaxCoordinate * (1.0f + 0x1p-18f);
        for (std::size_t i = 0; i < world_boxes.size(); ++i) {
            const AABB& b = world_boxes[i];
            if (b.is_empty()) continue;
            for (int a = 0; a < 3; ++a)
                if (!(std::fabs(b.min[a]) <= kBoxLimit && std::fabs(b.max[a]) <= kBoxLimit))
                    throw std::domain_error("raykit::Scene::update_top_level: instance " + std::to_string(i) +
                                            " reaches " + std::to_string(std::fmax(std::fabs(b.min[a]), std::fabs(b.max[a]))) +
                                            " on axis " + "xyz"[a] +
                                            ", outside [-2^32, 2^32]: float ray/triangle tests give wrong answers there "
                                            "(raykit/math/limits.hpp)");
        }
        if (mode == TopLevelUpdate::refit && top_.prim_ids.size() == instances_.size() && !instances_.empty()) {
            refit(top_, [&](std::uint32_t i) { return world_boxes[i]; });
        } else {
            top_ = build_top_level(world_boxes, top_config_);
        }
        stale_ = false;
    }

    /// Vertex stages of fewer vertices than this run on the calling thread (parallel_for's
    /// min_parallel).
    static constexpr std::size_t kSerialVertices = 16384;

    /// Scenes of at most this many instances get a top-level tree of one leaf.
    static constexpr std::size_t kOneLeafTopLevel = 4;

    /// The top-level build used by update_top_level(): one leaf holding every
    /// instance in order when there are at most kOneLeafTopLevel (queries then
    /// skip the top-level walk and its ray setup and try the instances' own
    /// trees in turn, whose root boxes are tested first anyway), else
    /// BinnedSahBuilder with `cfg` (one instance per leaf by default).
    static Bvh build_top_level(const std::vector<AABB>& world_boxes, const BinnedSahBuilder::Config& cfg) {
        if (!world_boxes.empty() && world_boxes.size() <= kOneLeafTopLevel) {
            Bvh one;
            Node root;
            for (const AABB& b : world_boxes) root.box.grow(b);
            root.index = 0;
            root.count = static_cast<std::uint32_t>(world_boxes.size());
            one.nodes.push_back(root);
            for (std::uint32_t i = 0; i < world_boxes.size(); ++i) one.prim_ids.push_back(i);
            return one;
        }
        std::vector<vec3> centers(world_boxes.size());
        for (std::size_t i = 0; i < world_boxes.size(); ++i)
            centers[i] = world_boxes[i].is_empty() ? vec3(std::numeric_limits<float>::quiet_NaN()) : world_boxes[i].center();
        return BinnedSahBuilder::build(world_boxes, centers, cfg);
    }
    /// Builder settings of the top-level tree (default: one instance per leaf).
    BinnedSahBuilder::Config& top_level_config() noexcept { return top_config_; }
    const BinnedSahBuilder::Config& top_level_config() const noexcept { return top_config_; }

    // ------------------------------------------------------------ queries

    /// Closest hit over all instances (h.inst set), or a miss. `keep(inst, prim, u, v)`
    /// filters candidate hits; `stats` counts the bottom-level walks.
    template <SceneTrees Trees = SceneTrees::blocks, class Keep = AcceptAll, class Stats = std::nullptr_t>
    Hit intersect_closest(const Ray& ray, const Keep& keep = {}, Stats stats = nullptr) const {
        require_fresh();
        const InstanceLeaves<Trees, Keep, Stats> leaves{this, keep, stats};
        // one leaf (kOneLeafTopLevel): no top-level walk. Measured on the thesis scene's camera
        // rays (one instance): 20.4 ms against 19.9 for its blocks alone; through the walk's slab
        // setup and root test, 21.5
        if (top_.nodes.size() == 1) {
            Hit hit;
            float tm = ray.tmax;
            leaves.closest({}, ray, 0, top_.nodes[0].count, tm, hit, keep, stats);
            return hit;
        }
        return closest_hit(top_, leaves, ray);
    }

    /// True when any instance is hit in [tmin, tmax] (filtered by `keep` as above).
    template <SceneTrees Trees = SceneTrees::blocks, class Keep = AcceptAll>
    bool intersect_any(const Ray& ray, const Keep& keep = {}) const {
        require_fresh();
        const InstanceLeaves<Trees, Keep, std::nullptr_t> leaves{this, keep, nullptr};
        if (top_.nodes.size() == 1) return leaves.any({}, ray, 0, top_.nodes[0].count, keep, nullptr);
        return any_hit(top_, leaves, ray);
    }

    /// Closest hits of a batch: hits[i] is intersect_closest<Trees>(rays[i], keep) bit for bit.
    /// Under a one-leaf top level (at most kOneLeafTopLevel instances) the rays go kPacketWidth
    /// at a time through each object's block tree as one packet (bvh/traverse_packet.hpp);
    /// otherwise, and over binary trees, ray by ray. Runs on the calling thread (callers
    /// spread batches over threads: the renderer's rows, or raykit::parallel_for).
    template <SceneTrees Trees = SceneTrees::blocks, class Keep = AcceptAll>
    void intersect_closest(std::span<const Ray> rays, std::span<Hit> hits, const Keep& keep = {}) const {
        detail::check_batch(rays.size(), hits.size(), "Scene::intersect_closest");
        const InstanceLeaves<Trees, Keep, std::nullptr_t> leaves{this, keep, nullptr};
        batch<Trees>(
            rays.size(),
            [&](std::size_t i, unsigned n) { leaves.closest_packet(rays.data() + i, n, top_.nodes[0].count, hits.data() + i); },
            [&](std::size_t i) { hits[i] = intersect_closest<Trees>(rays[i], keep); });
    }

    /// Any hits of a batch: occluded[i] is intersect_any<Trees>(rays[i], keep) (1 or 0), as
    /// packets under the same conditions as the closest-hit batch.
    template <SceneTrees Trees = SceneTrees::blocks, class Keep = AcceptAll>
    void intersect_any(std::span<const Ray> rays, std::span<std::uint8_t> occluded, const Keep& keep = {}) const {
        detail::check_batch(rays.size(), occluded.size(), "Scene::intersect_any");
        const InstanceLeaves<Trees, Keep, std::nullptr_t> leaves{this, keep, nullptr};
        batch<Trees>(
            rays.size(),
            [&](std::size_t i, unsigned n) {
                const unsigned m = leaves.any_packet(rays.data() + i, n, top_.nodes[0].count);
                for (unsigned k = 0; k < n; ++k) occluded[i + k] = std::uint8_t((m >> k) & 1u);
            },
            [&](std::size_t i) { occluded[i] = intersect_any<Trees>(rays[i], keep) ? 1 : 0; });
    }

    /// Oracle: every triangle of every instance, in object space (the same
    /// ray mapping as intersect_closest, no trees). Equal to it bit for bit.
    Hit brute_force_closest(const Ray& ray) const {
        Hit best;
        for (std::uint32_t i = 0; i < instances_.size(); ++i) {
            const SceneInstance& in = instances_[i];
            Hit h = raykit::brute_force_closest(objects_[in.object].mesh, object_ray(in, ray, ray.tmax));
            if (!h.valid()) continue;
            h.inst = i;
            if (h.closer_than(best)) best = h;
        }
        return best;
    }

    /// All instances' triangles in world space as one mesh (vertices mapped by
    /// Affine::point), plus for each of its triangles the (instance, triangle)
    /// it came from: the world-space oracle, equal to the traced answers up to
    /// rounding of the transforms.
    std::pair<Mesh, std::vector<std::pair<std::uint32_t, std::uint32_t>>> world_mesh() const {
        Mesh w;
        std::vector<std::pair<std::uint32_t, std::uint32_t>> origin;
        for (std::uint32_t i = 0; i < instances_.size(); ++i) {
            const SceneInstance& in = instances_[i];
            const Mesh& m = objects_[in.object].mesh;
            const auto base = static_cast<std::uint32_t>(w.positions.size());
            for (const vec3& p : m.positions) w.positions.push_back(in.to_world.point(p));
            for (std::uint32_t t = 0; t < m.triangles.size(); ++t) {
                const Triangle& tr = m.triangles[t];
                w.triangles.push_back({{tr.v[0] + base, tr.v[1] + base, tr.v[2] + base}});
                origin.emplace_back(i, t);
            }
        }
        return {std::move(w), std::move(origin)};
    }

    /// The object-space ray for `in` with tmax replaced by `tmax`.
    static Ray object_ray(const SceneInstance& in, const Ray& ray, float tmax) noexcept {
        if (in.identity) {
            Ray r = ray;
            r.tmax = tmax;
            return r;
        }
        Ray r;
        r.org = in.to_object.point(ray.org);
        r.dir = in.to_object.vector(ray.dir);
        r.tmin = ray.tmin;
        r.tmax = tmax;
        return r;
    }

    const std::vector<SceneObject>& objects() const noexcept { return objects_; }
    const std::vector<SceneInstance>& instances() const noexcept { return instances_; }
    const Bvh& top_level() const noexcept { return top_; }
    /// True when update_top_level() is due.
    bool stale() const noexcept { return stale_; }
    /// Bumped by every add_instance() and set_transform(): a copy of the instances kept elsewhere
    /// (cl::DeviceScene) compares it with its own to know it is out of date.
    std::uint64_t instance_revision() const noexcept { return instance_revision_; }
    std::size_t dynamic_object_count() const noexcept {
        return static_cast<std::size_t>(std::count_if(objects_.begin(), objects_.end(), [](const SceneObject& o) { return o.dynamic(); }));
    }

private:
    /// The batch rule: packet(first, n) over kPacketWidth rays at a time under a one-leaf top
    /// level (the object walks decide whether their tree takes packets: scene/trace.hpp), else
    /// ray(i) for each ray through the top-level walk.
    template <SceneTrees Trees, class PacketFn, class RayFn>
    void batch(std::size_t size, PacketFn&& packet, RayFn&& ray) const {
        require_fresh();
        if (top_.nodes.size() == 1) {
            for (std::size_t i = 0; i < size; i += kPacketWidth)
                packet(i, static_cast<unsigned>(std::min<std::size_t>(kPacketWidth, size - i)));
            return;
        }
        for (std::size_t i = 0; i < size; ++i) ray(i);
    }

    /// The top-level leaf store: a slot is an instance; its leaf runs the object's walk.
    template <SceneTrees Trees, class Keep, class Stats>
    struct InstanceLeaves {
        const Scene* scene;
        const Keep& keep;
        Stats stats;
        struct RayData {};
        static RayData prepare(const Ray&) noexcept { return {}; }

        /// The filter of instance `inst`'s object: keep(inst, prim, u, v), or AcceptAll.
        RAYKIT_INLINE auto keep_for(std::uint32_t inst) const noexcept {
            if constexpr (kFilters<Keep>)
                return [this, inst](std::uint32_t p, float u, float v) { return keep(inst, p, u, v); };
            else
                return AcceptAll{};
        }
        RAYKIT_INLINE Hit object_closest(const SceneObject& o, std::uint32_t inst, const Ray& r, float tmax) const {
            if constexpr (Trees == SceneTrees::blocks)
                return closest_hit_within(o.blocks.tree, o.blocks.leaves(), r, tmax, keep_for(inst), stats);
            else
                return closest_hit_within(o.bvh, indexed_leaves(o.mesh, o.bvh), r, tmax, keep_for(inst), stats);
        }
        RAYKIT_INLINE bool object_any(const SceneObject& o, std::uint32_t inst, const Ray& r) const {
            if constexpr (Trees == SceneTrees::blocks) return any_hit(o.blocks.tree, o.blocks.leaves(), r, keep_for(inst));
            else return any_hit(o.bvh, indexed_leaves(o.mesh, o.bvh), r, keep_for(inst));
        }
        template <class K, class S>
        bool closest(RayData, const Ray& ray, std::uint32_t first, std::uint32_t count, float& tm, Hit& best,
                     const K&, S) const {
            bool found = false;
            for (std::uint32_t k = first; k < first + count; ++k) {
                const std::uint32_t inst = scene->top_.prim_ids[k];
                const SceneInstance& in = scene->instances_[inst];
                const SceneObject& o = scene->objects_[in.object];
                // an identity instance traces the world ray itself (a copy costs 20 % of a
                // camera ray on the thesis scene: the ray setup's vector loads stall on it)
                Hit h = in.identity ? object_closest(o, inst, ray, tm) : object_closest(o, inst, object_ray(in, ray, tm), tm);
                if (!h.valid()) continue;
                h.inst = inst;
                if (h.closer_than(best)) {
                    best = h;
                    tm = h.t;
                    found = true;
                }
            }
            return found;
        }
        /// closest() over slots [0, count) for rays[0, n) as packets, into best[0, n).
        void closest_packet(const Ray* rays, unsigned n, std::uint32_t count, Hit* best) const {
            float tm[kPacketWidth];
            for (unsigned r = 0; r < n; ++r) {
                best[r] = Hit{};
                tm[r] = rays[r].tmax;
            }
            Ray local[kPacketWidth];
            Hit h[kPacketWidth];
            for (std::uint32_t k = 0; k < count; ++k) {
                const std::uint32_t inst = scene->top_.prim_ids[k];
                const SceneInstance& in = scene->instances_[inst];
                const SceneObject& o = scene->objects_[in.object];
                const Ray* r = rays;
                if (!in.identity) {
                    for (unsigned i = 0; i < n; ++i) local[i] = object_ray(in, rays[i], tm[i]);
                    r = local;
                }
                if constexpr (Trees == SceneTrees::blocks)
                    closest_hit_packet(o.blocks.tree, o.blocks.leaves(), r, tm, n, h, keep_for(inst));
                else
                    closest_hit_packet(o.bvh, indexed_leaves(o.mesh, o.bvh), r, tm, n, h, keep_for(inst));
                for (unsigned i = 0; i < n; ++i) {
                    if (!h[i].valid()) continue;
                    h[i].inst = inst;
                    if (h[i].closer_than(best[i])) {
                        best[i] = h[i];
                        tm[i] = h[i].t;
                    }
                }
            }
        }
        /// any() over slots [0, count) for rays[0, n) as packets: bit i set when rays[i] is blocked.
        unsigned any_packet(const Ray* rays, unsigned n, std::uint32_t count) const {
            unsigned blocked = 0;
            const unsigned all = (1u << n) - 1;
            Ray local[kPacketWidth];
            for (std::uint32_t k = 0; k < count && blocked != all; ++k) {
                const std::uint32_t inst = scene->top_.prim_ids[k];
                const SceneInstance& in = scene->instances_[inst];
                const SceneObject& o = scene->objects_[in.object];
                const Ray* r = rays;
                if (!in.identity) {
                    for (unsigned i = 0; i < n; ++i) local[i] = object_ray(in, rays[i], rays[i].tmax);
                    r = local;
                }
                if constexpr (Trees == SceneTrees::blocks)
                    blocked |= any_hit_packet(o.blocks.tree, o.blocks.leaves(), r, n, keep_for(inst));
                else
                    blocked |= any_hit_packet(o.bvh, indexed_leaves(o.mesh, o.bvh), r, n, keep_for(inst));
            }
            return blocked;
        }
        template <class K, class S>
        bool any(RayData, const Ray& ray, std::uint32_t first, std::uint32_t count, const K&, S) const {
            for (std::uint32_t k = first; k < first + count; ++k) {
                const std::uint32_t inst = scene->top_.prim_ids[k];
                const SceneInstance& in = scene->instances_[inst];
                const SceneObject& o = scene->objects_[in.object];
                if (in.identity ? object_any(o, inst, ray) : object_any(o, inst, object_ray(in, ray, ray.tmax)))
                    return true;
            }
            return false;
        }
    };

    static void check_mesh(const Mesh& mesh) {
        if (!mesh.normals.empty() && mesh.normals.size() != mesh.positions.size())
            throw std::invalid_argument("raykit::Scene::add_object: normals must be empty or one per vertex");
        if (!mesh.texcoords.empty() && mesh.texcoords.size() != mesh.positions.size())
            throw std::invalid_argument("raykit::Scene::add_object: texcoords must be empty or one per vertex");
        for (const Triangle& t : mesh.triangles)
            for (int c = 0; c < 3; ++c)
                if (t.v[c] >= mesh.positions.size())
                    throw std::invalid_argument("raykit::Scene::add_object: triangle vertex index out of range");
        check_positions(mesh.positions, "raykit::Scene::add_object");
    }
    std::uint32_t add(Mesh mesh, Bvh bvh, ObjectKind kind, const BinnedSahBuilder::Config& cfg) {
        SceneObject o;
        o.kind = kind;
        o.config = cfg;
        o.blocks = BlockBvh8::build(mesh, bvh, cfg.threads);
        o.bvh = std::move(bvh);
        if (kind == ObjectKind::dynamic) {
            o.rest.resize(mesh.positions.size());
            for (std::size_t i = 0; i < o.rest.size(); ++i) {
                o.rest[i].position = mesh.positions[i];
                if (!mesh.normals.empty()) o.rest[i].normal = mesh.normals[i];
                if (!mesh.texcoords.empty()) o.rest[i].uv = mesh.texcoords[i];
            }
        }
        o.mesh = std::move(mesh);
        objects_.push_back(std::move(o));
        stale_ = true;
        return static_cast<std::uint32_t>(objects_.size() - 1);
    }

    static void set(SceneInstance& in, const mat4& transform) {
        in.to_object = Affine::inverse_of(transform);  // validates first
        in.to_world = Affine::from_mat4(transform);
        in.transform = transform;
        in.identity = transform == mat4(1.0f);
    }
    SceneObject& dynamic_object(std::uint32_t object, const char* what) {
        if (object >= objects_.size())
            throw std::out_of_range(std::string("raykit::Scene::") + what + ": no object " + std::to_string(object));
        SceneObject& o = objects_[object];
        if (!o.dynamic())
            throw std::logic_error(std::string("raykit::Scene::") + what + ": object " + std::to_string(object) +
                                   " is static");
        return o;
    }
    static bool root_in_range(const SceneObject& o) noexcept {
        const AABB root = o.bounds();
        return root.is_empty() || (coordinate_in_range(root.min.x) && coordinate_in_range(root.min.y) &&
                                   coordinate_in_range(root.min.z) && coordinate_in_range(root.max.x) &&
                                   coordinate_in_range(root.max.y) && coordinate_in_range(root.max.z));
    }
    void require_fresh() const {
        if (stale_) throw std::logic_error("raykit::Scene: call update_top_level() before tracing");
    }

    std::vector<SceneObject> objects_;
    std::vector<SceneInstance> instances_;
    Bvh top_;
    BinnedSahBuilder::Config top_config_{.leaf = {.max_leaf_size = 1}};
    bool stale_ = true;
    std::uint64_t instance_revision_ = 0;
};

}  // namespace raykit
