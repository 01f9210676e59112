// raykit/cl/render.hpp — the wavefront renderer on an OpenCL device, with ray hooks.
//
// Interface
// ---------
//   raykit::cl::DeviceScene<WaveHook> ds(dev, scene);  ds.update();          // cl/device_scene.hpp
//   raykit::cl::DeviceRenderer r(ds, tables, lights);   // renders ds: its objects, instances and
//                                                       // top level, moved vertices included;
//                                                       // one MaterialTable per object
//   per frame: move ds (set_hook, scene.set_transform), ds.update(), r.render(cam, set)
//                                                       // (a move without ds.update(): render throws)
//   raykit::cl::DeviceRenderer r(dev, rs.view());       // a ShadeScene: uploads it into a
//                                                       // DeviceScene of its own
//   RenderSettings set;  set.spp = 4;  set.shade.shader = ShaderKind::ao;
//   Image img = r.render(cam, set);                            // built-in shader by set.shade.shader
//   Image img = r.render(cam, shade_settings);                 // 1 sample at each pixel centre
//   Image img = r.render_hook<MyHook>(cam, set, params);       // a user ray hook
//   r.set_lights(lights);                                      // replaces the lights
//
// Scenes: the renderer binds the DeviceScene's arrays (nodes, triangle blocks, triangles, positions,
// rk_vertex records, object and instance records, top-level tree) and adds what shading needs:
// the objects' material tables concatenated (ShadeObjectRecord: each object's offset, count and
// vertex attributes), their material ids at each object's triangle_offset, the textures, the
// lights. Surfaces are computed in object space and mapped to the world as on the CPU (points
// by the instance's transform, normals by its inverse transpose, renormalised; identity
// instances not mapped). Nothing is read back between a DeviceScene's update() and the image.
//
// The image equals render_cpu's over the binary trees (ShadeScene::trees = binary) for the same RenderSettings (render(cam, ShadeSettings) is
// spp = 1, jitter = false): the same camera rays bit for bit (raykit::PixelSampler's sample
// positions and generator states, CameraFrame::ray), the same triangle test and traversal
// order, the same random numbers (ao), the same traversal step counts (debug-cost), the same
// shading formulas; colours differ only in the last bits (float atomics add in any order;
// OpenCL's pow, normalize, sin and cos are not correctly rounded). Built-in shaders: all of
// ShaderKind — normals, depth, whitted, ao, debug_cost (the traversal steps are mapped to the
// heat map on the host with cost_heat_map and RenderSettings::cost_scale, as render_cpu does).
// Alpha cut-outs (map_Kd alpha < 0.5) are skipped inside the closest-hit and shadow walks as on
// the CPU: a leaf filter of the one walk (kernels/raykit/kernels/trace.hpp) compiled into the
// program only when some material is alpha-tested, so scenes without cut-outs pay nothing. RenderSettings::threads and time_stages mean nothing here; progress is called after
// each sample pass with (passes done, spp).
//
// Ray hooks
// ---------
// A ray hook is a C++ type carrying OpenCL C source, like the vertex hooks of cl/hook.hpp:
//
//   struct TintHook {
//       static constexpr const char* name = "tint";          // a C identifier
//       struct Params { float r, g, b; };                    // trivially copyable
//       static constexpr unsigned max_rays = 1;              // continuation rays per hit, at most
//       static constexpr unsigned max_shadow_rays = 0;       // shadow rays per hit (kPerLight: one per light)
//       static constexpr const char* source = R"(
//           typedef struct { float r, g, b; } tint_params;
//           void tint(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit,
//                     const rk_surface* s, tint_params p) { ... }
//       )";
//   };
//
// The hook is called once per traced ray (hit or miss) of every bounce; the API it may call
// (rk_add_color, rk_set_alpha, rk_emit_shadow, rk_emit_ray, rk_random, rk_traversal_steps,
// rk_get_material, rk_texture_sample, rk_offset_origin, lights) is documented in
// kernels/raykit/kernels/shade.hpp. max_shadow_rays may be a number, kPerLight (one per light of
// the scene) or kPerAoSample (ShadeSettings::ao_samples). A hook that declares
// `static constexpr bool traversal_steps = true;` gets the step count of each ray's closest-hit
// walk (rk_traversal_steps); its program is built with RK_DR_STEPS, so the others pay nothing.
// NAME_params must have the size of Params (checked when compiling: a mismatch is a build error
// naming the hook). Only hooks that are rendered with are compiled, each into its own program
// (cached per process, see cl/program.hpp); compiler messages about the hook name
// "<hook NAME>" and the line within the hook's own source, and a failed build throws
// BuildError carrying that log.
//
// Wavefront and memory
// --------------------
// A frame is spp passes, one per sample index: pass s puts sample s of every pixel into queue 0
// (W·H camera rays, whatever spp is). Rays live in per-bounce queues on the device; the shade
// launch of bounce k writes this bounce's shadow rays into fixed slots (ray i's from
// i · max_shadow_rays, unused ones marked empty, counted by one atomic add per work-group) and
// the continuation rays of bounce k + 1 into fixed slots of a staging queue, which the work-group
// then copies, packed, to a range of the next queue it takes with one atomic add. A shared
// counter taken once per ray cost the goblin frame's shade kernel 26 ms instead of 9 on PoCL
// (two cores bouncing its cache line, in processes where the two threads ran apart); fixed
// slots also keep the shadow queue in camera-tile order for the packet walk. Before each shade
// launch the host grows the next queue (and the staging queue) to (rays of bounce k) × max_rays
// and the shadow queue to (rays of bounce k) ×
// max_shadow_rays (buffers only grow, they are kept between frames), so memory follows the rays
// alive, never pixels × samples × a fixed maximum. A path ends when its hook emits nothing or at
// ShadeSettings::max_depth (rk_emit_ray refuses beyond it); a pass ends when a queue is empty.
// The only host round trip per bounce is reading the two counters. The image accumulates sums
// over the passes; the host multiplies them by 1 / spp after reading it back.
//
// Statistics (DeviceRenderStats): rays per kind and per bounce, and device time per stage
// (camera, closest hit, shade, shadow kernels) from the queue's profiling events.
//
// Pixels are accumulated in a float RGBA buffer with an atomic_cmpxchg loop on the bits of each
// float (OpenCL 1.2 has no atomic float add; several rays of one pixel can be in flight).
//
// Textures: all map_Kd textures are concatenated into one buffer of RGBA bytes (uchar4 texels)
// with a table of (offset, width, height, srgb) per texture; the sampling code is the twin of
// raykit::Texture::sample (wrap, bilinear or nearest, sRGB decoded per texel through the CPU's
// 256-entry table before filtering). Buffers rather than image objects: one code path for
// textures of any size and count (no per-device image size or count limits, no sampler
// rounding differences against the CPU), and it works the same on every OpenCL 1.2 device.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "raykit/cl/buffer.hpp"
#include "raykit/cl/device_scene.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/cl/trace.hpp"
#include "raykit/kernels/camera.hpp"
#include "raykit/kernels/shade.hpp"
#include "raykit/kernels/shaders/ao.hpp"
#include "raykit/kernels/shaders/debug_cost.hpp"
#include "raykit/kernels/shaders/depth.hpp"
#include "raykit/kernels/shaders/normals.hpp"
#include "raykit/kernels/shaders/whitted.hpp"
#include "raykit/kernels/trace.hpp"
#include "raykit/render/image.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/render/shade.hpp"
#include "raykit/render/shaders.hpp"
#include "raykit/scene/camera.hpp"

namespace raykit::cl {

using raykit::kPerAoSample;  // max_shadow_rays values (render/ray_hook.hpp)
using raykit::kPerLight;

template <class H>
concept RayHook = requires {
    { H::name } -> std::convertible_to<const char*>;
    { H::source } -> std::convertible_to<const char*>;
    { H::max_rays } -> std::convertible_to<unsigned>;
    { H::max_shadow_rays } -> std::convertible_to<unsigned>;
} && std::is_trivially_copyable_v<typename H::Params>;

// ---------------------------------------------------------------- crossing structs (kernels/raykit/kernels/shade.hpp)
// Sizes and offsets are pinned here and, with the same numbers, by RK_DR_CHECK in the kernels.

struct PathRay {
    Ray ray;
    float weight[3];
    std::uint32_t pixel, depth, kind;
    std::uint64_t rng;  ///< the sample's SampleRng state
};
static_assert(sizeof(PathRay) == 64 && offsetof(PathRay, weight) == 32 && offsetof(PathRay, pixel) == 44 &&
              offsetof(PathRay, depth) == 48 && offsetof(PathRay, kind) == 52 && offsetof(PathRay, rng) == 56);

struct ShadowRay {
    Ray ray;
    float color[3];
    std::uint32_t pixel;
};
static_assert(sizeof(ShadowRay) == 48 && offsetof(ShadowRay, color) == 32 && offsetof(ShadowRay, pixel) == 44);

struct MaterialRecord {
    float kd[3], ks[3], ke[3], mirror[3];
    float ns, ni, transparency;
    std::int32_t texture, fresnel_mirror, alpha_tested, illum, pad;
};
static_assert(sizeof(MaterialRecord) == 80 && offsetof(MaterialRecord, ks) == 12 && offsetof(MaterialRecord, ke) == 24 &&
              offsetof(MaterialRecord, mirror) == 36 && offsetof(MaterialRecord, ns) == 48 &&
              offsetof(MaterialRecord, ni) == 52 && offsetof(MaterialRecord, transparency) == 56 &&
              offsetof(MaterialRecord, texture) == 60 && offsetof(MaterialRecord, fresnel_mirror) == 64 &&
              offsetof(MaterialRecord, alpha_tested) == 68 && offsetof(MaterialRecord, illum) == 72);

struct TextureRecord {
    std::uint32_t offset, width, height, srgb;
};
static_assert(sizeof(TextureRecord) == 16 && offsetof(TextureRecord, width) == 4 &&
              offsetof(TextureRecord, height) == 8 && offsetof(TextureRecord, srgb) == 12);

struct LightRecord {
    float position[3];
    std::uint32_t type;
    float direction[3];
    float pad0;
    float color[3];
    float pad1;
};
static_assert(sizeof(LightRecord) == 48 && offsetof(LightRecord, type) == 12 && offsetof(LightRecord, direction) == 16 &&
              offsetof(LightRecord, color) == 32);

struct RenderSettingsRecord {
    float ambient[3], background[3];
    float min_weight, depth_far;
    std::uint32_t width, height, max_depth, shadows, filter, light_count, object_count, pad3;
    std::uint32_t pad4, material_count, alpha_testing, ao_samples;
    float ao_radius;
    std::uint32_t pad0, pad1, pad2;
};
static_assert(sizeof(RenderSettingsRecord) == 96 && offsetof(RenderSettingsRecord, background) == 12 &&
              offsetof(RenderSettingsRecord, min_weight) == 24 && offsetof(RenderSettingsRecord, depth_far) == 28 &&
              offsetof(RenderSettingsRecord, width) == 32 && offsetof(RenderSettingsRecord, max_depth) == 40 &&
              offsetof(RenderSettingsRecord, light_count) == 52 && offsetof(RenderSettingsRecord, material_count) == 68 &&
              offsetof(RenderSettingsRecord, alpha_testing) == 72 && offsetof(RenderSettingsRecord, ao_samples) == 76 &&
              offsetof(RenderSettingsRecord, ao_radius) == 80);

/// Per-object shading data (rk_shade_object): the object's slice of the concatenated material
/// table (its default material last) and of the material ids, and what its vertices carry.
struct ShadeObjectRecord {
    std::uint32_t material_offset = 0;    ///< its first material in the concatenated table
    std::uint32_t material_count = 0;     ///< its table's size, the default material (last) included
    std::uint32_t material_id_count = 0;  ///< its triangles with a material id
    std::uint32_t flags = 0;  ///< kShadeNormals | kShadeUvs
};
static_assert(sizeof(ShadeObjectRecord) == 16 && offsetof(ShadeObjectRecord, material_count) == 4 &&
              offsetof(ShadeObjectRecord, material_id_count) == 8 && offsetof(ShadeObjectRecord, flags) == 12);
/// ShadeObjectRecord::flags: the object has vertex normals (RK_SHADE_NORMALS).
inline constexpr std::uint32_t kShadeNormals = 1u;
/// ShadeObjectRecord::flags: the object has texture coordinates (RK_SHADE_UVS).
inline constexpr std::uint32_t kShadeUvs = 2u;

// ---------------------------------------------------------------- built-in hooks

// Each built-in device hook is its CPU twin (render/shaders.hpp: Params, budgets, shade) plus
// its OpenCL source and name, so one type renders on both sides.

/// 0.5 · N + 0.5 at the first hit (ShaderKind::normals).
struct NormalsRayHook : NormalsShader {
    static constexpr const char* name = "rk_normals";
    static constexpr const char* source = kernels::kShadeNormals;
};
/// 1 - distance / far at the first hit (ShaderKind::depth).
struct DepthRayHook : DepthShader {
    static constexpr const char* name = "rk_depth";
    static constexpr const char* source = kernels::kShadeDepth;
};
/// Whitted ray tracing (ShaderKind::whitted).
struct WhittedRayHook : WhittedShader {
    static constexpr const char* name = "rk_whitted";
    static constexpr const char* source = kernels::kShadeWhitted;
};
/// Ambient occlusion (ShaderKind::ao).
struct AoRayHook : AoShader {
    static constexpr const char* name = "rk_ao";
    static constexpr const char* source = kernels::kShadeAo;
};
/// Traversal steps of the camera ray (ShaderKind::debug_cost), before the heat map.
struct DebugCostRayHook : DebugCostShader {
    static constexpr const char* name = "rk_debug_cost";
    static constexpr const char* source = kernels::kShadeDebugCost;
};
static_assert(RayHook<NormalsRayHook> && RayHook<DepthRayHook> && RayHook<WhittedRayHook> && RayHook<AoRayHook> &&
              RayHook<DebugCostRayHook>);
static_assert(hook_counts_steps<DebugCostRayHook>() && !hook_counts_steps<WhittedRayHook>());

/// What a device frame did. Bounce slots as in render/shade.hpp (kBounceSlots: 0, 1, 2, 3+).
struct DeviceRenderStats {
    std::uint64_t primary = 0, continuation = 0, shadow = 0;  ///< rays traced per kind (shadow: any-hit, ao included)
    unsigned passes = 0;            ///< sample passes (= spp)
    unsigned bounces = 0;           ///< most closest-hit launches (queues traced) in one pass
    std::size_t peak_queue = 0;     ///< most rays in one queue (camera queue included)
    std::size_t queue_bytes = 0;    ///< device memory held by the ray queues and hits after the frame
    double render_ms = 0.0;         ///< wall time of the frame (launches to image read back and resolved)
    /// Device time per stage (profiling events, summed over passes and bounces), and the host's
    /// read-back, 1/spp and heat map (resolve).
    double camera_ms = 0.0, trace_ms = 0.0, shade_ms = 0.0, shadow_ms = 0.0, resolve_ms = 0.0;
    std::uint64_t bounce_rays[kBounceSlots] = {};  ///< closest-hit + shadow rays per bounce slot
    double bounce_ms[kBounceSlots] = {};           ///< closest-hit + shadow kernel time per bounce slot
    std::uint64_t total() const noexcept { return primary + continuation + shadow; }
    /// Rays of bounce slot b per second of its closest-hit and shadow kernels, in millions.
    double bounce_mrays_per_second(unsigned b) const noexcept {
        return b < kBounceSlots && bounce_ms[b] > 0.0 ? double(bounce_rays[b]) / (bounce_ms[b] * 1e3) : 0.0;
    }
};

namespace detail {
/// Throws std::invalid_argument unless `name` is a C identifier (it names OpenCL C functions).
inline void check_ray_hook_name(const std::string& name) {
    bool ok = !name.empty() && !(name[0] >= '0' && name[0] <= '9');
    for (char c : name) ok = ok && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_');
    if (!ok) throw std::invalid_argument("raykit::cl: ray hook name \"" + name + "\" is not a C identifier");
}
}  // namespace detail

/// Whether hook H's closest-hit and shadow rays walk as packets when `packet_walk` asks for them:
/// not for a hook that counts traversal steps (the packet walk counts none).
template <RayHook H>
constexpr bool hook_packets(bool packet_walk) noexcept {
    return packet_walk && !hook_counts_steps<H>();
}

/// Program of hook H for the renderer: base parts, camera, the shading data (with the alpha
/// cut-out leaf filter when `cut_outs`), the walk (and the packet walk when `packets`: the
/// closest-hit and shadow kernels then take kPacketRays rays per work-item), the shade API, the
/// hook, the check of its params size, its shade kernel rk_dr_shade_NAME (cached per process).
/// `packets` is taken through hook_packets; the walks read nodes of the form `form` (the scene's
/// DeviceSceneArrays::node_form()).
template <RayHook H>
Program ray_hook_program(Device& dev, bool cut_outs = false, bool packets = false, NodeForm form = NodeForm::full) {
    const std::string name = H::name;
    detail::check_ray_hook_name(name);
    std::vector<SourcePart> parts = base_parts();
    packets = hook_packets<H>(packets);
    if constexpr (hook_counts_steps<H>())
        parts.push_back({"<hook " + name + " options>", "#define RK_DR_STEPS 1\n"});
    if (cut_outs) parts.push_back({"<alpha cut-outs>", "#define RK_LEAF_FILTER 1\n"});
    parts.push_back({"raykit/kernels/camera.hpp", kernels::kCamera});
    parts.push_back({"raykit/kernels/shade.hpp (data)", kernels::kShadeData});
    for (SourcePart& p : trace_parts(packets, TraceKernels::none, form)) parts.push_back(std::move(p));
    parts.push_back({"raykit/kernels/shade.hpp", kernels::kShade});
    parts.push_back({"<hook " + name + ">", H::source});
    const std::string size = std::to_string(sizeof(typename H::Params));
    parts.push_back({"<hook " + name + " params check>",
                     "typedef char rk_ray_hook_" + name + "_params_must_be_" + size +
                         "_bytes_like_the_Cpp_Params[(sizeof(" + name + "_params) == " + size + ") ? 1 : -1];\n"});
    std::string stage = kernels::kShadeStage;
    for (std::size_t at = stage.find("@NAME@"); at != std::string::npos; at = stage.find("@NAME@", at))
        stage.replace(at, 6, name);
    parts.push_back({"raykit/kernels/shade.hpp (" + name + ")", stage});
    return build_program(dev, assemble(parts), raykit_build_options(dev));
}

class DeviceRenderer {
public:
    /// Renders `scene` as it stands after its last update(), with one material table per object
    /// of its Scene (in object order) and `lights`. The DeviceScene and its Scene must outlive
    /// the renderer (they are read at each render: call scene.update() after moving it; a
    /// render after an instance was added or moved without it throws std::logic_error); the
    /// tables and lights are copied. The depth and ao defaults use the world boxes of the
    /// instances (set_bounds() to replace them). Throws std::invalid_argument when there is not
    /// one table per object.
    DeviceRenderer(const DeviceSceneArrays& scene, std::span<const MaterialTable> materials,
                   std::span<const Light> lights)
        : dev_(&scene.device()), scene_(&scene) {
        upload_shading(materials);
        set_lights(lights);
    }
    /// Uploads `scene` (from make_shade_scene / RenderScene::view) into a DeviceScene of its own:
    /// the scene need not outlive the renderer (instances and vertices as they are now); its walks
    /// read nodes of the form `form` where the trees allow it.
    DeviceRenderer(Device& dev, const ShadeScene& scene, NodeForm form = NodeForm::full) : dev_(&dev) {
        if (!scene.scene)
            throw std::invalid_argument("raykit::cl::DeviceRenderer: incomplete ShadeScene (use make_shade_scene)");
        auto own = std::make_unique<DeviceScene<>>(dev, *scene.scene, DeviceRebuild{}, form);
        own->update();
        scene_ = own.get();
        own_ = std::move(own);
        bounds_ = scene.bounds;
        fixed_bounds_ = true;
        upload_shading(scene.materials);
        set_lights(scene.lights);
    }

    /// The box whose corners and diagonal give the depth shader's far distance and the ao
    /// radius when the settings leave them 0 (as the CPU's ShadeScene::bounds).
    void set_bounds(const AABB& b) {
        bounds_ = b;
        fixed_bounds_ = true;
    }

    /// Whether closest-hit and shadow rays walk as packets of kPacketRays (kernels/raykit/kernels/
    /// trace_packet.hpp; never for a hook that counts traversal steps). Default:
    /// packet_walk_default (CPU devices). The images are the same either way.
    bool packet_walk() const noexcept { return packets_; }
    /// Turns the packet walk on or off (for a comparison, or a device where it measures faster).
    void set_packet_walk(bool on) noexcept { packets_ = on; }

    /// Replaces the lights.
    void set_lights(std::span<const Light> lights) {
        std::vector<LightRecord> rec;
        for (const Light& l : lights) {
            LightRecord r{};
            for (int c = 0; c < 3; ++c) {
                r.position[c] = l.position[c];
                r.direction[c] = l.direction[c];
                r.color[c] = l.color[c];
            }
            r.type = l.type == Light::Type::point ? 0u : 1u;
            rec.push_back(r);
        }
        light_count_ = static_cast<std::uint32_t>(rec.size());
        lights_ = Buffer<LightRecord>(*dev_, rec, CL_MEM_READ_ONLY);
    }

    /// Renders with the built-in hook for set.shade.shader (every ShaderKind), `set.spp` samples
    /// per pixel placed by PixelSampler; debug_cost images are mapped with cost_heat_map
    /// (set.cost_scale) as render_cpu maps them. Throws std::invalid_argument for spp == 0 and an
    /// invalid camera.
    Image render(const Camera& cam, const RenderSettings& set, DeviceRenderStats* stats = nullptr) {
        switch (set.shade.shader) {
            case ShaderKind::normals: return render_hook<NormalsRayHook>(cam, set, {}, stats);
            case ShaderKind::depth: return render_hook<DepthRayHook>(cam, set, {}, stats);
            case ShaderKind::ao: return render_hook<AoRayHook>(cam, set, {}, stats);
            case ShaderKind::debug_cost: {
                using Clock = std::chrono::steady_clock;
                Image img = render_hook<DebugCostRayHook>(cam, set, {}, stats);
                const auto t0 = Clock::now();
                cost_heat_map(img, set.cost_scale);
                if (stats) {
                    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
                    stats->resolve_ms += ms;
                    stats->render_ms += ms;
                }
                return img;
            }
            case ShaderKind::whitted: return render_hook<WhittedRayHook>(cam, set, {}, stats);
        }
        throw std::invalid_argument("raykit::cl::DeviceRenderer: unknown shader");
    }
    /// One sample at each pixel centre (render_cpu with spp = 1, jitter = false).
    Image render(const Camera& cam, const ShadeSettings& set, DeviceRenderStats* stats = nullptr) {
        return render(cam, centre_sample(set), stats);
    }

    /// Renders with ray hook H (see the header comment): set.spp passes, samples placed by
    /// PixelSampler(set.spp, set.seed, set.jitter). `set.shade` supplies max_depth, ambient,
    /// background, filter, shadows, depth_far, min_weight, ao_samples and ao_radius to the hook
    /// (ctx->set). The image is the mean over the samples, with no further mapping.
    template <RayHook H>
    Image render_hook(const Camera& cam, const RenderSettings& set, const typename H::Params& params = {},
                      DeviceRenderStats* stats = nullptr) {
        using Clock = std::chrono::steady_clock;
        const auto t0 = Clock::now();
        if (set.spp == 0) throw std::invalid_argument("raykit::cl::DeviceRenderer: spp must be at least 1");
        const CameraFrame frame = cam.frame();
        const std::size_t n_pixels = std::size_t(frame.width) * frame.height;
        if (n_pixels >= 0xFFFFFFFFu / 4) throw std::length_error("raykit::cl::DeviceRenderer: image too large");
        if (!own_) scene_->require_fresh();
        Kernels& k = kernels_for<H>();
        const ShadeSettings& shade = set.shade;
        const RenderSettingsRecord rec = settings_record(shade, frame);
        const std::uint32_t max_rays = H::max_rays;
        const std::uint32_t max_shadows = H::max_shadow_rays == kPerLight      ? light_count_
                                          : H::max_shadow_rays == kPerAoSample ? shade.ao_samples
                                                                               : H::max_shadow_rays;
        constexpr bool want_steps = hook_counts_steps<H>();
        const PixelSampler sampler(set.spp, set.seed, set.jitter);

        DeviceRenderStats st;
        st.passes = set.spp;
        Device& dev = *dev_;
        const DeviceSceneArrays& sc = *scene_;
        image_.reserve(dev, n_pixels * 4);
        std::vector<Timed> events;
        for (std::uint32_t pass = 0; pass < set.spp; ++pass) {
            queue_.reserve(dev, n_pixels);
            set_args(k.camera, frame, queue_, image_, static_cast<cl_ulong>(set.seed), pass, set.spp,
                     sampler.grid_side(), sampler.inv_grid_side(), sampler.inv_spp(), set.jitter ? 1u : 0u);
            launch(dev.queue(), k.camera, n_pixels, kTraceGroupSize, &events.emplace_back(Stage::camera, 0u).event);
            std::size_t n = n_pixels;
            st.primary += n;
            st.peak_queue = std::max(st.peak_queue, n);
            std::uint32_t depth = 0;
            for (; n > 0; ++depth) {
                const unsigned slot = bounce_slot(depth);
                hits_.reserve(dev, n);
                steps_.reserve(dev, want_steps ? n : 1);
                set_args(k.closest, sc.top_nodes(), sc.top_count(), sc.top_ids(), sc.instances(), sc.objects(),
                         sc.walk_nodes(), sc.blocks(), sc.triangles(), queue_, hits_, steps_,
                         static_cast<std::uint32_t>(n), sc.vertices(), material_ids_, shade_objects_, materials_,
                         textures_, texels_, rec);
                launch(dev.queue(), k.closest, k.trace_items(n), kTraceGroupSize,
                       &events.emplace_back(Stage::trace, slot).event);
                const std::uint32_t rays_here = depth < shade.max_depth ? max_rays : 0u;
                // one ray per pixel in this bounce (camera rays, or paths that never branch):
                // the shade kernel, and the shadow kernel when each ray has at most one shadow
                // ray, add colours without atomics (kernels/raykit/kernels/shade.hpp)
                const std::uint32_t one_per_pixel = depth == 0 || max_rays <= 1 ? 1u : 0u;
                const std::size_t next_cap = n * rays_here, shadow_cap = n * max_shadows;
                if (next_cap >= 0xFFFFFFFFu || shadow_cap >= 0xFFFFFFFFu)
                    throw std::length_error("raykit::cl::DeviceRenderer: ray queue beyond 2^32 rays");
                next_.reserve(dev, next_cap);
                stage_.reserve(dev, next_cap);
                shadow_.reserve(dev, shadow_cap);
                const std::uint32_t zero[2] = {0u, 0u};
                counters_.write(dev, std::span<const std::uint32_t>(zero, 2));
                set_args(k.shade, queue_, hits_, steps_, static_cast<std::uint32_t>(n), sc.instances(), sc.objects(),
                         sc.triangles(), sc.positions(), sc.vertices(), material_ids_, shade_objects_, materials_,
                         textures_, texels_, srgb_lut_, lights_, rec, image_, next_, stage_, counters_, shadow_,
                         rays_here, max_shadows, one_per_pixel, params);
                launch(dev.queue(), k.shade, n, kTraceGroupSize, &events.emplace_back(Stage::shade, slot).event);
                std::uint32_t cnt[2] = {0u, 0u};
                counters_.read(dev, std::span<std::uint32_t>(cnt, 2));
                const std::size_t next_n = std::min<std::size_t>(cnt[0], next_cap);
                // shadow rays sit in fixed slots (ray i's from i · max_shadows, empty ones marked):
                // the launch covers every slot, cnt[1] counts the rays
                const std::size_t shadow_n = std::min<std::size_t>(cnt[1], shadow_cap);
                if (shadow_n > 0) {
                    set_args(k.shadow, sc.top_nodes(), sc.top_count(), sc.top_ids(), sc.instances(), sc.objects(),
                             sc.walk_nodes(), sc.blocks(), sc.triangles(), shadow_,
                             static_cast<std::uint32_t>(shadow_cap), image_, sc.vertices(), material_ids_,
                             shade_objects_, materials_, textures_, texels_, rec,
                             one_per_pixel != 0 && max_shadows <= 1 ? 1u : 0u);
                    launch(dev.queue(), k.shadow, k.trace_items(shadow_cap), kTraceGroupSize,
                           &events.emplace_back(Stage::shadow, slot).event);
                }
                st.bounce_rays[slot] += n + shadow_n;
                st.shadow += shadow_n;
                st.continuation += next_n;
                st.peak_queue = std::max(st.peak_queue, next_n);
                std::swap(queue_, next_);
                n = next_n;
            }
            st.bounces = std::max(st.bounces, depth);
            if (set.progress) set.progress(pass + 1, set.spp);
        }
        dev.finish();  // the last shadow launch, so that resolve_ms is the read-back alone
        const auto t_resolve = Clock::now();
        const std::span<float> px = readback_.get(dev, n_pixels * 4);
        image_.read(dev, px);
        const float inv_spp = sampler.inv_spp();
        Image img;  // filled once, from the read-back (not cleared first)
        img.width = frame.width;
        img.height = frame.height;
        img.pixels.reserve(n_pixels);
        for (std::size_t i = 0; i < n_pixels; ++i)
            img.pixels.push_back(vec4(px[4 * i], px[4 * i + 1], px[4 * i + 2], px[4 * i + 3]) * inv_spp);
        const auto t_end = Clock::now();
        for (Timed& e : events) {
            if (e.event() == nullptr) continue;  // nothing was launched
            const double ms = event_ms(e.event);
            switch (e.stage) {
                case Stage::camera: st.camera_ms += ms; break;
                case Stage::trace: st.trace_ms += ms; break;
                case Stage::shade: st.shade_ms += ms; break;
                case Stage::shadow: st.shadow_ms += ms; break;
            }
            if (e.stage == Stage::trace || e.stage == Stage::shadow) st.bounce_ms[e.slot] += ms;
        }
        st.queue_bytes =
            queue_.bytes() + next_.bytes() + stage_.bytes() + shadow_.bytes() + hits_.bytes() + steps_.bytes();
        st.resolve_ms = std::chrono::duration<double, std::milli>(t_end - t_resolve).count();
        st.render_ms = std::chrono::duration<double, std::milli>(t_end - t0).count();
        if (stats) *stats = st;
        return img;
    }
    /// render_hook with one sample at each pixel centre (spp = 1, jitter = false).
    template <RayHook H>
    Image render_hook(const Camera& cam, const ShadeSettings& set, const typename H::Params& params = {},
                      DeviceRenderStats* stats = nullptr) {
        return render_hook<H>(cam, centre_sample(set), params, stats);
    }

    /// The camera rays of sample `sample` of every pixel (row-major; the renderer's queue holds
    /// them in 4×4-pixel tiles, kernels/raykit/kernels/shade.hpp rk_dr_camera), as it traces
    /// them: for tests and tools (they equal PixelSampler + CameraFrame::ray on the CPU).
    std::vector<Ray> camera_rays(const Camera& cam, const RenderSettings& set, std::uint32_t sample) {
        if (set.spp == 0 || sample >= set.spp)
            throw std::invalid_argument("raykit::cl::DeviceRenderer::camera_rays: sample must be below spp");
        const CameraFrame frame = cam.frame();
        const std::size_t n_pixels = std::size_t(frame.width) * frame.height;
        Kernels& k = kernels_for<NormalsRayHook>();
        const PixelSampler sampler(set.spp, set.seed, set.jitter);
        Device& dev = *dev_;
        image_.reserve(dev, n_pixels * 4);
        queue_.reserve(dev, n_pixels);
        set_args(k.camera, frame, queue_, image_, static_cast<cl_ulong>(set.seed), sample, set.spp,
                 sampler.grid_side(), sampler.inv_grid_side(), sampler.inv_spp(), set.jitter ? 1u : 0u);
        launch(dev.queue(), k.camera, n_pixels, kTraceGroupSize);
        std::vector<PathRay> q(n_pixels);
        queue_.read(dev, std::span<PathRay>(q));
        std::vector<Ray> rays(n_pixels);
        for (std::size_t i = 0; i < n_pixels; ++i) {
            if (q[i].pixel >= n_pixels) throw std::logic_error("raykit::cl::DeviceRenderer::camera_rays: bad pixel");
            rays[q[i].pixel] = q[i].ray;
        }
        return rays;
    }

    /// Builds (or finds) the program and kernels of hook H now, e.g. before timing frames.
    template <RayHook H>
    const Program& prepare() {
        return kernels_for<H>().program;
    }

    Device& device() noexcept { return *dev_; }

private:
    struct Kernels {
        Program program;
        ::cl::Kernel camera, closest, shadow, shade;
        bool packets = false;  ///< closest and shadow take kPacketRays rays per work-item
        /// Work-items of a closest-hit or shadow launch over n rays.
        std::size_t trace_items(std::size_t n) const noexcept { return cl::trace_items(n, packets); }
    };
    enum class Stage { camera, trace, shade, shadow };
    struct Timed {
        Timed(Stage s, unsigned b) : stage(s), slot(b) {}
        Stage stage;
        unsigned slot;
        ::cl::Event event;
    };
    /// Device time of a finished command (profiling info), in ms.
    static double event_ms(const ::cl::Event& e) {
        cl_ulong start = 0, end = 0;
        check(e.getProfilingInfo(CL_PROFILING_COMMAND_START, &start), "clGetEventProfilingInfo");
        check(e.getProfilingInfo(CL_PROFILING_COMMAND_END, &end), "clGetEventProfilingInfo");
        return end > start ? double(end - start) * 1e-6 : 0.0;
    }
    static RenderSettings centre_sample(const ShadeSettings& s) {
        RenderSettings r;
        r.spp = 1;
        r.jitter = false;
        r.shade = s;
        return r;
    }

    template <RayHook H>
    Kernels& kernels_for() {
        const bool packets = hook_packets<H>(packets_);
        const NodeForm form = scene_->node_form();
        const std::string key = std::string(alpha_testing_ ? "cut-outs\n" : "") + (packets ? "packets\n" : "") +
                                (form == NodeForm::quantized ? "quantized\n" : "") + H::name + '\n' + H::source;
        if (auto it = kernels_.find(key); it != kernels_.end()) return it->second;
        Kernels k;
        k.packets = packets;
        k.program = ray_hook_program<H>(*dev_, alpha_testing_, packets, form);
        k.camera = k.program.kernel("rk_dr_camera");
        k.closest = k.program.kernel(packets ? "rk_dr_closest_packet" : "rk_dr_closest");
        k.shadow = k.program.kernel(packets ? "rk_dr_shadow_packet" : "rk_dr_shadow");
        k.shade = k.program.kernel(std::string("rk_dr_shade_") + H::name);
        return kernels_.emplace(key, std::move(k)).first->second;
    }

    /// Uploads the concatenated material table, textures, material ids and per-object records.
    void upload_shading(std::span<const MaterialTable> tables) {
        const Scene& scene = scene_->scene();
        const auto& objs = scene.objects();
        const auto& recs = scene_->object_records();
        if (tables.size() != objs.size())
            throw std::invalid_argument("raykit::cl::DeviceRenderer: one MaterialTable per object needed (" +
                                        std::to_string(objs.size()) + " objects, " + std::to_string(tables.size()) +
                                        " tables)");
        // textures: one byte buffer, a table of (offset, size, srgb); shared textures once
        std::map<const Texture*, std::int32_t> tex_index;
        std::vector<TextureRecord> tex_records;
        std::vector<std::uint8_t> texels;
        auto add_texture = [&](const Texture* t) -> std::int32_t {
            if (!t) return -1;
            if (auto it = tex_index.find(t); it != tex_index.end()) return it->second;
            if (texels.size() / 4 + std::size_t(t->width) * t->height >= 0xFFFFFFFFu)
                throw std::length_error("raykit::cl::DeviceRenderer: textures exceed 2^32 texels");
            TextureRecord r{static_cast<std::uint32_t>(texels.size() / 4), t->width, t->height, t->srgb ? 1u : 0u};
            if (t->empty()) r.width = r.height = 0;
            texels.insert(texels.end(), t->rgba.begin(), t->rgba.end());
            const auto idx = static_cast<std::int32_t>(tex_records.size());
            tex_records.push_back(r);
            tex_index.emplace(t, idx);
            return idx;
        };
        std::size_t triangles = 0;
        for (const ObjectRecord& r : recs) triangles = std::max<std::size_t>(triangles, std::size_t(r.triangle_offset) + r.triangle_count);
        std::vector<std::uint32_t> ids(triangles, 0u);
        std::vector<MaterialRecord> mats;
        std::vector<ShadeObjectRecord> so(objs.size());
        alpha_testing_ = false;
        for (std::size_t o = 0; o < objs.size(); ++o) {
            const MaterialTable& mt = tables[o];
            const Mesh& m = objs[o].mesh;
            so[o].material_offset = static_cast<std::uint32_t>(mats.size());
            so[o].material_count = static_cast<std::uint32_t>(mt.materials.size());
            for (const RenderMaterial& rm : mt.materials) {
                MaterialRecord r{};
                for (int c = 0; c < 3; ++c) {
                    r.kd[c] = rm.kd[c];
                    r.ks[c] = rm.ks[c];
                    r.ke[c] = rm.ke[c];
                    r.mirror[c] = rm.mirror[c];
                }
                r.ns = rm.ns;
                r.ni = rm.ni;
                r.transparency = rm.transparency;
                r.texture = add_texture(rm.map_kd);
                r.fresnel_mirror = rm.fresnel_mirror ? 1 : 0;
                r.alpha_tested = rm.alpha_tested ? 1 : 0;
                r.illum = rm.illum;
                mats.push_back(r);
            }
            const std::size_t with_id = std::min(m.material_ids.size(), m.triangles.size());
            so[o].material_id_count = static_cast<std::uint32_t>(with_id);
            std::copy_n(m.material_ids.begin(), with_id, ids.begin() + recs[o].triangle_offset);
            so[o].flags = (m.normals.empty() ? 0u : kShadeNormals) | (m.texcoords.empty() ? 0u : kShadeUvs);
            alpha_testing_ = alpha_testing_ || mt.any_alpha_tested();
        }
        if (mats.size() >= 0xFFFFFFFFu) throw std::length_error("raykit::cl::DeviceRenderer: too many materials");
        material_count_ = static_cast<std::uint32_t>(mats.size());
        object_count_ = static_cast<std::uint32_t>(objs.size());
        Device& dev = *dev_;
        materials_ = Buffer<MaterialRecord>(dev, mats, CL_MEM_READ_ONLY);
        material_ids_ = Buffer<std::uint32_t>(dev, ids, CL_MEM_READ_ONLY);
        shade_objects_ = Buffer<ShadeObjectRecord>(dev, so, CL_MEM_READ_ONLY);
        textures_ = Buffer<TextureRecord>(dev, tex_records, CL_MEM_READ_ONLY);
        texels_ = Buffer<std::uint8_t>(dev, texels, CL_MEM_READ_ONLY);
        srgb_lut_ = Buffer<float>(dev, std::span<const float>(raykit::detail::srgb8_lut, 256), CL_MEM_READ_ONLY);
        counters_ = Buffer<std::uint32_t>(dev, 2);
    }

    /// set_bounds()'s box, else the world boxes of the instances as of the last update().
    AABB bounds() const {
        if (fixed_bounds_) return bounds_;
        AABB b;
        const Scene& scene = scene_->scene();
        const auto& roots = scene_->root_boxes();
        for (const SceneInstance& in : scene.instances())
            b.grow(in.identity ? roots[in.object] : transformed_box(roots[in.object], in.transform));
        return b;
    }

    RenderSettingsRecord settings_record(const ShadeSettings& s, const CameraFrame& frame) const {
        const AABB box = bounds();
        RenderSettingsRecord r{};
        for (int c = 0; c < 3; ++c) {
            r.ambient[c] = s.ambient[c];
            r.background[c] = s.background[c];
        }
        r.min_weight = s.min_weight;
        const ShadeSettings rs = resolve_shade_settings(s, box, frame.origin);  // the CPU's rule
        r.depth_far = rs.depth_far;
        r.width = frame.width;
        r.height = frame.height;
        r.max_depth = s.max_depth;
        r.shadows = s.shadows ? 1u : 0u;
        r.filter = s.filter == TextureFilter::nearest ? 1u : 0u;
        r.light_count = light_count_;
        r.object_count = object_count_;
        r.material_count = material_count_;
        r.alpha_testing = alpha_testing_ ? 1u : 0u;
        r.ao_samples = s.ao_samples;
        r.ao_radius = rs.ao_radius;
        return r;
    }

    Device* dev_;
    const DeviceSceneArrays* scene_ = nullptr;
    std::unique_ptr<DeviceScene<>> own_;  ///< the ShadeScene constructor's upload
    AABB bounds_;
    bool fixed_bounds_ = false;
    Buffer<float> srgb_lut_, image_;
    HostStage<float> readback_;  ///< the image read back (pinned on NVIDIA: resolve was 2.0 of 2.36 ms on an H200)
    Buffer<std::uint32_t> material_ids_, counters_, steps_;
    Buffer<ShadeObjectRecord> shade_objects_;
    Buffer<MaterialRecord> materials_;
    Buffer<TextureRecord> textures_;
    Buffer<std::uint8_t> texels_;
    Buffer<LightRecord> lights_;
    Buffer<PathRay> queue_, next_, stage_;  ///< stage_: continuation rays in fixed slots before compaction
    Buffer<ShadowRay> shadow_;
    Buffer<Hit> hits_;
    std::uint32_t object_count_ = 0, material_count_ = 0, light_count_ = 0;
    bool alpha_testing_ = false;
    bool packets_ = packet_walk_default(*dev_);  ///< see packet_walk()
    std::map<std::string, Kernels> kernels_;
};

}  // namespace raykit::cl
