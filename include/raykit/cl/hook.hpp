// raykit/cl/hook.hpp — vertex hooks: user code that moves dynamic vertices.
//
// A vertex hook is a C++ type carrying its OpenCL C source, its parameter
// layout and a CPU twin:
//
//   struct WaveHook {
//       static constexpr const char* name = "wave";   // a C identifier
//       struct Params { float time, amplitude, frequency, pad; };
//       static constexpr const char* source = R"(
//           typedef struct { float time, amplitude, frequency, pad; } wave_params;
//           rk_vertex wave(rk_vertex v, uint index, wave_params p) { ... return v; }
//       )";
//       static Vertex apply(const Vertex& v, std::uint32_t index, const Params& p);  // CPU twin
//   };
//
// The source must define the struct NAME_params (same layout as Params:
// its size is checked when the program is compiled, so a mismatch is a
// build error naming the hook) and the function
//   rk_vertex NAME(rk_vertex v, uint index, NAME_params p)
// which returns the moved vertex; `index` is the vertex's index within its
// object. It may use rk_vertex_position / rk_vertex_set_position /
// rk_vertex_normal / rk_vertex_set_normal (kernels/raykit/kernels/layout.hpp).
// Compiler messages about the source name "<hook NAME>" and the line within
// the hook's own text.
//
// Global buffers (optional). Params travel by value; a hook that needs
// arrays (skinning: per-vertex links, per-frame bone matrices) also declares
//
//   static constexpr std::array<const char*, N> buffers = {"uint", "ushort2", "float"};
//
// the OpenCL C element types (type names, identifiers) of N read-only
// global buffers. Its function
// then takes them after the params:
//   rk_vertex NAME(rk_vertex v, uint index, NAME_params p,
//                  __global const uint* b0, __global const ushort2* b1, __global const float* b2)
// (the vertex-stage kernel gets the extra parameters rk_hook_buf0.. and
// passes them on). The buffers belong to the hook, not to an object: every
// object the hook moves in one launch sees the same buffers, and its Params
// say where its own data lies in them (e.g. a first-vertex / first-bone
// offset). The caller uploads them with
//   DeviceScene::set_hook_buffer<H>(slot, std::span<const T> data)
// (slot < N; reuses the device allocation when it is large enough, so a
// per-frame upload of bone matrices allocates nothing); update() throws
// std::logic_error if a used hook has a slot never set. A buffer hook's CPU
// twin may take whatever host data it needs (apply(v, i, p) is then not
// required; see raykit/anim/skin_hook.hpp for SkinHook). Hooks without
// `buffers` are unchanged.
//
// Hooks are template arguments of raykit::cl::DeviceScene; only hooks that
// some object of the scene uses are compiled into its program. On the CPU,
// Scene::move_vertices(object, [&](const Vertex& v, std::uint32_t i) {
// return H::apply(v, i, params); }) is the same stage. Transcendental
// functions (sin, cos, ...) are not correctly rounded in OpenCL, so CPU and
// device vertices may differ in the last bits unless the hook avoids them.
#pragma once

#include <array>
#include <cmath>
#include <cstddef>
#include <concepts>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "raykit/cl/program.hpp"
#include "raykit/kernels/vertex.hpp"
#include "raykit/scene/scene.hpp"

namespace raykit::cl {

/// Number of global buffers hook H declares (H::buffers; 0 without).
template <class H>
constexpr std::size_t hook_buffer_count() {
    if constexpr (requires { H::buffers; })
        return std::size(H::buffers);
    else
        return 0;
}

template <class H>
concept VertexHook = requires {
    { H::name } -> std::convertible_to<const char*>;
    { H::source } -> std::convertible_to<const char*>;
} && std::is_trivially_copyable_v<typename H::Params> &&
    (hook_buffer_count<H>() > 0 ||
     requires(const Vertex& v, std::uint32_t i, const typename H::Params& p) {
         { H::apply(v, i, p) } -> std::convertible_to<Vertex>;
     });

/// Throws std::invalid_argument unless `name` is a C identifier.
inline void check_hook_name(std::string_view name) {
    bool ok = !name.empty() && !(name[0] >= '0' && name[0] <= '9');
    for (char c : name) ok = ok && ((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_');
    if (!ok) throw std::invalid_argument("raykit::cl: hook name \"" + std::string(name) + "\" is not a C identifier");
}

/// The program parts of hook H: its source (as "<hook NAME>"), the
/// compile-time check of NAME_params against sizeof(H::Params), and its
/// vertex-stage kernel rk_vertex_stage_NAME.
template <VertexHook H>
std::vector<SourcePart> hook_parts() {
    const std::string name = H::name;
    check_hook_name(name);
    std::string stage = kernels::kVertexStage;
    for (std::size_t at = stage.find("@NAME@"); at != std::string::npos; at = stage.find("@NAME@", at))
        stage.replace(at, 6, name);
    std::string buf_params, buf_args;
    if constexpr (hook_buffer_count<H>() > 0) {
        for (std::size_t b = 0; b < hook_buffer_count<H>(); ++b) {
            const std::string type = H::buffers[b];
            check_hook_name(type);  // an OpenCL C type name, e.g. "uint" / "ushort2" / "float"
            buf_params += ", __global const " + type + "* rk_hook_buf" + std::to_string(b);
            buf_args += ", rk_hook_buf" + std::to_string(b);
        }
    }
    auto subst = [&](const std::string& key, const std::string& value) {
        for (std::size_t at = stage.find(key); at != std::string::npos; at = stage.find(key, at + value.size()))
            stage.replace(at, key.size(), value);
    };
    subst("@BUFFER_PARAMS@", buf_params);
    subst("@BUFFER_ARGS@", buf_args);
    const std::string size = std::to_string(sizeof(typename H::Params));
    std::string check = "typedef char rk_hook_" + name + "_params_must_be_" + size + "_bytes_like_the_Cpp_Params[(sizeof(" +
                        name + "_params) == " + size + ") ? 1 : -1];\n";
    return {{"<hook " + name + ">", H::source},
            {"<hook " + name + " params check>", check},
            {"raykit/kernels/vertex.hpp (" + name + ")", stage}};
}

/// Built-in hook: a travelling wave along z,
///   z += amplitude · sin(frequency·x + time) · cos(frequency·y + time/2).
/// Used by the CLI's animate test, the tests and the benchmarks.
struct WaveHook {
    static constexpr const char* name = "wave";
    struct Params {
        float time = 0.0f;
        float amplitude = 0.05f;
        float frequency = 4.0f;
        float pad = 0.0f;
    };
    static constexpr const char* source = R"CLC(typedef struct {
    float time;
    float amplitude;
    float frequency;
    float pad;
} wave_params;

rk_vertex wave(rk_vertex v, uint index, wave_params p) {
    float3 q = rk_vertex_position(v);
    q.z += p.amplitude * sin(p.frequency * q.x + p.time) * cos(p.frequency * q.y + 0.5f * p.time);
    return rk_vertex_set_position(v, q);
}
)CLC";
    static Vertex apply(const Vertex& v, std::uint32_t /*index*/, const Params& p) {
        Vertex o = v;
        o.position.z += p.amplitude * std::sin(p.frequency * v.position.x + p.time) *
                        std::cos(p.frequency * v.position.y + 0.5f * p.time);
        return o;
    }
};
static_assert(VertexHook<WaveHook>);

/// Built-in hook: scales positions about the origin (exact in float: the
/// CPU twin and the device agree bit for bit), for tests.
struct ScaleHook {
    static constexpr const char* name = "scale";
    struct Params {
        float factor = 1.0f;
    };
    static constexpr const char* source = R"CLC(typedef struct {
    float factor;
} scale_params;

rk_vertex scale(rk_vertex v, uint index, scale_params p) {
    for (int a = 0; a < 3; ++a) v.position[a] = v.position[a] * p.factor;
    return v;
}
)CLC";
    static Vertex apply(const Vertex& v, std::uint32_t, const Params& p) {
        Vertex o = v;
        o.position = v.position * p.factor;
        return o;
    }
};
static_assert(VertexHook<ScaleHook>);

}  // namespace raykit::cl
