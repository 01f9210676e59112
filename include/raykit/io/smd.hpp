// raykit/io/smd.hpp — Valve StudioMDL Data (SMD) loader: reference meshes and
// skeletal animations (Half-Life 1 and Half-Life 2 / Source flavours).
//
// Interface
// ---------
//   struct Bone          { std::string name; int parent; };        // parent -1 = root
//   struct BonePose      { vec3 position; vec3 rotation; };        // local to the parent;
//                                                                  // rotation = Euler XYZ radians
//   struct BoneWeight    { std::uint32_t bone; float weight; };
//   struct VertexWeights { std::vector<BoneWeight> links; };       // weights > 0, sum 1
//   struct SmdModel      { bones, bind_pose, mesh, weights };
//   struct SmdSkeletonAnim { frames, fps = 30, warnings };
//
//   SmdModel load_smd_reference(const std::filesystem::path& file);
//   SmdModel parse_smd_reference(std::string_view text, const std::string& name_for_errors,
//                                const std::filesystem::path& base_dir);
//       A reference file: skeleton, bind pose (its first `time` frame) and the
//       skinned triangle mesh. Texture names are resolved relative to the
//       file's folder (`base_dir`).
//   SmdSkeletonAnim load_smd_animation(const std::filesystem::path& file,
//                                      const std::vector<Bone>& reference_bones,
//                                      std::span<const BonePose> rest_pose = {});
//   SmdSkeletonAnim load_smd_animation(const std::filesystem::path& file, const SmdModel& reference);
//   SmdSkeletonAnim parse_smd_animation(std::string_view text, const std::string& name_for_errors,
//                                       const std::vector<Bone>& reference_bones,
//                                       std::span<const BonePose> rest_pose = {});
//       An animation file, retargeted to the reference skeleton by bone NAME:
//       frames[f][i] is the local pose of reference bone i at frame f. A
//       reference bone the file does not animate keeps rest_pose[i] (the bind
//       pose for the SmdModel overload; the zero pose when rest_pose is empty).
//       rest_pose must be empty or as long as reference_bones
//       (std::invalid_argument otherwise).
//
// Every function throws raykit::ParseError ("FILE:LINE: message") on malformed
// or unreadable input; LINE is 1-based, 0 when the file cannot be read.
//
// File format accepted
// --------------------
// * Lines end in LF or CRLF; a UTF-8 byte-order mark is skipped; blank lines
//   and lines starting with `//`, `#` or `;` are ignored everywhere; tokens are
//   separated by spaces/tabs.
// * Top level: `version 1` (optional; another version is an error), then the
//   blocks `nodes`, `skeleton`, `triangles`, `vertexanimation`, each ended by a
//   line `end`. `nodes` must come before `skeleton` and `triangles`; each block
//   may appear once; `vertexanimation` (flex data) is skipped. Other statements
//   are errors. A reference file needs `nodes` and `skeleton` (`triangles` is
//   optional: no triangles, empty mesh); an animation file needs `nodes` and
//   `skeleton` and its `triangles` block, if any, is skipped.
// * nodes: `ID "NAME" PARENT` — ID 0..65534, NAME in double quotes (may hold
//   spaces; an unquoted single word is accepted too), PARENT -1 for a root.
//   Lines may come in any order (a child may precede its parent, several
//   roots are fine), but the ids of a block must be exactly 0..N-1. Errors:
//   a duplicate id or name (at its line), a missing id (at the `end` line), a
//   parent that is not a bone or a parent cycle (at the line of the bone).
// * skeleton: `time T` (integer T >= 0, strictly increasing) opens a frame;
//   then lines `BONE px py pz rx ry rz`. A bone absent from a frame keeps its
//   value from the frame before; absent from the first frame it takes its
//   rest value (zero pose and a warning in a reference file; see
//   reference_bones above for an animation file). Frames are numbered from
//   the first `time`; a gap (time 3 then time 6) repeats the last frame for
//   the missing numbers (at most 65536 at a time). A bone listed twice in one
//   frame, a bone index out of range, a pose line before the first `time`,
//   a block without any `time` are errors. In a reference file the first
//   frame is the bind pose; later frames are checked and ignored.
// * triangles: groups of 4 lines — a material line (the whole trimmed line,
//   a texture file name) and 3 vertex lines
//       PARENT px py pz nx ny nz u v [LINKS (BONE WEIGHT) x LINKS]
//   Half-Life 1 lines have no links (or LINKS = 0): the vertex belongs wholly
//   to PARENT. Otherwise (Half-Life 2) the links are used as given; a
//   duplicate bone's weights are added, zero weights dropped; when the sum of
//   weights is below 1 the remainder goes to PARENT (Valve's rule); a sum
//   within 1e-5 of 1, or above 1, is renormalized to 1. PARENT and every link
//   bone must be a bone of the file; weights must be >= 0; a line must have
//   exactly 2 x LINKS fields after the count. A triangle cut short by `end`
//   is an error at the `end` line; by a line that is not a vertex line (its
//   first field is not an integer, e.g. the next material), at that line; by
//   the end of the file, at its material line.
// * Numbers: decimal floats as in OBJ (`1`, `-.5`, `1e-05`); `nan`, `inf`,
//   values overflowing a float and non-numeric fields are errors; integers
//   (ids, bones, link counts, time) must be plain decimal integers.
// * A block left open at the end of the file is an error at the line of its
//   keyword; a missing required block is an error at the last line.
//
// Result (reference)
// ------------------
// * bones[i] is the node with id i; bind_pose[i] its pose in the first frame.
// * mesh.triangles are in file order. Vertices are de-duplicated: one vertex
//   per distinct (position, normal, uv, weights) tuple (bit-exact floats), in
//   order of first use. mesh.normals and mesh.texcoords are one per vertex
//   (as in the file, not renormalized). weights[v] is vertex v's links.
// * Positions and normals are in model space, as SMD stores them in the
//   reference: they are the skinned result for the bind pose.
// * Materials: one Material per distinct material line in order of first use
//   (mesh.material_ids per triangle). Material::name is the line, map_kd the
//   texture path: base_dir/NAME when it exists, else a file in base_dir whose
//   name matches case-insensitively, else (NAME without extension) NAME plus
//   .bmp/.jpg/.jpeg/.tga/.png matched case-insensitively; when nothing is
//   found map_kd = base_dir/NAME and mesh.warnings says so.
// * Non-fatal remarks (missing textures, bones absent from the first frame)
//   go to mesh.warnings as "FILE:LINE: message".
//
// Result (animation)
// ------------------
// * frames[f].size() == reference_bones.size(). fps is 30 (SMD does not store
//   a rate; set it yourself for other rates).
// * A bone of the file whose name is not in the reference skeleton is
//   ignored with a warning; one whose parent's name differs from the
//   reference's parent gives a warning (its local pose is used as is).
#pragma once

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <utility>
#include <vector>

#include "raykit/io/obj.hpp"
#include "raykit/io/parse_error.hpp"
#include "raykit/scene/mesh.hpp"

namespace raykit {

/// A node of the skeleton. parent is the index of the parent bone, -1 for a root.
struct Bone {
    std::string name;
    int parent = -1;
};

/// Local pose of a bone relative to its parent, as SMD stores it: translation
/// and Euler angles in radians. The rotation matrix is Rz(z) * Ry(y) * Rx(x)
/// (see anim/skeleton.hpp).
struct BonePose {
    vec3 position{0.0f};
    vec3 rotation{0.0f};
};

/// One bone influence of a vertex.
struct BoneWeight {
    std::uint32_t bone = 0;
    float weight = 0.0f;
};

/// The bone influences of one vertex: distinct bones, weights > 0 summing to 1
/// (up to float rounding), in file order with Valve's parent remainder last.
struct VertexWeights {
    std::vector<BoneWeight> links;
};

/// A reference SMD: skeleton, bind pose and the skinned mesh (see header).
struct SmdModel {
    std::vector<Bone> bones;
    std::vector<BonePose> bind_pose;        ///< one per bone, the reference's first frame
    Mesh mesh;                               ///< warnings in mesh.warnings
    std::vector<VertexWeights> weights;      ///< one per mesh vertex
};

/// An animation SMD retargeted to a reference skeleton: frames[f][bone].
struct SmdSkeletonAnim {
    std::vector<std::vector<BonePose>> frames;
    float fps = 30.0f;
    std::vector<std::string> warnings;

    std::size_t frame_count() const noexcept { return frames.size(); }
};

inline SmdModel load_smd_reference(const std::filesystem::path& file);
inline SmdModel parse_smd_reference(std::string_view text, const std::string& name_for_errors,
                                    const std::filesystem::path& base_dir);
inline SmdSkeletonAnim load_smd_animation(const std::filesystem::path& file, const std::vector<Bone>& reference_bones,
                                          std::span<const BonePose> rest_pose = {});
inline SmdSkeletonAnim load_smd_animation(const std::filesystem::path& file, const SmdModel& reference);
inline SmdSkeletonAnim parse_smd_animation(std::string_view text, const std::string& name_for_errors,
                                           const std::vector<Bone>& reference_bones,
                                           std::span<const BonePose> rest_pose = {});

namespace detail {

inline constexpr int kSmdMaxBones = 65535;           ///< ids 0..65534 (bone indices pack into u16)
inline constexpr std::int64_t kSmdMaxTimeGap = 65536;  ///< most frames one `time` may skip

inline std::string smd_lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

/// Texture path for an SMD material line (rules in the header comment).
/// Returns the path and whether a file was found.
inline std::pair<std::filesystem::path, bool> smd_resolve_texture(const std::filesystem::path& base_dir,
                                                                   std::string_view name) {
    namespace fs = std::filesystem;
    const fs::path direct = base_dir / fs::path(name);
    std::error_code ec;
    if (fs::is_regular_file(direct, ec)) return {direct, true};
    const fs::path rel(name);
    const fs::path dir = (base_dir / rel).parent_path();
    const std::string stem_lower = smd_lower(rel.filename().string());
    const bool has_ext = rel.has_extension();
    static constexpr const char* kExt[] = {".bmp", ".jpg", ".jpeg", ".tga", ".png"};
    fs::directory_iterator it(dir.empty() ? fs::path(".") : dir, ec);
    if (ec) return {direct, false};
    fs::path by_ext;
    for (; it != fs::directory_iterator(); it.increment(ec)) {
        if (ec) break;
        if (!it->is_regular_file(ec)) continue;
        const std::string f = smd_lower(it->path().filename().string());
        if (f == stem_lower) return {dir / it->path().filename(), true};
        if (!has_ext && by_ext.empty()) {
            for (const char* e : kExt) {
                if (f == stem_lower + e) by_ext = dir / it->path().filename();
            }
        }
    }
    if (!by_ext.empty()) return {by_ext, true};
    return {direct, false};
}

/// Splits the text into trimmed lines (LF or CRLF), skipping nothing.
class SmdLineReader {
public:
    explicit SmdLineReader(std::string_view text) : text_(text) {
        if (text_.size() >= 3 && static_cast<unsigned char>(text_[0]) == 0xEF &&
            static_cast<unsigned char>(text_[1]) == 0xBB && static_cast<unsigned char>(text_[2]) == 0xBF) {
            text_.remove_prefix(3);
        }
    }
    /// Next non-blank, non-comment line; false at the end of the text.
    bool next(std::string_view& line, std::size_t& number) {
        while (pos_ < text_.size()) {
            const std::size_t nl = text_.find('\n', pos_);
            const std::size_t end = nl == std::string_view::npos ? text_.size() : nl;
            std::string_view l = obj_trim(text_.substr(pos_, end - pos_));
            pos_ = nl == std::string_view::npos ? text_.size() : nl + 1;
            ++line_;
            if (l.empty() || l[0] == '#' || l[0] == ';' || (l.size() >= 2 && l[0] == '/' && l[1] == '/')) continue;
            line = l;
            number = line_;
            return true;
        }
        number = line_;
        return false;
    }
    std::size_t lines_read() const noexcept { return line_; }

private:
    std::string_view text_;
    std::size_t pos_ = 0;
    std::size_t line_ = 0;
};

class SmdParser {
public:
    enum class Mode { reference, animation };

    SmdParser(std::string name, std::filesystem::path base_dir, Mode mode)
        : name_(std::move(name)), base_(std::move(base_dir)), mode_(mode) {}

    /// For Mode::animation: the skeleton the file is retargeted to.
    void set_reference(const std::vector<Bone>* bones, std::span<const BonePose> rest) {
        ref_bones_ = bones;
        ref_rest_ = rest;
    }

    void parse(std::string_view text) {
        SmdLineReader reader(text);
        std::string_view line;
        while (reader.next(line, line_)) {
            std::string_view rest = line;
            const std::string_view key = obj_next_token(rest);
            if (key == "version") {
                statement_version(rest);
            } else if (key == "nodes") {
                open_block(rest, "nodes", seen_nodes_);
                block_nodes(reader);
            } else if (key == "skeleton") {
                open_block(rest, "skeleton", seen_skeleton_);
                require_nodes("skeleton");
                block_skeleton(reader);
            } else if (key == "triangles") {
                open_block(rest, "triangles", seen_triangles_);
                require_nodes("triangles");
                if (mode_ == Mode::reference) {
                    block_triangles(reader);
                } else {
                    skip_block(reader, "triangles");
                }
            } else if (key == "vertexanimation") {
                open_block(rest, "vertexanimation", seen_vertexanimation_);
                skip_block(reader, "vertexanimation");
            } else {
                fail("unknown statement " + obj_quote(key) +
                     " (expected version, nodes, skeleton, triangles or vertexanimation)");
            }
        }
        last_line_ = reader.lines_read();
        line_ = last_line_;
        if (!seen_nodes_) fail("no 'nodes' block");
        if (!seen_skeleton_) fail("no 'skeleton' block");
    }

    SmdModel take_model() {
        SmdModel m;
        m.bones = std::move(bones_);
        m.bind_pose = std::move(frames_.front());
        const std::size_t nv = positions_.size();
        m.mesh.positions = std::move(positions_);
        m.mesh.normals = std::move(normals_);
        m.mesh.texcoords = std::move(texcoords_);
        m.mesh.triangles = std::move(triangles_);
        m.mesh.material_ids = std::move(material_ids_);
        m.weights.resize(nv);
        for (std::size_t v = 0; v < nv; ++v) {
            m.weights[v].links.assign(links_.begin() + link_offsets_[v], links_.begin() + link_offsets_[v + 1]);
        }
        for (std::size_t i = 0; i < material_names_.size(); ++i) {
            Material mat;
            mat.name = material_names_[i];
            const auto [path, found] = smd_resolve_texture(base_, material_names_[i]);
            mat.map_kd = path.string();
            if (!found) {
                warnings_.push_back(name_ + ":" + std::to_string(material_lines_[i]) + ": texture " +
                                    obj_quote(material_names_[i]) + " not found (" + mat.map_kd + ")");
            }
            m.mesh.materials.push_back(std::move(mat));
        }
        m.mesh.warnings = std::move(warnings_);
        return m;
    }

    SmdSkeletonAnim take_animation() {
        SmdSkeletonAnim a;
        const std::size_t nref = ref_bones_->size();
        a.frames.resize(frames_.size());
        for (std::size_t f = 0; f < frames_.size(); ++f) {
            std::vector<BonePose>& out = a.frames[f];
            if (ref_rest_.empty()) {
                out.assign(nref, BonePose{});
            } else {
                out.assign(ref_rest_.begin(), ref_rest_.end());
            }
            for (std::size_t b = 0; b < frames_[f].size(); ++b) {
                if (to_ref_[b] >= 0) out[static_cast<std::size_t>(to_ref_[b])] = frames_[f][b];
            }
        }
        a.warnings = std::move(warnings_);
        return a;
    }

private:
    [[noreturn]] void fail(const std::string& msg) const { throw ParseError(name_, line_, msg); }
    [[noreturn]] void fail_at(std::size_t line, const std::string& msg) const { throw ParseError(name_, line, msg); }
    void warn(std::size_t line, const std::string& msg) {
        warnings_.push_back(name_ + ":" + std::to_string(line) + ": " + msg);
    }

    // ------------------------------------------------------------ tokens

    void tokenize(std::string_view s) {
        toks_.clear();
        for (;;) {
            const std::string_view t = obj_next_token(s);
            if (t.empty()) break;
            toks_.push_back(t);
        }
    }

    std::int64_t integer(std::string_view tok, const char* what) const {
        const char* p = tok.data();
        const char* e = p + tok.size();
        std::int64_t v = 0;
        if (!obj_parse_int(p, e, v) || p != e) fail(std::string("malformed ") + what + " " + obj_quote(tok));
        return v;
    }

    float number(std::string_view tok, const char* what) const {
        return obj_number_or_throw(tok, what, name_, line_);
    }

    // ------------------------------------------------------------ top level

    void statement_version(std::string_view rest) {
        tokenize(rest);
        if (seen_nodes_ || seen_skeleton_ || seen_triangles_) fail("'version' after the first block");
        if (toks_.size() != 1) fail("'version' takes one number");
        if (integer(toks_[0], "version") != 1) fail("unsupported SMD version " + obj_quote(toks_[0]) + " (only 1)");
    }

    void open_block(std::string_view rest, const char* what, bool& seen) {
        if (!obj_trim(rest).empty()) fail(std::string("unexpected text after '") + what + "'");
        if (seen) fail(std::string("second '") + what + "' block");
        seen = true;
        block_line_ = line_;
    }

    void require_nodes(const char* what) const {
        if (!seen_nodes_) fail(std::string("'") + what + "' block before the 'nodes' block");
    }

    [[noreturn]] void unterminated(const char* what) const {
        fail_at(block_line_, std::string("'") + what + "' block has no 'end' (end of file)");
    }

    void skip_block(SmdLineReader& reader, const char* what) {
        std::string_view line;
        while (reader.next(line, line_)) {
            if (line == "end") return;
        }
        unterminated(what);
    }

    // ------------------------------------------------------------ nodes

    void block_nodes(SmdLineReader& reader) {
        std::vector<std::size_t> lines;  // per id, 0 = not seen
        std::vector<std::int64_t> parents;
        std::unordered_map<std::string, std::size_t> by_name;
        std::string_view line;
        for (;;) {
            if (!reader.next(line, line_)) unterminated("nodes");
            if (line == "end") break;
            // ID "NAME" PARENT
            std::string_view rest = line;
            const std::int64_t id = integer(obj_next_token(rest), "bone id");
            if (id < 0 || id >= kSmdMaxBones) fail("bone id " + std::to_string(id) + " out of range (0..65534)");
            rest = obj_trim(rest);
            std::string_view bone_name;
            if (!rest.empty() && rest[0] == '"') {
                const std::size_t close = rest.find('"', 1);
                if (close == std::string_view::npos) fail("bone name without a closing quote");
                bone_name = rest.substr(1, close - 1);
                rest.remove_prefix(close + 1);
                if (!rest.empty() && !obj_is_space(rest[0])) fail("expected a space after the bone name");
            } else {
                bone_name = obj_next_token(rest);
                if (bone_name.empty()) fail("bone line needs 'ID \"NAME\" PARENT'");
            }
            tokenize(rest);
            if (toks_.size() != 1) fail("bone line needs 'ID \"NAME\" PARENT'");
            const std::int64_t parent = integer(toks_[0], "parent id");
            const auto uid = static_cast<std::size_t>(id);
            if (uid >= lines.size()) {
                lines.resize(uid + 1, 0);
                parents.resize(uid + 1, -1);
                bones_.resize(uid + 1);
            }
            if (lines[uid] != 0) {
                fail("duplicate bone id " + std::to_string(id) + " (first at line " + std::to_string(lines[uid]) + ")");
            }
            auto [it, inserted] = by_name.try_emplace(std::string(bone_name), uid);
            if (!inserted) {
                fail("duplicate bone name " + obj_quote(bone_name) + " (first at line " +
                     std::to_string(lines[it->second]) + ")");
            }
            lines[uid] = line_;
            parents[uid] = parent;
            bones_[uid].name = std::string(bone_name);
        }
        const std::size_t n = bones_.size();
        for (std::size_t i = 0; i < n; ++i) {
            if (lines[i] == 0) fail("bone ids must be 0..N-1: id " + std::to_string(i) + " is missing");
        }
        for (std::size_t i = 0; i < n; ++i) {
            const std::int64_t p = parents[i];
            if (p < -1 || p >= static_cast<std::int64_t>(n)) {
                fail_at(lines[i], "parent " + std::to_string(p) + " of bone " + std::to_string(i) + " " +
                                      obj_quote(bones_[i].name) + " is not a bone (" + std::to_string(n) +
                                      " bones)");
            }
            bones_[i].parent = static_cast<int>(p);
        }
        // Cycle check: colour 0 = unvisited, 1 = on the current path, 2 = reaches a root.
        std::vector<std::uint8_t> colour(n, 0);
        std::vector<std::size_t> path;
        for (std::size_t i = 0; i < n; ++i) {
            path.clear();
            std::size_t b = i;
            while (colour[b] == 0) {
                colour[b] = 1;
                path.push_back(b);
                if (bones_[b].parent < 0) break;
                b = static_cast<std::size_t>(bones_[b].parent);
            }
            if (colour[b] == 1 && bones_[b].parent >= 0) {
                fail_at(lines[b], "parent cycle through bone " + std::to_string(b) + " " + obj_quote(bones_[b].name));
            }
            for (std::size_t q : path) colour[q] = 2;
        }
        bone_lines_ = std::move(lines);
        nodes_done();
    }

    /// After `nodes`: the defaults of a first frame and, for an animation,
    /// the mapping of the file's bones onto the reference skeleton.
    void nodes_done() {
        const std::size_t n = bones_.size();
        defaults_.assign(n, BonePose{});
        if (mode_ != Mode::animation) return;
        std::unordered_map<std::string_view, std::size_t> ref_by_name;
        for (std::size_t i = 0; i < ref_bones_->size(); ++i) ref_by_name.try_emplace((*ref_bones_)[i].name, i);
        to_ref_.assign(n, -1);
        for (std::size_t b = 0; b < n; ++b) {
            const auto it = ref_by_name.find(bones_[b].name);
            if (it == ref_by_name.end()) {
                warn(bone_lines_[b], "bone " + obj_quote(bones_[b].name) + " is not in the reference skeleton; ignored");
                continue;
            }
            const std::size_t r = it->second;
            to_ref_[b] = static_cast<std::int64_t>(r);
            if (!ref_rest_.empty()) defaults_[b] = ref_rest_[r];
            const int p = bones_[b].parent;
            const int rp = (*ref_bones_)[r].parent;
            const std::string pn = p < 0 ? std::string() : bones_[static_cast<std::size_t>(p)].name;
            const std::string rpn =
                (rp < 0 || static_cast<std::size_t>(rp) >= ref_bones_->size()) ? std::string()
                                                                               : (*ref_bones_)[static_cast<std::size_t>(rp)].name;
            if (pn != rpn) {
                warn(bone_lines_[b], "bone " + obj_quote(bones_[b].name) + " has parent " +
                                         (p < 0 ? std::string("(none)") : obj_quote(pn)) + " here but " +
                                         (rp < 0 ? std::string("(none)") : obj_quote(rpn)) + " in the reference");
            }
        }
    }

    // ------------------------------------------------------------ skeleton

    void block_skeleton(SmdLineReader& reader) {
        const std::size_t n = bones_.size();
        std::vector<std::uint8_t> in_frame(n, 0);
        std::vector<std::uint8_t> in_first(n, 0);
        std::int64_t last_time = -1;
        std::size_t first_line = 0;
        std::string_view line;
        for (;;) {
            if (!reader.next(line, line_)) unterminated("skeleton");
            if (line == "end") break;
            tokenize(line);
            if (toks_[0] == "time") {
                if (toks_.size() != 2) fail("'time' takes one integer");
                const std::int64_t t = integer(toks_[1], "time");
                if (t < 0) fail("negative time " + std::to_string(t));
                if (frames_.empty()) {
                    frames_.push_back(defaults_);
                    first_line = line_;
                } else {
                    if (t <= last_time) {
                        fail("time " + std::to_string(t) + " does not follow time " + std::to_string(last_time));
                    }
                    if (t - last_time > kSmdMaxTimeGap) {
                        fail("time jumps from " + std::to_string(last_time) + " to " + std::to_string(t));
                    }
                    if (frames_.size() == 1) in_first = in_frame;
                    for (std::int64_t k = last_time; k < t; ++k) frames_.push_back(frames_.back());
                }
                last_time = t;
                std::fill(in_frame.begin(), in_frame.end(), std::uint8_t{0});
                continue;
            }
            if (frames_.empty()) fail("bone pose before the first 'time' line");
            if (toks_.size() != 7) {
                fail("pose line needs 7 fields (bone px py pz rx ry rz), got " + std::to_string(toks_.size()));
            }
            const std::int64_t b = integer(toks_[0], "bone index");
            if (b < 0 || b >= static_cast<std::int64_t>(n)) {
                fail("bone index " + std::to_string(b) + " out of range (" + std::to_string(n) + " bones)");
            }
            const auto ub = static_cast<std::size_t>(b);
            if (in_frame[ub]) fail("bone " + std::to_string(b) + " listed twice in time " + std::to_string(last_time));
            in_frame[ub] = 1;
            BonePose& pose = frames_.back()[ub];
            for (int k = 0; k < 3; ++k) pose.position[k] = number(toks_[1 + k], "skeleton");
            for (int k = 0; k < 3; ++k) pose.rotation[k] = number(toks_[4 + k], "skeleton");
        }
        if (frames_.empty()) fail("'skeleton' block has no 'time' frame");
        if (frames_.size() == 1) in_first = in_frame;
        if (mode_ == Mode::reference) {
            for (std::size_t b = 0; b < n; ++b) {
                if (!in_first[b]) {
                    warn(first_line, "bone " + std::to_string(b) + " " + obj_quote(bones_[b].name) +
                                         " has no pose in the first frame; using the zero pose");
                }
            }
        }
    }

    // ------------------------------------------------------------ triangles

    void block_triangles(SmdLineReader& reader) {
        link_offsets_.assign(1, 0);
        std::string_view line;
        int corner = -1;  // -1: expecting a material line
        std::size_t tri_line = 0;
        std::uint32_t tri[3] = {0, 0, 0};
        std::uint32_t slot = 0;
        for (;;) {
            if (!reader.next(line, line_)) {
                if (corner >= 0) {
                    fail_at(tri_line, "end of file inside the triangle starting here (" + std::to_string(corner) +
                                          " of 3 vertex lines)");
                }
                unterminated("triangles");
            }
            if (line == "end") {
                if (corner >= 0) {
                    fail("triangle starting at line " + std::to_string(tri_line) + " has " + std::to_string(corner) +
                         " of 3 vertex lines before 'end'");
                }
                break;
            }
            if (corner < 0) {
                slot = material_slot(line);
                tri_line = line_;
                corner = 0;
                continue;
            }
            {
                std::string_view probe = line;
                const std::string_view first = obj_next_token(probe);
                const char* p = first.data();
                std::int64_t dummy = 0;
                if (!obj_parse_int(p, first.data() + first.size(), dummy) || p != first.data() + first.size()) {
                    fail("expected a vertex line, got " + obj_quote(line) + " (the triangle starting at line " +
                         std::to_string(tri_line) + " has " + std::to_string(corner) + " of 3 vertex lines)");
                }
            }
            tri[corner++] = vertex_line(line);
            if (corner == 3) {
                if (triangles_.size() >= kInvalidIndex - 1) fail("too many triangles");
                triangles_.push_back(Triangle{{tri[0], tri[1], tri[2]}});
                material_ids_.push_back(slot);
                corner = -1;
            }
        }
    }

    std::uint32_t material_slot(std::string_view name) {
        if (!material_names_.empty() && material_names_[last_slot_] == name) return last_slot_;
        auto [it, inserted] =
            slot_of_name_.try_emplace(std::string(name), static_cast<std::uint32_t>(material_names_.size()));
        if (inserted) {
            material_names_.emplace_back(name);
            material_lines_.push_back(line_);
        }
        last_slot_ = it->second;
        return last_slot_;
    }

    std::uint32_t bone_field(std::string_view tok, const char* what) const {
        const std::int64_t b = integer(tok, what);
        if (b < 0 || b >= static_cast<std::int64_t>(bones_.size())) {
            fail(std::string(what) + " " + std::to_string(b) + " is not a bone (" + std::to_string(bones_.size()) +
                 " bones)");
        }
        return static_cast<std::uint32_t>(b);
    }

    /// Parses a vertex line, applies the weight rules, returns the vertex index.
    std::uint32_t vertex_line(std::string_view line) {
        tokenize(line);
        if (toks_.size() < 9) {
            fail("vertex line needs at least 9 fields (parent x y z nx ny nz u v), got " + std::to_string(toks_.size()));
        }
        const std::uint32_t parent = bone_field(toks_[0], "parent bone");
        float f[8];
        for (int k = 0; k < 8; ++k) f[k] = number(toks_[1 + k], "vertex");
        cur_links_.clear();
        std::int64_t nlinks = 0;
        if (toks_.size() > 9) {
            nlinks = integer(toks_[9], "link count");
            if (nlinks < 0) fail("negative link count " + std::to_string(nlinks));
            const std::size_t have = toks_.size() - 10;
            if (static_cast<std::uint64_t>(nlinks) * 2 != have) {
                fail("vertex line declares " + std::to_string(nlinks) + " links (" + std::to_string(2 * nlinks) +
                     " fields) but has " + std::to_string(have) + " fields after the count");
            }
        }
        double sum = 0.0;
        for (std::int64_t k = 0; k < nlinks; ++k) {
            const std::uint32_t b = bone_field(toks_[10 + 2 * k], "link to bone");
            const float w = number(toks_[11 + 2 * k], "link weight");
            if (w < 0.0f) fail("negative link weight " + obj_quote(toks_[11 + 2 * k]));
            sum += w;
            add_link(b, w);
        }
        if (nlinks == 0) {
            cur_links_.push_back({parent, 1.0f});
        } else {
            drop_zero_links();
            const double remainder = 1.0 - sum;
            if (remainder > 1e-5) {
                add_link(parent, static_cast<float>(remainder));
                sum = 1.0;
            }
            if (sum != 1.0) {
                for (BoneWeight& l : cur_links_) l.weight = static_cast<float>(l.weight / sum);
            }
        }
        return vertex_index(f);
    }

    void add_link(std::uint32_t bone, float w) {
        for (BoneWeight& l : cur_links_) {
            if (l.bone == bone) {
                l.weight += w;
                return;
            }
        }
        cur_links_.push_back({bone, w});
    }

    void drop_zero_links() {
        cur_links_.erase(std::remove_if(cur_links_.begin(), cur_links_.end(),
                                        [](const BoneWeight& l) { return !(l.weight > 0.0f); }),
                         cur_links_.end());
    }

    static std::uint64_t mix(std::uint64_t h, std::uint64_t v) noexcept {
        h ^= v + 0x9E3779B97F4A7C15ull + (h << 6) + (h >> 2);
        return h;
    }

    std::uint32_t vertex_index(const float* f) {
        std::uint64_t h = 0x243F6A8885A308D3ull;
        for (int k = 0; k < 8; ++k) h = mix(h, std::bit_cast<std::uint32_t>(f[k]));
        for (const BoneWeight& l : cur_links_) {
            h = mix(h, l.bone);
            h = mix(h, std::bit_cast<std::uint32_t>(l.weight));
        }
        const auto [it, inserted] = head_of_hash_.try_emplace(h, kInvalidIndex);
        for (std::uint32_t v = it->second; v != kInvalidIndex; v = chain_[v]) {
            if (same_vertex(v, f)) return v;
        }
        if (positions_.size() >= kInvalidIndex - 1) fail("too many vertices");
        const auto id = static_cast<std::uint32_t>(positions_.size());
        positions_.emplace_back(f[0], f[1], f[2]);
        normals_.emplace_back(f[3], f[4], f[5]);
        texcoords_.emplace_back(f[6], f[7]);
        links_.insert(links_.end(), cur_links_.begin(), cur_links_.end());
        link_offsets_.push_back(links_.size());
        chain_.push_back(it->second);
        it->second = id;
        return id;
    }

    bool same_vertex(std::uint32_t v, const float* f) const {
        const float g[8] = {positions_[v].x, positions_[v].y, positions_[v].z, normals_[v].x,
                            normals_[v].y,   normals_[v].z,   texcoords_[v].x, texcoords_[v].y};
        if (std::memcmp(g, f, sizeof g) != 0) return false;
        const std::size_t b = link_offsets_[v], e = link_offsets_[v + 1];
        if (e - b != cur_links_.size()) return false;
        for (std::size_t k = 0; k < cur_links_.size(); ++k) {
            if (links_[b + k].bone != cur_links_[k].bone ||
                std::bit_cast<std::uint32_t>(links_[b + k].weight) != std::bit_cast<std::uint32_t>(cur_links_[k].weight)) {
                return false;
            }
        }
        return true;
    }

    // ------------------------------------------------------------ state

    std::string name_;
    std::filesystem::path base_;
    Mode mode_;
    std::size_t line_ = 0;
    std::size_t last_line_ = 0;
    std::size_t block_line_ = 0;
    bool seen_nodes_ = false, seen_skeleton_ = false, seen_triangles_ = false, seen_vertexanimation_ = false;
    std::vector<std::string_view> toks_;
    std::vector<std::string> warnings_;

    std::vector<Bone> bones_;
    std::vector<std::size_t> bone_lines_;
    std::vector<BonePose> defaults_;
    std::vector<std::vector<BonePose>> frames_;

    // animation retargeting
    const std::vector<Bone>* ref_bones_ = nullptr;
    std::span<const BonePose> ref_rest_;
    std::vector<std::int64_t> to_ref_;

    // mesh
    std::vector<vec3> positions_;
    std::vector<vec3> normals_;
    std::vector<vec2> texcoords_;
    std::vector<BoneWeight> links_;
    std::vector<std::size_t> link_offsets_;
    std::vector<BoneWeight> cur_links_;
    std::unordered_map<std::uint64_t, std::uint32_t> head_of_hash_;
    std::vector<std::uint32_t> chain_;
    std::vector<Triangle> triangles_;
    std::vector<std::uint32_t> material_ids_;
    std::vector<std::string> material_names_;
    std::vector<std::size_t> material_lines_;
    std::unordered_map<std::string, std::uint32_t> slot_of_name_;
    std::uint32_t last_slot_ = 0;
};

}  // namespace detail

inline SmdModel parse_smd_reference(std::string_view text, const std::string& name_for_errors,
                                    const std::filesystem::path& base_dir) {
    detail::SmdParser p(name_for_errors, base_dir, detail::SmdParser::Mode::reference);
    p.parse(text);
    return p.take_model();
}

inline SmdModel load_smd_reference(const std::filesystem::path& file) {
    const std::string text = detail::read_text_file(file);
    return parse_smd_reference(text, file.string(), file.parent_path());
}

inline SmdSkeletonAnim parse_smd_animation(std::string_view text, const std::string& name_for_errors,
                                           const std::vector<Bone>& reference_bones,
                                           std::span<const BonePose> rest_pose) {
    if (!rest_pose.empty() && rest_pose.size() != reference_bones.size()) {
        throw std::invalid_argument("parse_smd_animation: rest_pose must be empty or one pose per reference bone");
    }
    detail::SmdParser p(name_for_errors, {}, detail::SmdParser::Mode::animation);
    p.set_reference(&reference_bones, rest_pose);
    p.parse(text);
    return p.take_animation();
}

inline SmdSkeletonAnim load_smd_animation(const std::filesystem::path& file, const std::vector<Bone>& reference_bones,
                                          std::span<const BonePose> rest_pose) {
    const std::string text = detail::read_text_file(file);
    return parse_smd_animation(text, file.string(), reference_bones, rest_pose);
}

inline SmdSkeletonAnim load_smd_animation(const std::filesystem::path& file, const SmdModel& reference) {
    return load_smd_animation(file, reference.bones, reference.bind_pose);
}

}  // namespace raykit
