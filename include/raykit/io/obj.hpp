// raykit/io/obj.hpp — Wavefront OBJ / MTL loader.
//
// Interface
// ---------
//   struct ObjOptions { bool load_materials = true; };
//
//   Mesh load_obj(const std::filesystem::path& file, const ObjOptions& = {});
//       Reads `file` and parses it; `mtllib` paths are relative to its folder.
//   Mesh parse_obj(std::string_view text, const std::string& name_for_errors,
//                  const std::filesystem::path& base_dir, const ObjOptions& = {});
//       Parses OBJ text already in memory; `mtllib` paths are relative to
//       `base_dir`, errors and warnings name `name_for_errors`.
//   std::vector<Material> load_mtl(const std::filesystem::path& file);
//   std::vector<Material> parse_mtl(std::string_view text, const std::string& name_for_errors,
//                                   const std::filesystem::path& base_dir);
//       Material libraries; `map_Kd` paths are resolved relative to the MTL's folder
//       (`base_dir` for parse_mtl).
//
// Every function throws raykit::ParseError ("FILE:LINE: message") on malformed
// or unreadable input; LINE is the physical 1-based line where the offending
// (logical) line starts, 0 when the file itself cannot be read.
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
//   material id is kNoMaterial (no warnings).
// * All other keywords (`s`, `l`, `p`, `vp`, `curv`, `c`, ...) are ignored:
//   lines and points make no triangles.
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
//   errors, values too small for a float become 0 (or a subnormal).
//
// MTL
// ---
// `newmtl NAME` (rest of line, trimmed), `Ka Kd Ks Ke` (r [g b]; one value
// means grey; the `spectral` / `xyz` forms are ignored), `Ns Ni d Tr illum`,
// `map_Kd [options] FILE`. `d` wins over `Tr` whatever their order; `Tr` alone
// gives d = 1 - Tr. map_Kd options (-blendu -blendv -bm -boost -cc -clamp
// -colorspace -imfchan -mm -o -s -t -texres -type) are skipped with their
// arguments and the rest of the line (trimmed, spaces allowed) is the file
// name, stored as base_dir / FILE. Statements before the first `newmtl` and
// other keywords are ignored.
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
#include <initializer_list>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "raykit/io/parse_error.hpp"
#include "raykit/scene/mesh.hpp"

namespace raykit {

/// Options for load_obj / parse_obj.
struct ObjOptions {
    bool load_materials = true;  ///< read `mtllib` files and resolve `usemtl` names
};

inline Mesh load_obj(const std::filesystem::path& file, const ObjOptions& options = {});
inline Mesh parse_obj(std::string_view text, const std::string& name_for_errors,
                      const std::filesystem::path& base_dir, const ObjOptions& options = {});
inline std::vector<Material> load_mtl(const std::filesystem::path& file);
inline std::vector<Material> parse_mtl(std::string_view text, const std::string& name_for_errors,
                                       const std::filesystem::path& base_dir);

namespace detail {

// ---------------------------------------------------------------- text utilities

inline bool obj_is_space(char c) noexcept {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

inline std::string_view obj_trim(std::string_view s) noexcept {
    std::size_t b = 0, e = s.size();
    while (b < e && obj_is_space(s[b])) ++b;
    while (e > b && obj_is_space(s[e - 1])) --e;
    return s.substr(b, e - b);
}

/// Removes and returns the next whitespace-separated token of `s` ("" at end).
inline std::string_view obj_next_token(std::string_view& s) noexcept {
    std::size_t b = 0;
    const std::size_t n = s.size();
    while (b < n && obj_is_space(s[b])) ++b;
    std::size_t e = b;
    while (e < n && !obj_is_space(s[e])) ++e;
    std::string_view tok = s.substr(b, e - b);
    s.remove_prefix(e);
    return tok;
}

/// Short quoted excerpt of user text for error messages.
inline std::string obj_quote(std::string_view s) {
    constexpr std::size_t kMax = 40;
    std::string out = "'";
    out.append(s.substr(0, kMax));
    if (s.size() > kMax) out += "...";
    out += "'";
    return out;
}

/// Reads a whole file; ParseError(file, 0, ...) when it cannot be read.
inline std::string read_text_file(const std::filesystem::path& file) {
    const std::string name = file.string();
    std::error_code ec;
    if (std::filesystem::is_directory(file, ec)) throw ParseError(name, 0, "is a directory");
    struct Closer {
        void operator()(std::FILE* f) const noexcept { std::fclose(f); }
    };
    std::unique_ptr<std::FILE, Closer> f(std::fopen(name.c_str(), "rb"));
    if (!f) throw ParseError(name, 0, std::string("cannot open file: ") + std::strerror(errno));
    std::string data;
    const auto size = std::filesystem::file_size(file, ec);
    if (!ec) data.reserve(static_cast<std::size_t>(size));
    char buf[1 << 16];
    for (;;) {
        const std::size_t got = std::fread(buf, 1, sizeof buf, f.get());
        data.append(buf, got);
        if (got < sizeof buf) break;
    }
    if (std::ferror(f.get())) throw ParseError(name, 0, "read error");
    return data;
}

inline void obj_append_utf8(std::string& out, std::uint32_t cp) {
    if (cp < 0x80) {
        out.push_back(static_cast<char>(cp));
    } else if (cp < 0x800) {
        out.push_back(static_cast<char>(0xC0 | (cp >> 6)));
        out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    } else if (cp < 0x10000) {
        out.push_back(static_cast<char>(0xE0 | (cp >> 12)));
        out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
        out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    } else {
        out.push_back(static_cast<char>(0xF0 | (cp >> 18)));
        out.push_back(static_cast<char>(0x80 | ((cp >> 12) & 0x3F)));
        out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
        out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
    }
}

/// Handles byte-order marks: returns the text to parse, converting UTF-16
/// (BOM FE FF or FF FE) into `storage`. Other text is returned as is, minus a
/// UTF-8 BOM.
inline std::string_view obj_decode_text(std::string_view text, std::string& storage,
                                        const std::string& name) {
    auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
    if (text.size() >= 3 && byte(0) == 0xEF && byte(1) == 0xBB && byte(2) == 0xBF) {
        return text.substr(3);
    }
    if (text.size() >= 2 && ((byte(0) == 0xFE && byte(1) == 0xFF) || (byte(0) == 0xFF && byte(1) == 0xFE))) {
        const bool big_endian = byte(0) == 0xFE;
        if (text.size() % 2 != 0) throw ParseError(name, 0, "UTF-16 text with an odd number of bytes");
        storage.clear();
        storage.reserve(text.size() / 2);
        auto unit = [&](std::size_t i) -> std::uint32_t {
            return big_endian ? (std::uint32_t{byte(i)} << 8) | byte(i + 1)
                              : (std::uint32_t{byte(i + 1)} << 8) | byte(i);
        };
        for (std::size_t i = 2; i < text.size(); i += 2) {
            std::uint32_t cp = unit(i);
            if (cp >= 0xD800 && cp <= 0xDBFF && i + 3 < text.size()) {
                const std::uint32_t lo = unit(i + 2);
                if (lo >= 0xDC00 && lo <= 0xDFFF) {
                    cp = 0x10000 + ((cp - 0xD800) << 10) + (lo - 0xDC00);
                    i += 2;
                }
            }
            obj_append_utf8(storage, cp);
        }
        return storage;
    }
    return text;
}

/// Splits text into logical lines: joins `\` continuations and strips
/// surrounding whitespace (comments are left to the caller, see
/// obj_strip_comment). Line numbers are 1-based physical lines (the first line
/// of a continued logical line).
class ObjLineReader {
public:
    explicit ObjLineReader(std::string_view text) noexcept : text_(text) {}

    bool next(std::string_view& line, std::size_t& line_no) {
        if (pos_ >= text_.size()) return false;
        line_no = physical_ + 1;
        joined_.clear();
        bool joining = false;
        std::string_view result;
        for (;;) {
            if (pos_ >= text_.size()) {  // continuation on the last line
                result = joined_;
                break;
            }
            const char* begin = text_.data() + pos_;
            const std::size_t left = text_.size() - pos_;
            const void* nl = std::memchr(begin, '\n', left);
            const std::size_t len = nl ? static_cast<std::size_t>(static_cast<const char*>(nl) - begin) : left;
            pos_ += nl ? len + 1 : len;
            ++physical_;
            std::string_view phys(begin, len);
            std::size_t end = phys.size();
            while (end > 0 && obj_is_space(phys[end - 1])) --end;
            if (end > 0 && phys[end - 1] == '\\') {
                joined_.append(phys.data(), end - 1);
                joined_.push_back(' ');
                joining = true;
                continue;
            }
            if (!joining) {
                result = phys;
                break;
            }
            if (end == 0) continue;  // blank line inside a continuation: skipped
            joined_.append(phys.data(), end);
            result = joined_;
            break;
        }
        line = obj_trim(result);
        return true;
    }

private:
    std::string_view text_;
    std::size_t pos_ = 0;
    std::size_t physical_ = 0;
    std::string joined_;
};

/// Cuts a data statement (numbers, indices) at its `#` comment. Statements
/// that take a name (usemtl, newmtl, o, g, mtllib, map_Kd) keep the whole rest
/// of the line instead: names such as "Material_#353" are common.
inline std::string_view obj_strip_comment(std::string_view s) noexcept {
    if (const void* hash = std::memchr(s.data(), '#', s.size())) {
        s = s.substr(0, static_cast<std::size_t>(static_cast<const char*>(hash) - s.data()));
    }
    return s;
}

// ---------------------------------------------------------------- numbers

enum class NumStatus { ok, malformed, not_finite, overflow };

/// Parses a whole token as a finite float (see the header comment for forms).
inline NumStatus obj_parse_float(std::string_view tok, float& out) noexcept {
    const char* p = tok.data();
    const char* const e = p + tok.size();
    if (p != e && *p == '+') {
        ++p;
        if (p != e && *p == '-') return NumStatus::malformed;
    }
    const char* q = p;
    if (q != e && *q == '-') ++q;
    if (q == e) return NumStatus::malformed;
    if (!((*q >= '0' && *q <= '9') || *q == '.')) {
        // nan, nan(...), inf, infinity in any case: a number, but not finite.
        std::string_view word(q, static_cast<std::size_t>(e - q));
        auto is = [&](std::string_view w) {
            if (word.size() < w.size()) return false;
            for (std::size_t i = 0; i < w.size(); ++i) {
                if ((word[i] | 0x20) != w[i]) return false;
            }
            return true;
        };
        const bool nonfinite = (is("nan") && (word.size() == 3 || word[3] == '(')) ||
                               (is("inf") && word.size() == 3) || (is("infinity") && word.size() == 8);
        return nonfinite ? NumStatus::not_finite : NumStatus::malformed;
    }
    float value = 0.0f;
    auto [ptr, ec] = std::from_chars(p, e, value, std::chars_format::general);
    if (ec == std::errc::result_out_of_range) {
        // Too large or too small for a float: decide which.
        if (ptr != e) return NumStatus::malformed;
        double d = 0.0;
        auto [dptr, dec] = std::from_chars(p, e, d, std::chars_format::general);
        if (dec == std::errc{} && dptr == e) {
            if (!(std::fabs(d) < 1.0)) return NumStatus::overflow;
            out = static_cast<float>(d);  // 0 or a subnormal, sign kept
            return NumStatus::ok;
        }
        // Out of double range too: the exponent's sign decides; without an
        // exponent the number is tiny iff its integer part is all zeros.
        bool tiny = true;
        const char* x = q;
        while (x != e && *x != 'e' && *x != 'E') ++x;
        if (x != e) {
            tiny = x + 1 != e && x[1] == '-';
        } else {
            for (const char* y = q; y != e && *y != '.'; ++y) tiny = tiny && *y == '0';
        }
        if (!tiny) return NumStatus::overflow;
        out = (*p == '-') ? -0.0f : 0.0f;
        return NumStatus::ok;
    }
    if (ec != std::errc{} || ptr != e) return NumStatus::malformed;
    if (!std::isfinite(value)) return NumStatus::not_finite;
    out = value;
    return NumStatus::ok;
}

/// Parses an optionally signed decimal integer at [p, e); advances p. Returns
/// false when there are no digits. Values saturate at +-2^40 (every index
/// beyond 2^32 is out of range anyway).
inline bool obj_parse_int(const char*& p, const char* e, std::int64_t& out) noexcept {
    bool neg = false;
    if (p != e && (*p == '-' || *p == '+')) {
        neg = *p == '-';
        ++p;
    }
    const char* start = p;
    std::int64_t v = 0;
    constexpr std::int64_t kCap = std::int64_t{1} << 40;
    while (p != e && *p >= '0' && *p <= '9') {
        if (v < kCap) v = v * 10 + (*p - '0');
        ++p;
    }
    if (p == start) return false;
    if (v > kCap) v = kCap;
    out = neg ? -v : v;
    return true;
}

/// Parses `tok` as a finite float or throws ParseError(file, line) naming the
/// statement `key`.
inline float obj_number_or_throw(std::string_view tok, std::string_view key, const std::string& file,
                                 std::size_t line) {
    float v = 0.0f;
    const NumStatus status = obj_parse_float(tok, v);
    if (status == NumStatus::ok) return v;
    const std::string where = " in '" + std::string(key) + "'";
    switch (status) {
        case NumStatus::not_finite: throw ParseError(file, line, "non-finite number " + obj_quote(tok) + where);
        case NumStatus::overflow:
            throw ParseError(file, line, "number " + obj_quote(tok) + " overflows a float" + where);
        default: throw ParseError(file, line, "malformed number " + obj_quote(tok) + where);
    }
}

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
        ObjLineReader reader(text);
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
                m.map_kd = file.empty() ? std::string() : (base_ / std::filesystem::path(file)).string();
            }
        }
        finish();
        return std::move(materials_);
    }

private:
    [[noreturn]] void fail(const std::string& msg) const { throw ParseError(name_, line_, msg); }

    float number(std::string_view tok, std::string_view key) const {
        return obj_number_or_throw(tok, key, name_, line_);
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
        ObjLineReader reader(text);
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

    std::uint32_t vertex_for(std::uint32_t v, std::uint32_t vt, std::uint32_t vn) {
        if (v >= head_.size()) head_.resize(positions_.size(), kInvalidIndex);  // v < positions_.size()
        for (std::uint32_t i = head_[v]; i != kInvalidIndex; i = chain_[i]) {
            if (keys_[i].vt == vt && keys_[i].vn == vn) return i;
        }
        if (keys_.size() >= kInvalidIndex) fail("too many vertices");
        const auto id = static_cast<std::uint32_t>(keys_.size());
        keys_.push_back({v, vt, vn});
        chain_.push_back(head_[v]);
        head_[v] = id;
        return id;
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

    void material_library(std::string_view rest) {
        if (rest.empty()) return;
        std::error_code ec;
        std::vector<std::string> files;
        if (std::filesystem::is_regular_file(base_ / std::filesystem::path(rest), ec)) {
            files.emplace_back(rest);
        } else {
            files = split_escaped(rest);
        }
        for (const std::string& f : files) {
            const std::filesystem::path path = base_ / std::filesystem::path(f);
            const std::string key = path.lexically_normal().string();
            if (!loaded_libraries_.insert(key).second) continue;
            if (!std::filesystem::is_regular_file(path, ec)) {
                warn("material library " + obj_quote(f) + " not found (" + path.string() + ")");
                continue;
            }
            std::string text;
            try {
                text = read_text_file(path);
            } catch (const ParseError& e) {
                warn(std::string("material library not readable: ") + e.what());
                continue;
            }
            std::vector<Material> mats = MtlParser(path.string(), path.parent_path()).parse(text);
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
        for (std::vector<Group>* list : {&mesh_.objects, &mesh_.groups}) {
            if (!list->empty()) list->back().triangle_count = n_tri - list->back().first_triangle;
        }

        // Vertices.
        if (!used_vt_ && !used_vn_) {
            // Position-only: referenced `v` entries in file order.
            std::vector<std::uint32_t> remap(keys_.size());
            std::uint32_t next = 0;
            for (std::size_t v = 0; v < head_.size(); ++v) {
                if (head_[v] != kInvalidIndex) remap[head_[v]] = next++;
            }
            if (next == positions_.size()) {
                mesh_.positions = std::move(positions_);
            } else {
                mesh_.positions.reserve(next);
                for (std::size_t v = 0; v < head_.size(); ++v) {
                    if (head_[v] != kInvalidIndex) mesh_.positions.push_back(positions_[v]);
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

    // Vertex de-duplication: a hash table keyed on the (v, vt, vn) triple whose
    // bucket is the position index v itself (a perfect hash on v); entries that
    // share v are chained through chain_.
    std::vector<VertexKey> keys_;
    std::vector<std::uint32_t> chain_;
    std::vector<std::uint32_t> head_;

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
                                       const std::filesystem::path& base_dir) {
    return detail::MtlParser(name_for_errors, base_dir).parse(text);
}

inline std::vector<Material> load_mtl(const std::filesystem::path& file) {
    const std::string text = detail::read_text_file(file);
    return parse_mtl(text, file.string(), file.parent_path());
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
