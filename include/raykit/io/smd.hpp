// raykit/io/smd.hpp — Valve StudioMDL Data (SMD) loader: reference meshes and
// skeletal animations (Half-Life 1 and Half-Life 2 / Source flavours).
//
// Interface
// ---------
//   Bone, BonePose, BoneWeight, VertexWeights, SmdSkeletonAnim (key frames
//   and their frame numbers: frames, times, fps = 30, warnings; frame(f)):
//   scene/skeleton_data.hpp (the format-independent skeleton, skin and
//   animation data this parser fills)
//   struct SmdModel      { bones, bind_pose, mesh, weights };
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
//       frame(f)[i] is the local pose of reference bone i at frame f. A
//       reference bone the file does not animate keeps rest_pose[i] (the bind
//       pose for the SmdModel overload; the zero pose when rest_pose is empty).
//       rest_pose must be empty or as long as reference_bones
//       (std::invalid_argument otherwise).
//   class SmdTextureFinder
//       SmdTextureFinder(base_dir); find(name) -> {path, found}: the texture
//       rule below. Lists each folder once (cached for the finder's life);
//       listings() counts the folders listed. One finder per reference load.
//   std::pair<path, bool> smd_resolve_texture(base_dir, name)   // one-shot finder
//
// Every function throws raykit::ParseError ("FILE:LINE: message") on malformed
// or unreadable input; LINE is 1-based (an empty file's errors are at line 1),
// 0 only when the file cannot be opened or read or is UTF-16 of an odd byte
// count (then what() is "FILE: message").
//
// Bounds: memory and time grow linearly with the input, except an animation's
// key frames, which hold one pose per reference bone each: at most
// kSmdMaxAnimPoses = 2^24 poses (key frames x reference bones, ~400 MB) per
// animation, an error at the `time` line that would pass it.
//
// File format accepted
// --------------------
// * Byte-order marks as in OBJ (io/lexer.hpp's one rule): a UTF-8 BOM is
//   skipped, UTF-16 text with a BOM is read as its UTF-8 conversion (an odd
//   byte count is an error at line 0).
// * Lines end in LF or CRLF; blank lines and lines starting with `//`, `#`
//   or `;` are ignored everywhere; tokens are separated by spaces/tabs.
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
// * skeleton: `time T` (integer 0 <= T <= 2147483647, strictly increasing)
//   opens a key frame; then lines `BONE px py pz rx ry rz`. A bone absent
//   from a key keeps its value from the key before; absent from the first
//   key it takes its rest value (zero pose and a warning in a reference file;
//   see reference_bones above for an animation file). Frames are numbered
//   from the first `time` (frame T - T0); a gap (time 3 then time 6) holds
//   the last key over the missing numbers (frames 4 and 5 show time 3's
//   pose, exactly as if the file repeated it), stored once: a gap costs
//   nothing. A bone listed twice in one key, a bone index out of range, a
//   pose line before the first `time`, a block without any `time` are
//   errors. In a reference file the first key is the bind pose; later keys
//   are checked and ignored (not stored).
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
//   .bmp/.jpg/.jpeg/.tga/.png matched case-insensitively (the first such
//   file in directory order); when nothing is found map_kd = base_dir/NAME
//   and mesh.warnings says so. NAME may name a subfolder. Each folder is
//   listed once per load, however many materials it serves.
// * Non-fatal remarks (missing textures, bones absent from the first frame)
//   go to mesh.warnings as "FILE:LINE: message".
//
// Result (animation)
// ------------------
// * One key frame per `time` line: frames[k] (one pose per reference bone,
//   frames[k].size() == reference_bones.size()) is the pose at frame number
//   times[k]; times[0] == 0, strictly increasing. frame_count() ==
//   times.back() + 1, the frame numbers the file spans; frame(f) ==
//   frames[key_of_frame(f)], the last key at or before f. For a file without
//   gaps times[k] == k and frame(f) is frames[f]. (A hand-made
//   SmdSkeletonAnim may leave times empty: then key k is frame k.)
//   fps is 30 (SMD does not store a rate; set it yourself for other rates).
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

#include "raykit/io/lexer.hpp"
#include "raykit/io/parse_error.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/scene/skeleton_data.hpp"

namespace raykit {

/// A reference SMD: skeleton, bind pose and the skinned mesh (see header).
struct SmdModel {
    std::vector<Bone> bones;
    std::vector<BonePose> bind_pose;        ///< one per bone, the reference's first frame
    Mesh mesh;                               ///< warnings in mesh.warnings
    std::vector<VertexWeights> weights;      ///< one per mesh vertex
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

inline constexpr int kSmdMaxBones = 65535;                 ///< ids 0..65534 (bone indices pack into u16)
inline constexpr std::int64_t kSmdMaxTime = 2147483647;    ///< largest `time` value (frame numbers fit u32)

inline std::string smd_lower(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return out;
}

}  // namespace detail

/// Most bone poses one animation stores (key frames x reference bones): 2^24, ~400 MB.
inline constexpr std::size_t kSmdMaxAnimPoses = std::size_t{1} << 24;

/// Texture paths for SMD material lines (rules in the header comment), listing
/// each folder at most once: a folder's regular files are read on first use
/// and kept, keyed by the folder's lexically normal path.
class SmdTextureFinder {
public:
    explicit SmdTextureFinder(std::filesystem::path base_dir) : base_(std::move(base_dir)) {}

    /// The texture path for material line `name` and whether a file was found.
    std::pair<std::filesystem::path, bool> find(std::string_view name) {
        namespace fs = std::filesystem;
        const fs::path rel(name);
        const fs::path direct = base_ / rel;
        std::error_code ec;
        if (fs::is_regular_file(direct, ec)) return {direct, true};
        const fs::path dir = direct.parent_path();
        const Folder& f = folder(dir);
        if (!f.listed) return {direct, false};
        const std::string stem_lower = detail::smd_lower(rel.filename().string());
        if (const auto it = f.by_lower.find(stem_lower); it != f.by_lower.end()) {
            return {dir / it->second.second, true};
        }
        if (!rel.has_extension()) {
            static constexpr const char* kExt[] = {".bmp", ".jpg", ".jpeg", ".tga", ".png"};
            const std::pair<std::size_t, std::string>* best = nullptr;
            for (const char* e : kExt) {
                const auto it = f.by_lower.find(stem_lower + e);
                if (it != f.by_lower.end() && (!best || it->second.first < best->first)) best = &it->second;
            }
            if (best) return {dir / best->second, true};
        }
        return {direct, false};
    }

    /// Folders listed so far.
    std::size_t listings() const noexcept { return listings_; }

private:
    struct Folder {
        bool listed = false;
        /// lower-case file name -> (position in directory order, file name), first file of each.
        std::unordered_map<std::string, std::pair<std::size_t, std::string>> by_lower;
    };

    const Folder& folder(const std::filesystem::path& dir) {
        namespace fs = std::filesystem;
        const fs::path where = dir.empty() ? fs::path(".") : dir;
        fs::path key = where.lexically_normal();  // "a/./b/" and "a/b" are one folder
        if (!key.has_filename() && key.has_relative_path()) key = key.parent_path();
        auto [slot, inserted] = folders_.try_emplace(key.string());
        Folder& f = slot->second;
        if (!inserted) return f;
        ++listings_;
        std::error_code ec;
        fs::directory_iterator it(where, ec);
        if (ec) return f;
        f.listed = true;
        std::size_t order = 0;
        for (; it != fs::directory_iterator(); it.increment(ec)) {
            if (ec) break;
            if (!it->is_regular_file(ec)) continue;
            std::string file = it->path().filename().string();
            f.by_lower.try_emplace(detail::smd_lower(file), order++, std::move(file));
        }
        return f;
    }

    std::filesystem::path base_;
    std::unordered_map<std::string, Folder> folders_;
    std::size_t listings_ = 0;
};

/// One-shot texture lookup (lists the folder every call: use an SmdTextureFinder for many names).
inline std::pair<std::filesystem::path, bool> smd_resolve_texture(const std::filesystem::path& base_dir,
                                                                   std::string_view name) {
    return SmdTextureFinder(base_dir).find(name);
}

namespace detail {

/// Splits decoded text (obj_decode_text) into trimmed lines (LF or CRLF), skipping blank and comment lines.
class SmdLineReader {
public:
    explicit SmdLineReader(std::string_view text) : text_(text) {}
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
        std::string decoded;  // UTF-16 text converted; the reader's lines point into it
        SmdLineReader reader(obj_decode_text(text, decoded, name_));
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
        last_line_ = std::max<std::size_t>(reader.lines_read(), 1);  // an empty file's errors are at line 1
        line_ = last_line_;
        if (!seen_nodes_) fail("no 'nodes' block");
        if (!seen_skeleton_) fail("no 'skeleton' block");
    }

    SmdModel take_model() {
        SmdModel m;
        m.bones = std::move(bones_);
        m.bind_pose = std::move(first_);
        const std::size_t nv = positions_.size();
        m.mesh.positions = std::move(positions_);
        m.mesh.normals = std::move(normals_);
        m.mesh.texcoords = std::move(texcoords_);
        m.mesh.triangles = std::move(triangles_);
        m.mesh.material_ids = std::move(material_ids_);
        m.weights.resize(nv);
        for (std::size_t v = 0; v < nv; ++v) {
            m.weights[v].links.assign(links_.begin() + static_cast<std::ptrdiff_t>(link_offsets_[v]),
                                      links_.begin() + static_cast<std::ptrdiff_t>(link_offsets_[v + 1]));
        }
        SmdTextureFinder textures(base_);
        for (std::size_t i = 0; i < material_names_.size(); ++i) {
            Material mat;
            mat.name = material_names_[i];
            const auto [path, found] = textures.find(material_names_[i]);
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
        a.frames = std::move(keys_);
        a.times = std::move(key_times_);
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
        first_.assign(n, BonePose{});
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

    /// Key frames: a reference keeps its first (the bind pose, in first_) and
    /// checks the others; an animation keeps one pose per reference bone per
    /// key (keys_, key_times_). O(1) work per line besides the key copies.
    void block_skeleton(SmdLineReader& reader) {
        const std::size_t n = bones_.size();
        const bool anim = mode_ == Mode::animation;
        const std::size_t per_key = anim ? std::max<std::size_t>(ref_bones_->size(), 1) : 1;
        const std::size_t max_keys = kSmdMaxAnimPoses / per_key;
        // An animation counts its `time` lines first: over the limit it stores
        // nothing and fails at the first `time` line past it (after any earlier error).
        bool store = anim;
        if (anim) {
            SmdLineReader ahead = reader;
            std::string_view l;
            std::size_t number_ignored = 0, total = 0;
            while (ahead.next(l, number_ignored) && l != "end") {
                std::string_view r = l;
                if (obj_next_token(r) == "time") ++total;
            }
            store = total <= max_keys;
            if (store) {
                keys_.reserve(total);
                key_times_.reserve(total);
            }
        }
        std::vector<std::size_t> listed(n, 0);  // key (1-based) in which each bone was last listed
        std::vector<std::uint8_t> in_first(n, 0);
        std::size_t key = 0;  // keys so far; the current key is number `key`
        std::int64_t first_time = -1, last_time = -1;
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
                if (t > kSmdMaxTime) {
                    fail("time " + std::to_string(t) + " out of range (0.." + std::to_string(kSmdMaxTime) + ")");
                }
                if (key == 0) {
                    first_time = t;
                    first_line = line_;
                } else if (t <= last_time) {
                    fail("time " + std::to_string(t) + " does not follow time " + std::to_string(last_time));
                }
                last_time = t;
                ++key;
                if (anim && key > max_keys) {
                    fail("animation too large: more than " + std::to_string(kSmdMaxAnimPoses) + " bone poses (" +
                         std::to_string(key) + " key frames x " + std::to_string(ref_bones_->size()) +
                         " reference bones)");
                }
                if (store) {
                    if (keys_.empty()) {
                        keys_.emplace_back(ref_rest_.begin(), ref_rest_.end());
                        keys_.back().resize(ref_bones_->size());  // zero poses without a rest pose
                    } else {
                        keys_.push_back(keys_.back());
                    }
                    key_times_.push_back(static_cast<std::uint32_t>(t - first_time));
                }
                continue;
            }
            if (key == 0) fail("bone pose before the first 'time' line");
            if (toks_.size() != 7) {
                fail("pose line needs 7 fields (bone px py pz rx ry rz), got " + std::to_string(toks_.size()));
            }
            const std::int64_t b = integer(toks_[0], "bone index");
            if (b < 0 || b >= static_cast<std::int64_t>(n)) {
                fail("bone index " + std::to_string(b) + " out of range (" + std::to_string(n) + " bones)");
            }
            const auto ub = static_cast<std::size_t>(b);
            if (listed[ub] == key) {
                fail("bone " + std::to_string(b) + " listed twice in time " + std::to_string(last_time));
            }
            listed[ub] = key;
            BonePose pose;
            for (int k = 0; k < 3; ++k) pose.position[k] = number(toks_[std::size_t(1 + k)], "skeleton");
            for (int k = 0; k < 3; ++k) pose.rotation[k] = number(toks_[std::size_t(4 + k)], "skeleton");
            if (key == 1) {
                in_first[ub] = 1;
                first_[ub] = pose;
            }
            if (store && to_ref_[ub] >= 0) keys_.back()[static_cast<std::size_t>(to_ref_[ub])] = pose;
        }
        if (key == 0) fail("'skeleton' block has no 'time' frame");
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
        for (std::size_t k = 0; k < 8; ++k) f[k] = number(toks_[1 + k], "vertex");
        cur_links_.clear();
        std::int64_t nlinks = 0;
        if (toks_.size() > 9) {
            nlinks = integer(toks_[9], "link count");
            if (nlinks < 0) fail("negative link count " + std::to_string(nlinks));
            const std::size_t have = toks_.size() - 10;
            if (have % 2 != 0 || static_cast<std::uint64_t>(nlinks) != have / 2) {
                fail("vertex line declares " + std::to_string(nlinks) + " links (" + std::to_string(2 * nlinks) +
                     " fields) but has " + std::to_string(have) + " fields after the count");
            }
        }
        if (nlinks == 0) {
            cur_links_.push_back({parent, 1.0f});
            return vertex_index(f);
        }
        // Weights add up per bone in double (finite however many duplicates;
        // a float sum could overflow), found through slot_of_bone_ in O(1).
        if (slot_of_bone_.size() != bones_.size()) slot_of_bone_.assign(bones_.size(), kInvalidIndex);
        acc_links_.clear();
        double sum = 0.0;
        for (std::int64_t k = 0; k < nlinks; ++k) {
            const std::uint32_t b = bone_field(toks_[static_cast<std::size_t>(10 + 2 * k)], "link to bone");
            const std::string_view wt = toks_[static_cast<std::size_t>(11 + 2 * k)];
            const float w = number(wt, "link weight");
            if (w < 0.0f) fail("negative link weight " + obj_quote(wt));
            sum += w;
            std::uint32_t& slot = slot_of_bone_[b];
            if (slot == kInvalidIndex) {
                slot = static_cast<std::uint32_t>(acc_links_.size());
                acc_links_.push_back({b, static_cast<double>(w)});
            } else {
                acc_links_[slot].weight += w;
            }
        }
        for (const AccLink& l : acc_links_) slot_of_bone_[l.bone] = kInvalidIndex;
        // Zero weights go; Valve's remainder goes to the parent (last when it has no link yet).
        acc_links_.erase(std::remove_if(acc_links_.begin(), acc_links_.end(),
                                        [](const AccLink& l) { return !(l.weight > 0.0); }),
                         acc_links_.end());
        const double remainder = 1.0 - sum;
        if (remainder > 1e-5) {
            auto it = std::find_if(acc_links_.begin(), acc_links_.end(),
                                   [&](const AccLink& l) { return l.bone == parent; });
            if (it == acc_links_.end()) {
                acc_links_.push_back({parent, remainder});
            } else {
                it->weight += remainder;
            }
            sum = 1.0;
        }
        for (const AccLink& l : acc_links_) {
            const float w = static_cast<float>(sum != 1.0 ? l.weight / sum : l.weight);
            if (w > 0.0f) cur_links_.push_back({l.bone, w});  // a weight far below the others may round to 0
        }
        return vertex_index(f);
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
    std::vector<BonePose> first_;  ///< per file bone: its pose in the first key (zero when absent)

    // animation key frames (retargeted: one pose per reference bone)
    std::vector<std::vector<BonePose>> keys_;
    std::vector<std::uint32_t> key_times_;

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
    struct AccLink {
        std::uint32_t bone;
        double weight;
    };
    std::vector<AccLink> acc_links_;
    std::vector<std::uint32_t> slot_of_bone_;  ///< per bone: its index in acc_links_, kInvalidIndex when none
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
