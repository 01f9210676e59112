// SMD reference + animation + CPU skinning (io/smd.hpp, anim/). The input is a
// reference SMD, optionally followed by a line `%%ANIM` and an animation SMD
// (without the marker the reference is also read as its own animation, as a
// reference's skeleton block is one). Both are parsed in memory with
// parse_smd_reference / parse_smd_animation (textures resolve against an empty
// scratch folder). Bad input must be a ParseError "NAME:LINE: ..." naming
// ref.smd or anim.smd at a line of that text (1 .. its line count; line 0 is
// only for unreadable files). A reference that parses must have: one bind pose
// per bone, parents that are bones without cycles (Skeleton accepts them),
// normals/texcoords/weights one per vertex, triangle indices < vertex count,
// one material id per triangle naming a material, finite positions, normals,
// texcoords and poses, and per vertex distinct link bones < bone count with
// finite weights > 0 summing to 1; pack_skin accepts the weights. An
// animation that parses must have one key per time, times[0] == 0 and
// increasing, one pose per reference bone per key, frame_count() ==
// times.back() + 1, key_of_frame consistent with times, finite poses, and at
// most kSmdMaxAnimPoses poses. Skinning the bind pose and a few frames
// (first, last, one fractional, looping) on the CPU must give finite
// positions and normals whenever every input coordinate is within 1e6
// (beyond that float overflow is the input's, not a bug), and a unit normal
// of a one-bone vertex stays unit.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_text.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/io/smd.hpp"

namespace {

void check(bool ok) {
    if (!ok) __builtin_trap();
}

bool finite3(const raykit::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

constexpr float kBounded = 1e6f;
bool bounded3(const raykit::vec3& v) {
    return std::abs(v.x) <= kBounded && std::abs(v.y) <= kBounded && std::abs(v.z) <= kBounded;
}

/// An empty folder for texture lookups: the process's own, removed at exit.
const std::filesystem::path& scratch_dir() {
    struct Scratch {
        std::filesystem::path path;
        Scratch() {
            std::string tmpl = (std::filesystem::temp_directory_path() / "raykit_fuzz_smd_XXXXXX").string();
            if (::mkdtemp(tmpl.data())) path = tmpl;
        }
        ~Scratch() {
            std::error_code ec;
            if (!path.empty()) std::filesystem::remove_all(path, ec);
        }
    };
    static const Scratch dir;
    return dir.path;
}

std::size_t line_count(std::string_view text) {
    std::size_t n = 1;
    for (char c : text) n += c == '\n';
    return n;
}

void check_error(const raykit::ParseError& e, const std::string& name, std::string_view text) {
    check(e.file() == name);
    if (e.line() == 0) {  // only odd-length UTF-16 is an error of no line
        check(raykit_fuzz::line_zero_allowed(text));
        check(std::string(e.what()).rfind(name + ": ", 0) == 0);
        return;
    }
    check(e.line() <= line_count(raykit_fuzz::lines_view(text)));  // UTF-16 is read decoded
    const std::string prefix = name + ":" + std::to_string(e.line()) + ": ";
    check(std::string(e.what()).rfind(prefix, 0) == 0);
}

void check_pose(const raykit::BonePose& p) { check(finite3(p.position) && finite3(p.rotation)); }

/// Checks the model; returns whether every coordinate is within kBounded.
bool check_model(const raykit::SmdModel& m) {
    const std::size_t nb = m.bones.size(), nv = m.mesh.positions.size(), nt = m.mesh.triangles.size();
    check(nb <= 65535);
    check(m.bind_pose.size() == nb);
    bool bounded = true;
    for (const raykit::Bone& b : m.bones) check(b.parent >= -1 && b.parent < static_cast<int>(nb));
    for (const raykit::BonePose& p : m.bind_pose) {
        check_pose(p);
        bounded = bounded && bounded3(p.position);
    }
    check(m.mesh.normals.size() == nv && m.mesh.texcoords.size() == nv && m.weights.size() == nv);
    for (const raykit::Triangle& t : m.mesh.triangles) {
        for (std::uint32_t i : t.v) check(i < nv);
    }
    check(m.mesh.material_ids.size() == nt);
    for (std::uint32_t id : m.mesh.material_ids) check(id < m.mesh.materials.size());
    for (std::size_t v = 0; v < nv; ++v) {
        check(finite3(m.mesh.positions[v]) && finite3(m.mesh.normals[v]));
        check(std::isfinite(m.mesh.texcoords[v].x) && std::isfinite(m.mesh.texcoords[v].y));
        bounded = bounded && bounded3(m.mesh.positions[v]) && bounded3(m.mesh.normals[v]);
        const std::vector<raykit::BoneWeight>& links = m.weights[v].links;
        check(!links.empty());
        double sum = 0.0;
        std::set<std::uint32_t> seen;
        for (const raykit::BoneWeight& l : links) {
            check(l.bone < nb);
            check(std::isfinite(l.weight) && l.weight > 0.0f);
            check(seen.insert(l.bone).second);
            sum += l.weight;
        }
        check(std::abs(sum - 1.0) <= 1e-6 * static_cast<double>(links.size()) + 1e-6);
    }
    return bounded;
}

/// Checks the animation; returns whether every pose position is within kBounded.
bool check_anim(const raykit::SmdSkeletonAnim& a, std::size_t bones) {
    check(!a.frames.empty());
    check(a.times.size() == a.frames.size());
    check(a.times.front() == 0);
    check(a.frames.size() * std::max<std::size_t>(bones, 1) <= raykit::kSmdMaxAnimPoses);
    check(a.frame_count() == static_cast<std::size_t>(a.times.back()) + 1);
    bool bounded = true;
    for (std::size_t k = 0; k < a.frames.size(); ++k) {
        if (k > 0) check(a.times[k] > a.times[k - 1]);
        check(a.frames[k].size() == bones);
        check(a.key_of_frame(a.times[k]) == k);
        if (a.times[k] > 0) check(a.key_of_frame(a.times[k] - 1) == k - 1);
        for (const raykit::BonePose& p : a.frames[k]) {
            check_pose(p);
            bounded = bounded && bounded3(p.position);
        }
    }
    return bounded;
}

float length2(const raykit::vec3& v) { return v.x * v.x + v.y * v.y + v.z * v.z; }

/// Skinned positions and normals: finite for bounded input; a one-bone
/// vertex (a rotation, no blending) keeps a unit normal unit.
void check_skinned(const raykit::SmdModel& m, const std::vector<raykit::vec3>& p, const std::vector<raykit::vec3>& n,
                   bool bounded) {
    if (!bounded) return;
    for (std::size_t v = 0; v < p.size(); ++v) {
        check(finite3(p[v]) && finite3(n[v]));
        const float rest = length2(m.mesh.normals[v]);
        if (m.weights[v].links.size() == 1 && rest > 0.25f && rest < 4.0f) {
            check(std::abs(length2(n[v]) - 1.0f) < 1e-3f);
        }
    }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view input(reinterpret_cast<const char*>(data), size);
    constexpr std::string_view kMarker = "\n%%ANIM\n";
    const std::size_t cut = input.find(kMarker);
    const std::string_view ref_text = input.substr(0, cut);
    const std::string_view anim_text = cut == std::string_view::npos ? input : input.substr(cut + kMarker.size());

    raykit::SmdModel model;
    try {
        model = raykit::parse_smd_reference(ref_text, "ref.smd", scratch_dir());
    } catch (const raykit::ParseError& e) {
        check_error(e, "ref.smd", ref_text);
        return 0;
    }
    const bool model_bounded = check_model(model);
    // Anything but a ParseError escaping from here is a finding (libFuzzer reports it).
    const raykit::Skeleton skeleton(model);
    const raykit::PackedSkin skin = raykit::pack_skin(model.weights, model.bones.size());
    check(skin.vertex_count() == model.mesh.positions.size());
    const std::size_t nv = model.mesh.positions.size();
    std::vector<raykit::vec3> pos(nv), nrm(nv);
    auto skin_pose = [&](const std::vector<raykit::BoneTransform>& local, bool bounded) {
        const std::vector<raykit::SkinMatrix> mats = raykit::skin_matrices(skeleton, local);
        check(mats.size() == model.bones.size());
        raykit::skin_vertices(skin, mats, model.mesh.positions, model.mesh.normals, pos, nrm, 1);
        check_skinned(model, pos, nrm, bounded);
    };
    skin_pose(skeleton.bind_transforms(), model_bounded);

    raykit::SmdSkeletonAnim anim;
    try {
        anim = raykit::parse_smd_animation(anim_text, "anim.smd", model.bones, model.bind_pose);
    } catch (const raykit::ParseError& e) {
        check_error(e, "anim.smd", anim_text);
        return 0;
    }
    const bool bounded = check_anim(anim, model.bones.size()) && model_bounded;
    const double last = static_cast<double>(anim.frame_count() - 1);
    const double frac = static_cast<double>(size % 97) / 97.0;  // some fraction the input picks
    for (double f : {0.0, last, frac * last, last + 0.5}) {
        const raykit::WrapMode wrap = f > last ? raykit::WrapMode::loop : raykit::WrapMode::clamp;
        for (raykit::Interpolation mode : {raykit::Interpolation::slerp, raykit::Interpolation::euler}) {
            const std::vector<raykit::BoneTransform> local = raykit::sample_frame(anim, f, mode, wrap);
            check(local.size() == model.bones.size());
            skin_pose(local, bounded);
        }
    }
    return 0;
}
