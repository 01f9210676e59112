// raykit/cl/trace.hpp — tracing one mesh on an OpenCL device.
//
//   raykit::cl::MeshTracer tracer(raykit::cl::Device::shared(), mesh, bvh);
//   std::vector<Hit> hits = tracer.closest(rays);          // == intersect_closest per ray
//   std::vector<std::uint32_t> occ = tracer.any(rays);      // 1 = occluded, 0 = free
//
// The kernels (kernels/raykit/kernels/trace.hpp) are the twins of
// scene/trace.hpp's closest_hit / any_hit over the WideBvh8 collapsed from the
// given tree, with the Watertight test: the same traversal order, the same tie
// rule (smaller t, then smaller triangle index), the same stack bound; the
// triangles are read from 4-triangle blocks in leaf order (cl/device_tree.hpp). On a device with cl_khr_fp64 the edge
// functions are evaluated in double like the CPU's; the two expressions a
// compiler may fuse into fma are fused on the device exactly when the host
// build fuses them (RAYKIT_FMA, cl/layout.hpp host_float_config()); division is
// correctly rounded where the device supports
// -cl-fp32-correctly-rounded-divide-sqrt. So on such devices (PoCL's CPU
// device is one) hits equal the CPU's bit for bit (t, u, v, triangle).
// Without fp64 the edge functions are float and FMA-proof (watertight, but
// t may differ in the last bits, and ties at shared edges may go to the
// neighbouring triangle).
//
// Device-resident variants take Buffers (rays stay on the device, e.g. from
// camera_rays()); the vector variants upload, trace and download.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "raykit/cl/buffer.hpp"
#include "raykit/cl/device_tree.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/kernels/camera.hpp"
#include "raykit/kernels/trace.hpp"
#include "raykit/kernels/trace_packet.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/mesh.hpp"

namespace raykit::cl {

/// Work-items per work-group of raykit's trace launches.
inline constexpr std::size_t kTraceGroupSize = 64;
/// Rays per work-item of the packet walk (kernels/raykit/kernels/trace_packet.hpp).
inline constexpr std::size_t kPacketRays = 16;

/// Whether raykit walks rays as packets on `dev` unless told otherwise: on CPU devices (PoCL),
/// where a work-item's walk is scalar code and 16 coherent rays sharing each node's fetch and
/// box test trace faster (kernels/raykit/kernels/trace_packet.hpp); not on GPUs.
inline bool packet_walk_default(const Device& dev) noexcept { return dev.info().is_cpu(); }

/// Which of trace.hpp's kernel pairs a program holds: each inlines the whole walk, so a program
/// compiles only the pair it launches (the renderer's programs have kernels of their own).
enum class TraceKernels { none, mesh, scene };

/// The form of the objects' nodes a walk reads: DeviceNode (256 bytes, the CPU's own tree) or
/// QuantizedNode (104 bytes, its child boxes as bytes rounded outward; cl/device_tree.hpp).
/// Both give the same answers bit for bit; the quantized walk tests a few more boxes and
/// triangles (it never counts the same traversal steps as the CPU).
enum class NodeForm { full, quantized };

/// The walk's program parts: trace.hpp with the kernels `kernels`, and with `packets` the packet
/// walk and its kernels (the *_packet kernels, kPacketRays rays per work-item), preceded by the
/// RK_PACKET define that later parts (the renderer's) test; with NodeForm::quantized the walks
/// read QuantizedNodes (RK_QNODES).
inline std::vector<SourcePart> trace_parts(bool packets, TraceKernels kernels, NodeForm form = NodeForm::full) {
    std::vector<SourcePart> parts;
    if (form == NodeForm::quantized) parts.push_back({"<nodes>", "#define RK_QNODES 1\n"});
    if (kernels != TraceKernels::none)
        parts.push_back({"<trace kernels>", kernels == TraceKernels::mesh ? "#define RK_MESH_KERNELS 1\n"
                                                                         : "#define RK_SCENE_KERNELS 1\n"});
    if (packets) parts.push_back({"<packets>", "#define RK_PACKET " + std::to_string(kPacketRays) + "\n"});
    parts.push_back({"raykit/kernels/trace.hpp", kernels::kTrace});
    if (packets) parts.push_back({"raykit/kernels/trace_packet.hpp", kernels::kTracePacket});
    return parts;
}

/// Work-items of a trace launch over n rays: n, or one per kPacketRays rays with `packets`.
inline std::size_t trace_items(std::size_t n, bool packets) noexcept {
    return packets ? (n + kPacketRays - 1) / kPacketRays : n;
}

/// A program's closest-hit and any-hit kernels of one pair (trace_parts' `kernels`), with their
/// packet forms when it was built with them.
struct TraceKernelSet {
    ::cl::Kernel closest, any, closest_packet, any_packet;
    bool packets = false;  ///< the packet forms are there

    TraceKernelSet() = default;
    TraceKernelSet(const Program& p, TraceKernels pair, bool with_packets) : packets(with_packets) {
        const std::string base = pair == TraceKernels::mesh ? "rk_mesh_" : "rk_scene_";
        closest = p.kernel(base + "closest");
        any = p.kernel(base + "any");
        if (packets) {
            closest_packet = p.kernel(base + "closest_packet");
            any_packet = p.kernel(base + "any_packet");
        }
    }
    /// The kernel of a closest-hit (any_hit false) or any-hit launch, as packets when `packet_walk`.
    ::cl::Kernel& pick(bool any_hit, bool packet_walk) {
        if (packet_walk && !packets) throw std::logic_error("raykit::cl: packet kernels were not built");
        return any_hit ? (packet_walk ? any_packet : any) : (packet_walk ? closest_packet : closest);
    }
};

/// Config + layout + common math + camera + the mesh trace kernels for `dev` (cached), with the
/// packet kernels when `packets`, walking nodes of the form `form`. `extra_options` are appended
/// to the build options (e.g. "-DRK_EDGE_DOUBLE=0" forces the float edge functions of
/// kernels/raykit/kernels/common.hpp).
inline Program trace_program(Device& dev, const std::string& extra_options = {}, bool packets = false,
                             NodeForm form = NodeForm::full) {
    std::vector<SourcePart> parts = base_parts();
    parts.push_back({"raykit/kernels/camera.hpp", kernels::kCamera});
    for (SourcePart& p : trace_parts(packets, TraceKernels::mesh, form)) parts.push_back(std::move(p));
    std::string opts = raykit_build_options(dev);
    if (!extra_options.empty()) opts += (opts.empty() ? "" : " ") + extra_options;
    return build_program(dev, assemble(parts), opts);
}

/// Fills `rays` (width·height, row-major) with the camera's rays through the
/// image points (x + jx, y + jy): bit-identical to CameraFrame::ray.
inline void camera_rays(Device& dev, ::cl::Kernel& k, const CameraFrame& frame, Buffer<Ray>& rays, float jx = 0.5f,
                        float jy = 0.5f) {
    const std::size_t n = std::size_t(frame.width) * frame.height;
    if (n > 0xFFFFFFFFu) throw std::length_error("raykit::cl::camera_rays: more than 2^32 pixels");
    rays.reserve(dev, n);
    set_args(k, frame, jx, jy, rays);
    launch(dev.queue(), k, n, kTraceGroupSize);
}

class MeshTracer {
public:
    /// Uploads the tree in the device's form (device_tree() of BlockBvh8::build(mesh, bvh): 8-wide
    /// nodes over 4-triangle blocks), its nodes in the form `form` where they can be (a tree
    /// with a leaf of more than 255 blocks stays full: node_form());
    /// `extra_options` go to trace_program().
    MeshTracer(Device& dev, const MeshView& mesh, const Bvh& bvh, const std::string& extra_options = {},
               NodeForm form = NodeForm::full)
        : dev_(&dev), asked_form_(form) {
        if (mesh.positions.size() >= 0x55555555u || mesh.size() >= 0x55555555u)
            throw std::length_error("raykit::cl::MeshTracer: mesh too large for 32-bit indices");
        extra_options_ = extra_options;
        update_tree(mesh, bvh);
    }

    /// The form of the nodes uploaded (NodeForm::full where the asked form could not be made).
    NodeForm node_form() const noexcept { return form_; }

    /// Whether rays walk as packets (packet_walk_default: on CPU devices); the answers are the
    /// same either way.
    bool packet_walk() const noexcept { return packets_; }
    /// Turns the packet walk on or off (builds the program with it when first needed).
    void set_packet_walk(bool on) {
        packets_ = on;
        if (on && !kernels_.packets) build_kernels();
    }

    /// Replaces the tree and its blocks (e.g. after the vertices moved and `bvh` was refitted
    /// or rebuilt over `mesh`).
    void update_tree(const MeshView& mesh, const Bvh& bvh) {
        if (bvh.prim_ids.size() != mesh.size())
            throw std::invalid_argument("raykit::cl::MeshTracer: tree and mesh differ in triangle count");
        const DeviceTree tree = device_tree(BlockBvhT<kDeviceWidth>::build(mesh, bvh));
        if (tree.nodes.size() >= 0xFFFFFFFFu) throw std::length_error("raykit::cl::MeshTracer: tree too large");
        std::optional<std::vector<QuantizedNode>> q;
        if (asked_form_ == NodeForm::quantized) q = quantize_nodes(tree.nodes);
        const NodeForm form = q ? NodeForm::quantized : NodeForm::full;
        if (q) {
            qnodes_ = Buffer<QuantizedNode>(*dev_, *q, CL_MEM_READ_ONLY);
            nodes_ = {};
        } else {
            nodes_ = Buffer<DeviceNode>(*dev_, tree.nodes, CL_MEM_READ_ONLY);
            qnodes_ = {};
        }
        blocks_ = Buffer<TriangleBlock4>(*dev_, tree.blocks, CL_MEM_READ_ONLY);
        node_count_ = static_cast<std::uint32_t>(tree.nodes.size());
        if (form != form_ || !built_) {
            form_ = form;
            build_kernels();
        }
    }

    /// Closest hits of rays[0..n) into hits (device-resident; asynchronous).
    void closest(const Buffer<Ray>& rays, Buffer<Hit>& hits, std::size_t n) {
        check_count(rays, n);
        hits.reserve(*dev_, n);
        ::cl::Kernel& k = kernels_.pick(false, packets_);
        set_args(k, walk_nodes(), blocks_, node_count_, rays, hits, static_cast<std::uint32_t>(n));
        launches_ += launch(dev_->queue(), k, trace_items(n, packets_), kTraceGroupSize);
    }
    /// occluded[i] = 1 when rays[i] hits anything in [tmin, tmax], else 0.
    void any(const Buffer<Ray>& rays, Buffer<std::uint32_t>& occluded, std::size_t n) {
        check_count(rays, n);
        occluded.reserve(*dev_, n);
        ::cl::Kernel& k = kernels_.pick(true, packets_);
        set_args(k, walk_nodes(), blocks_, node_count_, rays, occluded, static_cast<std::uint32_t>(n));
        launches_ += launch(dev_->queue(), k, trace_items(n, packets_), kTraceGroupSize);
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

    /// Camera rays generated on the device (see camera_rays()).
    void camera_rays(const CameraFrame& frame, Buffer<Ray>& rays, float jx = 0.5f, float jy = 0.5f) {
        cl::camera_rays(*dev_, k_camera_, frame, rays, jx, jy);
        ++launches_;
    }

    Device& device() noexcept { return *dev_; }
    const Program& program() const noexcept { return program_; }
    /// Kernel launches so far.
    std::size_t launches() const noexcept { return launches_; }
    /// The tree's nodes (device_tree()) when node_form() is NodeForm::full, else empty.
    Buffer<DeviceNode>& nodes() noexcept { return nodes_; }
    /// The tree's nodes quantized when node_form() is NodeForm::quantized, else empty.
    Buffer<QuantizedNode>& quantized_nodes() noexcept { return qnodes_; }
    /// The leaves' triangle blocks.
    Buffer<TriangleBlock4>& blocks() noexcept { return blocks_; }

private:
    void build_kernels() {
        program_ = trace_program(*dev_, extra_options_, packets_, form_);
        built_ = true;
        kernels_ = TraceKernelSet(program_, TraceKernels::mesh, packets_);
        k_camera_ = program_.kernel("rk_camera_rays");
    }
    /// The nodes the walk reads, in node_form() (as DeviceSceneArrays::walk_nodes).
    const ::cl::Buffer& walk_nodes() const noexcept {
        return form_ == NodeForm::quantized ? qnodes_.handle() : nodes_.handle();
    }
    static void check_count(const Buffer<Ray>& rays, std::size_t n) {
        if (n > rays.size()) throw std::out_of_range("raykit::cl::MeshTracer: more rays asked for than the buffer holds");
        if (n > 0xFFFFFFFFu) throw std::length_error("raykit::cl::MeshTracer: more than 2^32 rays in one launch");
    }

    Device* dev_;
    std::string extra_options_;
    bool packets_ = packet_walk_default(*dev_);
    Program program_;
    TraceKernelSet kernels_;
    ::cl::Kernel k_camera_;
    NodeForm asked_form_ = NodeForm::full;
    NodeForm form_ = NodeForm::full;
    bool built_ = false;
    Buffer<DeviceNode> nodes_;
    Buffer<QuantizedNode> qnodes_;
    Buffer<TriangleBlock4> blocks_;
    std::uint32_t node_count_ = 0;
    std::size_t launches_ = 0;
};

}  // namespace raykit::cl
