// raykit/io/obj.hpp — Wavefront OBJ / MTL loader.
//
// Interface
// ---------
//   struct ObjOptions { bool load_materials = true; read_material_library (optional) };
//
//   Mesh load_obj(const std::filesystem::path& file, const ObjOptions& = {});
//       Reads `file` and parses it; `mtllib` paths are relative to its folder.
//   Mesh parse_obj(std::string_view text, const std::string& name_for_errors,
//                  const std::filesystem::path& base_dir, const ObjOptions& = {});
//       Parses OBJ text already in memory; `mtllib` paths are relative to
//       `base_dir`, errors and warnings name `name_for_errors`.
//   std::vector<Material> load_mtl(const std::filesystem::path& file, warnings = nullptr);
//   std::vector<Material> parse_mtl(std::string_view text, const std::string& name_for_errors,
//                                   const std::filesystem::path& base_dir, warnings = nullptr);
//       Material libraries; `map_Kd` paths are resolved relative to the MTL's folder
//       (`base_dir` for parse_mtl); warnings (unsupported statements) are appended
//       to *warnings when given.
//
// Every function throws raykit::ParseError ("FILE:LINE: message") on malformed
// or unreadable input; LINE is the physical 1-based line where the offending
// (logical) line starts, 0 when the file itself cannot be read. Files are read
// only when regular and at most kMaxTextFileBytes; a logical line over
// kMaxLineBytes is an error (lexer.hpp).
//
// OBJ
// ---
// * `v x y z [w | r g b]` (extra components are checked to be numbers, then
//   ignored), `vt u [v [w]]` (v defaults to 0), `vn x y z`.
// * `f c0 c1 ... cn` with corners `v`, `v/vt`, `v//vn` or `v/vt/vn`; indices
//   are 1-based, negative ones count back from the last element defined so far.
//   An index must refer to an element defined above the face: index 0, an index
//   out of range or a face with fewer than 3 corners is an error.
// * Polygons are fan-triangulated in file order: corners c0..cn give the
//   triangles (c0, ci, ci+1) for i = 1..n-1, so triangle k of a face is
//   predictable and the triangles of the file appear in file order.
// * Vertices: one Mesh vertex per distinct (v, vt, vn) index triple, numbered in
//   order of first use. When no face corner of the file uses vt or vn, the
//   vertices are instead the referenced `v` entries in file order (so a file
//   whose faces use all of its `v` lines gives positions == its `v` list).
//   `normals` / `texcoords` are empty when no corner uses vn / vt, else one per
//   vertex, zero where the corner had none.
// * `o NAME` / `g NAME` open a new entry in Mesh::objects / Mesh::groups (NAME
//   is the rest of the line, trimmed, spaces allowed, may be empty); it covers
//   the triangles up to the next `o` / `g` (entries may be empty).
// * `usemtl NAME` (rest of line, trimmed) sets the material of the following
//   triangles. Names are resolved after the whole file is read, against every
//   `mtllib` of the file (the first definition of a name wins); an unknown name
//   gives kNoMaterial and one warning in Mesh::warnings. `usemtl` with no name
//   resets to kNoMaterial.
// * `mtllib` may appear several times and list several files. If the whole
//   rest of the line names an existing file it is taken as one name (spaces
//   allowed); otherwise it is split on whitespace, where "\ " is an escaped
//   space inside a name and a word starting with `#` ends the list. Paths are
//   relative to the OBJ's folder (`base_dir`); each library is read once. A
//   missing or unreadable library is a warning in Mesh::warnings, not an
//   error; a malformed one throws ParseError naming the MTL file. With
//   ObjOptions::load_materials == false, `mtllib` is ignored and every
//   material id is kNoMaterial (no warnings). A NUL byte in an `mtllib` or
//   `map_Kd` name is an error (the OS would open the name cut at the NUL).
// * All other keywords (`s`, `l`, `p`, `vp`, `curv`, `c`, ...) are ignored:
//   lines and points make no triangles.
// * A file that yields no triangle gets one warning ("NAME: no triangles"),
//   which also says when NAME does not end in `.obj`: a binary file or an SMD
//   given as a scene used to render a black image without a word.
// * ObjOptions::read_material_library, when set, supplies the text of every
//   `mtllib` (given base_dir / NAME; nullopt = not found) instead of the file
//   system: for OBJ + MTL held in memory (the fuzz target carries both).
//
// Lexical rules (OBJ and MTL)
// ---------------------------
// * A line whose first non-blank character is `#` is a comment. In statements
//   made of numbers or indices (v, vt, vn, f, Kd, Ns, d, ...) a `#` anywhere
//   ends the data; statements that take a name or a file (o, g, usemtl,
//   newmtl, map_Kd) keep the whole rest of the line, `#` included (exporters
//   write names such as "Material_#25").
// * A line whose last non-blank character is `\` continues on the next line
//   (also inside comments); blank lines inside a continuation are skipped.
// * LF or CRLF line endings (not CR alone); spaces, tabs and runs of them
//   separate tokens; leading and trailing blanks are ignored; the last line
//   needs no newline.
// * A UTF-8 byte-order mark is skipped; UTF-16 text (with a BOM) is converted
//   to UTF-8.
// * Numbers: decimal floats with an optional sign (`+1`, `.5`, `-.5`, `5.`,
//   `1e-05`, `1E+5`); `nan`, `inf` and values that overflow a float are
//   errors, values too small for a float become 0 (or a subnormal). The RAYS
//   reader (rays.hpp) shares this rule (lexer.hpp: obj_parse_float).
//
// MTL
// ---
// `newmtl NAME` (rest of line, trimmed), `Ka Kd Ks Ke` (r [g b]; one value
// means grey; the `spectral` / `xyz` forms are ignored), `Ns Ni d Tr illum`,
// `map_Kd [options] FILE`. `d` wins over `Tr` whatever their order; `Tr` alone
// gives d = 1 - Tr. map_Kd options (-blendu -blendv -bm -boost -cc -clamp
// -colorspace -imfchan -mm -o -s -t -texres -type) are skipped with their
// arguments and the rest of the line (trimmed, spaces allowed) is the file
// name, stored as base_dir / FILE; when that does not exist and FILE has `\`
// separators (`map_Kd .\SpiderTex.jpg`, written on Windows, as in assimp's
// spider.mtl) they are read as `/`. Statements before the first `newmtl` are
// ignored; any other keyword (`map_Ka`, `map_Ks`, `bump`, `Tf`, `Pr`, ...) is
// ignored with one warning per keyword per file, at its first line.
#pragma once

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "raykit/io/lexer.hpp"
#include "raykit/io/parse_error.hpp"
#include "raykit/scene/mesh.hpp"

namespace raykit {

/// Options for load_obj / parse_obj.
struct ObjOptions {
    bool load_materials = true;  ///< read `mtllib` files and resolve `usemtl` names
    /// When set, `mtllib` files are read through it instead of the file system:
    /// it gets base_dir / NAME and returns the MTL text, or nullopt for "no such file".
    std::function<std::optional<std::string>(const std::filesystem::path&)> read_material_library{};
};

inline Mesh load_obj(const std::filesystem::path& file, const ObjOptions& options = {});
inline Mesh parse_obj(std::string_view text, const std::string& name_for_errors,
                      const std::filesystem::path& base_dir, const ObjOptions& options = {});
inline std::vector<Material> load_mtl(const std::filesystem::path& file,
                                      std::vector<std::string>* warnings = nullptr);
inline std::vector<Material> parse_mtl(std::string_view text, const std::string& name_for_errors,
                                       const std::filesystem::path& base_dir,
                                       std::vector<std::string>* warnings = nullptr);

namespace detail {

// ---------------------------------------------------------------- MTL

/// Number of arguments (min, max) of a texture map option; {0, 0} if unknown.
inline std::pair<int, int> mtl_texture_option_args(std::string_view opt) noexcept {
    struct Opt {
        std::string_view name;
        int min, max;
    };
    static constexpr Opt kOptions[] = {
        {"-blendu", 1, 1}, {"-blendv", 1, 1}, {"-bm", 1, 1},     {"-boost", 1, 1},
        {"-cc", 1, 1},     {"-clamp", 1, 1},  {"-colorspace", 1, 1}, {"-imfchan", 1, 1},
        {"-mm", 1, 2},     {"-o", 1, 3},      {"-s", 1, 3},      {"-t", 1, 3},
        {"-texres", 1, 1}, {"-type", 1, 1},
    };
    for (const Opt& o : kOptions) {
        if (o.name == opt) return {o.min, o.max};
    }
    return {0, 0};
}

/// The file name of a `map_*` statement: skips known options and their
/// arguments, returns the trimmed rest (may contain spaces, may be empty).
inline std::string_view mtl_texture_file(std::string_view rest) noexcept {
    for (;;) {
        rest = obj_trim(rest);
        std::string_view probe = rest;
        const std::string_view opt = obj_next_token(probe);
        const auto [min_args, max_args] = mtl_texture_option_args(opt);
        if (max_args == 0) return rest;
        for (int i = 0; i < max_args; ++i) {
            std::string_view after = probe;
            const std::string_view arg = obj_next_token(after);
            if (arg.empty()) return {};  // option without its argument and no file
            float dummy = 0.0f;
            if (i >= min_args && obj_parse_float(arg, dummy) != NumStatus::ok) break;
            probe = after;
        }
        rest = probe;
    }
}

class MtlParser {
public:
    MtlParser(std::string name, std::filesystem::path base_dir)
        : name_(std::move(name)), base_(std::move(base_dir)) {}

    std::vector<Material> parse(std::string_view text) {
        std::string decoded;
        text = obj_decode_text(text, decoded, name_);
        ObjLineReader reader(text, name_);
        std::string_view line;
        while (reader.next(line, line_)) {
            if (line.empty() || line[0] == '#') continue;
            std::string_view rest = line;
            const std::string_view key = obj_next_token(rest);
            if (key == "newmtl") {
                finish();
                materials_.emplace_back();
                materials_.back().name = std::string(obj_trim(rest));
                has_d_ = false;
                has_tr_ = false;
                continue;
            }
            if (materials_.empty()) continue;  // statements before the first newmtl
            Material& m = materials_.back();
            if (key == "Kd") {
                color(rest, key, m.kd);
            } else if (key == "Ka") {
                color(rest, key, m.ka);
            } else if (key == "Ks") {
                color(rest, key, m.ks);
            } else if (key == "Ke") {
                color(rest, key, m.ke);
            } else if (key == "Ns") {
                m.ns = scalar(rest, key);
            } else if (key == "Ni") {
                m.ni = scalar(rest, key);
            } else if (key == "d") {
                rest = obj_strip_comment(rest);
                std::string_view probe = rest;
                if (obj_next_token(probe) == "-halo") rest = probe;
                m.d = scalar(rest, key);
                has_d_ = true;
            } else if (key == "Tr") {
                tr_ = scalar(rest, key);
                has_tr_ = true;
            } else if (key == "illum") {
                rest = obj_strip_comment(rest);
                const std::string_view tok = obj_next_token(rest);
                const char* p = tok.data();
                std::int64_t v = 0;
                if (!obj_parse_int(p, tok.data() + tok.size(), v) || p != tok.data() + tok.size() ||
                    v < 0 || v > 1000) {
                    fail("malformed illum value " + obj_quote(tok));
                }
                m.illum = static_cast<int>(v);
            } else if (key == "map_Kd") {
                const std::string_view file = mtl_texture_file(rest);
                m.map_kd = file.empty() ? std::string() : texture_path(file);
            } else if (warned_keys_.insert(std::string(key)).second) {
                warnings_.push_back(name_ + ":" + std::to_string(line_) + ": MTL statement " + obj_quote(key) +
                                    " is not supported and is ignored (warned once per file)");
            }
        }
        finish();
        return std::move(materials_);
    }

    /// Warnings of the last parse(): one per unsupported keyword, at its first line.
    std::vector<std::string>& warnings() noexcept { return warnings_; }

private:
    [[noreturn]] void fail(const std::string& msg) const { throw ParseError(name_, line_, msg); }

    float number(std::string_view tok, std::string_view key) const {
        return obj_number_or_throw(tok, key, name_, line_);
    }

    /// base_ / file; where that does not exist and `file` has Windows `\`
    /// separators (`.\SpiderTex.jpg`), they become `/`.
    std::string texture_path(std::string_view file) const {
        // The OS would cut the name at the NUL and open another file.
        if (file.find('\0') != std::string_view::npos) fail("NUL byte in file name " + obj_quote(file));
        std::filesystem::path p = base_ / std::filesystem::path(file);
        std::error_code ec;
        if (file.find('\\') != std::string_view::npos && !std::filesystem::exists(p, ec)) {
            std::string fixed(file);
            std::replace(fixed.begin(), fixed.end(), '\\', '/');
            p = base_ / std::filesystem::path(fixed).lexically_normal();
        }
        return p.string();
    }

    float scalar(std::string_view rest, std::string_view key) const {
        rest = obj_strip_comment(rest);
        const std::string_view tok = obj_next_token(rest);
        if (tok.empty()) fail("'" + std::string(key) + "' needs a value");
        return number(tok, key);
    }

    void color(std::string_view rest, std::string_view key, vec3& out) const {
        rest = obj_strip_comment(rest);
        const std::string_view r = obj_next_token(rest);
        if (r == "spectral" || r == "xyz") return;  // not supported: keep the default
        if (r.empty()) fail("'" + std::string(key) + "' needs 1 or 3 values");
        const float x = number(r, key);
        const std::string_view g = obj_next_token(rest);
        if (g.empty()) {
            out = vec3(x);
            return;
        }
        const float y = number(g, key);
        const std::string_view b = obj_next_token(rest);
        if (b.empty()) fail("'" + std::string(key) + "' needs 1 or 3 values, got 2");
        out = vec3(x, y, number(b, key));
    }

    void finish() {
        if (!materials_.empty() && has_tr_ && !has_d_) materials_.back().d = 1.0f - tr_;
        has_d_ = has_tr_ = false;
    }

    std::string name_;
    std::filesystem::path base_;
    std::vector<Material> materials_;
    std::vector<std::string> warnings_;
    std::unordered_set<std::string> warned_keys_;
    std::size_t line_ = 0;
    bool has_d_ = false;
    bool has_tr_ = false;
    float tr_ = 0.0f;
};

// ---------------------------------------------------------------- OBJ

class ObjParser {
public:
    ObjParser(std::string name, std::filesystem::path base_dir, const ObjOptions& options)
        : name_(std::move(name)), base_(std::move(base_dir)), options_(options) {}

    Mesh parse(std::string_view text) {
        std::string decoded;
        text = obj_decode_text(text, decoded, name_);
        // Rough capacity guesses (a face line is ~25-40 bytes) avoid most regrowth.
        triangles_.reserve(text.size() / 40);
        material_slots_.reserve(text.size() / 40);
        ObjLineReader reader(text, name_);
        std::string_view line;
        while (reader.next(line, line_)) {
            if (line.empty() || line[0] == '#') continue;
            std::string_view rest = line;
            const std::string_view key = obj_next_token(rest);
            if (key.size() == 1) {
                switch (key[0]) {
                    case 'v': parse_v(obj_strip_comment(rest)); break;
                    case 'f': parse_f(obj_strip_comment(rest)); break;
                    case 'o': open_group(mesh_.objects, rest); break;
                    case 'g': open_group(mesh_.groups, rest); break;
                    default: break;  // s, l, p, ...
                }
            } else if (key == "vt") {
                parse_vt(obj_strip_comment(rest));
            } else if (key == "vn") {
                parse_vn(obj_strip_comment(rest));
            } else if (key == "usemtl") {
                use_material(obj_trim(rest));
            } else if (key == "mtllib") {
                if (options_.load_materials) material_library(obj_trim(rest));
            }
        }
        return finish();
    }

private:
    struct VertexKey {
        std::uint32_t v, vt, vn;
    };

    [[noreturn]] void fail(const std::string& msg) const { throw ParseError(name_, line_, msg); }

    float number(std::string_view tok, const char* what) const {
        return obj_number_or_throw(tok, what, name_, line_);
    }

    /// Reads between `min` and `max` numbers into out[0..]; checks that any
    /// further tokens are numbers too (ignored). Returns the count read.
    int numbers(std::string_view rest, float* out, int min, int max, const char* what) const {
        int n = 0;
        for (;;) {
            const std::string_view tok = obj_next_token(rest);
            if (tok.empty()) break;
            const float v = number(tok, what);
            if (n < max) out[n] = v;
            ++n;
        }
        if (n < min) {
            fail(std::string("'") + what + "' needs at least " + std::to_string(min) + " numbers, got " +
                 std::to_string(n));
        }
        return n < max ? n : max;
    }

    void parse_v(std::string_view rest) {
        float c[3];
        numbers(rest, c, 3, 3, "v");
        positions_.emplace_back(c[0], c[1], c[2]);
    }
    void parse_vt(std::string_view rest) {
        float c[2] = {0.0f, 0.0f};
        numbers(rest, c, 1, 2, "vt");
        texcoords_.emplace_back(c[0], c[1]);
    }
    void parse_vn(std::string_view rest) {
        float c[3];
        numbers(rest, c, 3, 3, "vn");
        normals_.emplace_back(c[0], c[1], c[2]);
    }

    std::uint32_t resolve(std::int64_t idx, std::size_t count, int kind, std::string_view corner) {
        static constexpr const char* kKind[] = {"vertex", "texture coordinate", "normal"};
        auto in_corner = [&] { return " in face corner " + obj_quote(corner); };  // only built on failure
        if (idx == 0) fail(std::string(kKind[kind]) + " index 0" + in_corner() + " (indices start at 1)");
        if (idx < 0) {
            if (static_cast<std::uint64_t>(-idx) > count) {
                fail(std::string("relative ") + kKind[kind] + " index " + std::to_string(idx) + in_corner() +
                     " is out of range (only " + std::to_string(count) + " defined)");
            }
            const std::int64_t r = static_cast<std::int64_t>(count) + idx;
            if (r >= static_cast<std::int64_t>(kInvalidIndex)) fail("index too large" + in_corner());
            return static_cast<std::uint32_t>(r);
        }
        if (static_cast<std::uint64_t>(idx) > count || idx >= static_cast<std::int64_t>(kInvalidIndex)) {
            fail(std::string(kKind[kind]) + " index " + std::to_string(idx) + in_corner() +
                 " is out of range (only " + std::to_string(count) + " defined so far)");
        }
        return static_cast<std::uint32_t>(idx - 1);
    }

    /// A 64-bit mix of the (v, vt, vn) triple for the hash table.
    static std::size_t key_hash(std::uint32_t v, std::uint32_t vt, std::uint32_t vn) noexcept {
        std::uint64_t h = (std::uint64_t{v} * 0x9E3779B97F4A7C15ull) ^ (std::uint64_t{vt} * 0xC2B2AE3D27D4EB4Full) ^
                          (std::uint64_t{vn} * 0x165667B19E3779F9ull);
        h ^= h >> 29;
        h *= 0xBF58476D1CE4E5B9ull;
        h ^= h >> 32;
        return static_cast<std::size_t>(h);
    }

    /// Doubles the open-addressing table and re-inserts every key it holds.
    void grow_table() {
        const std::size_t size = slots_.empty() ? 1024 : slots_.size() * 2;
        std::vector<std::uint32_t> old(size, kInvalidIndex);
        old.swap(slots_);
        for (const std::uint32_t id : old) {
            if (id == kInvalidIndex) continue;
            const VertexKey& k = keys_[id];
            std::size_t i = key_hash(k.v, k.vt, k.vn) & (size - 1);
            while (slots_[i] != kInvalidIndex) i = (i + 1) & (size - 1);
            slots_[i] = id;
        }
    }

    /// Appends the triple as the next vertex (order of first use); returns its id.
    std::uint32_t new_vertex(std::uint32_t v, std::uint32_t vt, std::uint32_t vn) {
        if (keys_.size() >= kInvalidIndex) fail("too many vertices");
        keys_.push_back({v, vt, vn});
        return static_cast<std::uint32_t>(keys_.size() - 1);
    }

    std::uint32_t vertex_for(std::uint32_t v, std::uint32_t vt, std::uint32_t vn) {
        // Fast path: the first triple used with position v (every triple of a
        // position-only file). With it the bunny parses in as many instructions
        // as before the table (+0.8%, callgrind); without, its parse was ~25% slower.
        if (v >= first_.size()) first_.resize(positions_.size(), kInvalidIndex);  // v < positions_.size()
        const std::uint32_t f = first_[v];
        if (f == kInvalidIndex) return first_[v] = new_vertex(v, vt, vn);
        if (keys_[f].vt == vt && keys_[f].vn == vn) return f;
        return vertex_in_table(v, vt, vn);
    }

    /// Any triple but the first of its position: the hash table.
    std::uint32_t vertex_in_table(std::uint32_t v, std::uint32_t vt, std::uint32_t vn) {
        if (2 * (table_count_ + 1) > slots_.size()) grow_table();  // load factor <= 1/2
        const std::size_t mask = slots_.size() - 1;
        std::size_t i = key_hash(v, vt, vn) & mask;
        for (; slots_[i] != kInvalidIndex; i = (i + 1) & mask) {
            const VertexKey& k = keys_[slots_[i]];
            if (k.v == v && k.vt == vt && k.vn == vn) return slots_[i];
        }
        ++table_count_;
        return slots_[i] = new_vertex(v, vt, vn);
    }

    void parse_f(std::string_view rest) {
        corners_.clear();
        for (;;) {
            const std::string_view tok = obj_next_token(rest);
            if (tok.empty()) break;
            const char* p = tok.data();
            const char* const e = p + tok.size();
            std::int64_t iv = 0, it = 0, in = 0;
            bool has_t = false, has_n = false;
            bool ok = obj_parse_int(p, e, iv);
            if (ok && p != e) {
                ok = *p++ == '/';
                if (ok && p != e && *p == '/') {
                    ++p;
                    ok = has_n = obj_parse_int(p, e, in);
                } else if (ok) {
                    ok = has_t = obj_parse_int(p, e, it);
                    if (ok && p != e) {
                        ok = *p++ == '/';
                        ok = ok && (has_n = obj_parse_int(p, e, in));
                    }
                }
            }
            if (!ok || p != e) fail("malformed face corner " + obj_quote(tok));
            const std::uint32_t v = resolve(iv, positions_.size(), 0, tok);
            const std::uint32_t t = has_t ? resolve(it, texcoords_.size(), 1, tok) : kInvalidIndex;
            const std::uint32_t n = has_n ? resolve(in, normals_.size(), 2, tok) : kInvalidIndex;
            used_vt_ = used_vt_ || has_t;
            used_vn_ = used_vn_ || has_n;
            corners_.push_back(vertex_for(v, t, n));
        }
        if (corners_.size() < 3) {
            fail("face needs at least 3 corners, got " + std::to_string(corners_.size()));
        }
        if (triangles_.size() + corners_.size() - 2 >= kInvalidIndex) fail("too many triangles");
        for (std::size_t i = 1; i + 1 < corners_.size(); ++i) {
            triangles_.push_back(Triangle{{corners_[0], corners_[i], corners_[i + 1]}});
            material_slots_.push_back(current_slot_);
        }
    }

    void open_group(std::vector<Group>& list, std::string_view rest) {
        const auto n = static_cast<std::uint32_t>(triangles_.size());
        if (!list.empty()) list.back().triangle_count = n - list.back().first_triangle;
        list.push_back(Group{std::string(obj_trim(rest)), n, 0});
    }

    void use_material(std::string_view name) {
        if (name.empty()) {
            current_slot_ = kNoMaterial;
            return;
        }
        if (current_slot_ != kNoMaterial && slot_names_[current_slot_] == name) return;
        const auto next_slot = static_cast<std::uint32_t>(slot_names_.size());
        auto [it, inserted] = slot_of_name_.try_emplace(std::string(name), next_slot);
        if (inserted) {
            slot_names_.emplace_back(name);
            slot_lines_.push_back(line_);
        }
        current_slot_ = it->second;
    }

    /// Splits an mtllib argument list on whitespace; "\ " escapes a space and
    /// a word starting with `#` starts a comment.
    static std::vector<std::string> split_escaped(std::string_view s) {
        std::vector<std::string> out;
        std::string cur;
        bool in_token = false;
        for (std::size_t i = 0; i < s.size(); ++i) {
            const char c = s[i];
            if (c == '\\' && i + 1 < s.size() && (s[i + 1] == ' ' || s[i + 1] == '\t')) {
                cur.push_back(s[++i]);
                in_token = true;
            } else if (c == '#' && !in_token) {
                break;  // a trailing comment
            } else if (obj_is_space(c)) {
                if (in_token) out.push_back(std::move(cur));
                cur.clear();
                in_token = false;
            } else {
                cur.push_back(c);
                in_token = true;
            }
        }
        if (in_token) out.push_back(std::move(cur));
        return out;
    }

    /// Whether a material library exists at `path` (the file system, or the
    /// in-memory route of ObjOptions::read_material_library).
    bool library_exists(const std::filesystem::path& path) const {
        if (options_.read_material_library) return options_.read_material_library(path).has_value();
        std::error_code ec;
        return std::filesystem::is_regular_file(path, ec);
    }

    void material_library(std::string_view rest) {
        if (rest.empty()) return;
        if (rest.find('\0') != std::string_view::npos) fail("NUL byte in file name " + obj_quote(rest));
        std::vector<std::string> files;
        if (library_exists(base_ / std::filesystem::path(rest))) {
            files.emplace_back(rest);
        } else {
            files = split_escaped(rest);
        }
        for (const std::string& f : files) {
            const std::filesystem::path path = base_ / std::filesystem::path(f);
            const std::string key = path.lexically_normal().string();
            if (!loaded_libraries_.insert(key).second) continue;
            std::optional<std::string> text;
            if (options_.read_material_library) {
                text = options_.read_material_library(path);
            } else if (library_exists(path)) {
                try {
                    text = read_text_file(path);
                } catch (const ParseError& e) {
                    warn(std::string("material library not readable: ") + e.what());
                    continue;
                }
            }
            if (!text) {
                warn("material library " + obj_quote(f) + " not found (" + path.string() + ")");
                continue;
            }
            MtlParser mtl(path.string(), path.parent_path());
            std::vector<Material> mats = mtl.parse(*text);
            for (std::string& w : mtl.warnings()) mesh_.warnings.push_back(std::move(w));
            for (Material& m : mats) {
                material_of_name_.try_emplace(m.name, static_cast<std::uint32_t>(mesh_.materials.size()));
                mesh_.materials.push_back(std::move(m));
            }
        }
    }

    void warn(const std::string& msg) {
        mesh_.warnings.push_back(name_ + ":" + std::to_string(line_) + ": " + msg);
    }

    Mesh finish() {
        const auto n_tri = static_cast<std::uint32_t>(triangles_.size());
        if (n_tri == 0) {
            // A binary file, an SMD or an empty export parses to nothing: say so
            // rather than let a caller render a black image in silence.
            std::string ext = std::filesystem::path(name_).extension().string();
            for (char& c : ext) c = static_cast<char>(c >= 'A' && c <= 'Z' ? c - 'A' + 'a' : c);
            std::string msg = name_ + ": no triangles (no face statement) in this file";
            if (ext != ".obj") {
                msg += "; its name does not end in .obj (" + (ext.empty() ? std::string("no extension") : "'" + ext + "'") +
                       "): is it an OBJ file?";
            }
            mesh_.warnings.push_back(std::move(msg));
        }
        for (std::vector<Group>* list : {&mesh_.objects, &mesh_.groups}) {
            if (!list->empty()) list->back().triangle_count = n_tri - list->back().first_triangle;
        }

        // Vertices.
        if (!used_vt_ && !used_vn_) {
            // Position-only: referenced `v` entries in file order (one key per v here).
            const std::vector<std::uint32_t>& head = first_;  // v -> key id
            std::vector<std::uint32_t> remap(keys_.size());
            std::uint32_t next = 0;
            for (std::size_t v = 0; v < head.size(); ++v) {
                if (head[v] != kInvalidIndex) remap[head[v]] = next++;
            }
            if (next == positions_.size()) {
                mesh_.positions = std::move(positions_);
            } else {
                mesh_.positions.reserve(next);
                for (std::size_t v = 0; v < head.size(); ++v) {
                    if (head[v] != kInvalidIndex) mesh_.positions.push_back(positions_[v]);
                }
            }
            for (Triangle& t : triangles_) {
                for (std::uint32_t& i : t.v) i = remap[i];
            }
        } else {
            const std::size_t nv = keys_.size();
            mesh_.positions.resize(nv);
            if (used_vn_) mesh_.normals.resize(nv, vec3(0.0f));
            if (used_vt_) mesh_.texcoords.resize(nv, vec2(0.0f));
            for (std::size_t i = 0; i < nv; ++i) {
                const VertexKey& k = keys_[i];
                mesh_.positions[i] = positions_[k.v];
                if (used_vn_ && k.vn != kInvalidIndex) mesh_.normals[i] = normals_[k.vn];
                if (used_vt_ && k.vt != kInvalidIndex) mesh_.texcoords[i] = texcoords_[k.vt];
            }
        }
        mesh_.triangles = std::move(triangles_);

        // Materials: usemtl slots -> indices into mesh_.materials.
        std::vector<std::uint32_t> slot_to_material(slot_names_.size(), kNoMaterial);
        if (options_.load_materials) {
            for (std::size_t s = 0; s < slot_names_.size(); ++s) {
                const auto it = material_of_name_.find(slot_names_[s]);
                if (it != material_of_name_.end()) {
                    slot_to_material[s] = it->second;
                } else {
                    mesh_.warnings.push_back(name_ + ":" + std::to_string(slot_lines_[s]) + ": usemtl " +
                                             obj_quote(slot_names_[s]) + ": no such material");
                }
            }
        }
        for (std::uint32_t& s : material_slots_) s = (s == kNoMaterial) ? kNoMaterial : slot_to_material[s];
        mesh_.material_ids = std::move(material_slots_);
        return std::move(mesh_);
    }

    std::string name_;
    std::filesystem::path base_;
    ObjOptions options_;
    Mesh mesh_;
    std::size_t line_ = 0;

    std::vector<vec3> positions_;
    std::vector<vec2> texcoords_;
    std::vector<vec3> normals_;
    bool used_vt_ = false;
    bool used_vn_ = false;

    // Vertex de-duplication: first_ holds the first triple of each position; every
    // other triple goes into an open-addressing hash table (linear probing, load
    // <= 1/2) over the whole (v, vt, vn) triple; slots_ hold ids into keys_. It
    // replaced per-position chains, which were walked linearly: a file using each
    // position with many texcoords was quadratic. Measured (Release, load_obj):
    // 40k faces on 10 positions, 120k distinct corners: 3.57 s -> 0.02 s;
    // 300k faces on 100 positions, 900k corners (25 MB): 391 s -> 0.19 s.
    std::vector<VertexKey> keys_;
    std::vector<std::uint32_t> first_;  // v -> id of the first triple used with v
    std::vector<std::uint32_t> slots_;  // the table: ids of every other triple
    std::size_t table_count_ = 0;

    std::vector<std::uint32_t> corners_;
    std::vector<Triangle> triangles_;
    std::vector<std::uint32_t> material_slots_;  // usemtl slot per triangle until finish()

    std::uint32_t current_slot_ = kNoMaterial;
    std::unordered_map<std::string, std::uint32_t> slot_of_name_;
    std::vector<std::string> slot_names_;
    std::vector<std::size_t> slot_lines_;
    std::unordered_map<std::string, std::uint32_t> material_of_name_;
    std::unordered_set<std::string> loaded_libraries_;
};

}  // namespace detail

inline std::vector<Material> parse_mtl(std::string_view text, const std::string& name_for_errors,
                                       const std::filesystem::path& base_dir, std::vector<std::string>* warnings) {
    detail::MtlParser parser(name_for_errors, base_dir);
    std::vector<Material> out = parser.parse(text);
    if (warnings) warnings->insert(warnings->end(), parser.warnings().begin(), parser.warnings().end());
    return out;
}

inline std::vector<Material> load_mtl(const std::filesystem::path& file, std::vector<std::string>* warnings) {
    const std::string text = detail::read_text_file(file);
    return parse_mtl(text, file.string(), file.parent_path(), warnings);
}

inline Mesh parse_obj(std::string_view text, const std::string& name_for_errors,
                      const std::filesystem::path& base_dir, const ObjOptions& options) {
    return detail::ObjParser(name_for_errors, base_dir, options).parse(text);
}

inline Mesh load_obj(const std::filesystem::path& file, const ObjOptions& options) {
    const std::string text = detail::read_text_file(file);
    return parse_obj(text, file.string(), file.parent_path(), options);
}

}  // namespace raykit
