// raykit/io/lexer.hpp — the text helpers shared by the OBJ, MTL, SMD and RAYS readers.
//
// One number rule for every text format raykit reads (obj_parse_float): decimal
// floats with an optional sign; `nan`, `inf` and values that overflow a float are
// errors naming the value; values too small for a float become 0 or a subnormal.
// The RAYS reader had its own rule (std::from_chars alone), so `1e-46` and `1e39`
// were "not a number" there but 0 and an overflow error in an OBJ file.
//
// One byte-order-mark rule for every reader (obj_decode_text): a UTF-8 BOM is
// skipped, UTF-16 with a BOM is converted to UTF-8. SMD and RAYS used to skip a
// UTF-8 BOM by hand, so a UTF-16 file that OBJ reads failed there at line 1.
//
// Bounds: read_text_file refuses what is not a regular file (a directory, a FIFO,
// /dev/zero: reading /dev/zero used to end in std::bad_alloc) and files over
// kMaxTextFileBytes; ObjLineReader refuses a logical line over kMaxLineBytes.
// Both limits are far above real data: the largest OBJ in the shared test data
// is 2.4 MB (stanford-bunny.obj), and a 4 MiB line holds a polygon of ~200,000
// `v/vt/vn` corners.
#pragma once

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>

#include "raykit/io/parse_error.hpp"

namespace raykit {

/// Largest file read_text_file accepts (bytes): 2 GiB.
inline constexpr std::uintmax_t kMaxTextFileBytes = std::uintmax_t{1} << 31;
/// Longest logical line the OBJ, MTL and RAYS readers accept (bytes): 4 MiB.
inline constexpr std::size_t kMaxLineBytes = std::size_t{1} << 22;

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

/// Throws ParseError ("FILE: ...", line 0) unless `file` is an existing regular file within
/// kMaxTextFileBytes: what every reader checks before reading (a folder, /dev/zero or a pipe
/// never ends or ends in bad_alloc otherwise). Returns its size.
inline std::uintmax_t check_text_file(const std::filesystem::path& file) {
    const std::string name = file.string();
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(file, ec);
    if (ec || !std::filesystem::exists(st)) {
        throw ParseError(name, 0, "cannot open file: " + (ec ? ec.message() : std::string("no such file")));
    }
    if (std::filesystem::is_directory(st)) throw ParseError(name, 0, "is a directory, not a file");
    if (!std::filesystem::is_regular_file(st)) {
        throw ParseError(name, 0, "is not a regular file (a device, pipe or socket)");
    }
    const std::uintmax_t size = std::filesystem::file_size(file, ec);
    if (ec) throw ParseError(name, 0, "cannot read its size: " + ec.message());
    if (size > kMaxTextFileBytes) {
        throw ParseError(name, 0, "file is " + std::to_string(size) + " bytes, over the limit of " +
                                      std::to_string(kMaxTextFileBytes) + " bytes");
    }
    return size;
}

/// Reads a whole regular file of at most kMaxTextFileBytes; ParseError(file, 0, ...)
/// naming it when it is missing, not a regular file, too large or unreadable.
inline std::string read_text_file(const std::filesystem::path& file) {
    const std::string name = file.string();
    const std::uintmax_t size = check_text_file(file);
    struct Closer {
        void operator()(std::FILE* f) const noexcept { std::fclose(f); }
    };
    std::unique_ptr<std::FILE, Closer> f(std::fopen(name.c_str(), "rb"));
    if (!f) throw ParseError(name, 0, std::string("cannot open file: ") + std::strerror(errno));
    std::string data;
    data.reserve(static_cast<std::size_t>(size));
    char buf[1 << 16];
    for (;;) {
        const std::size_t got = std::fread(buf, 1, sizeof buf, f.get());
        data.append(buf, got);
        if (data.size() > kMaxTextFileBytes) {  // the file grew while being read
            throw ParseError(name, 0, "file is over the limit of " + std::to_string(kMaxTextFileBytes) + " bytes");
        }
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
/// of a continued logical line). A logical line over kMaxLineBytes is a
/// ParseError naming `name`.
class ObjLineReader {
public:
    ObjLineReader(std::string_view text, const std::string& name) noexcept : text_(text), name_(name) {}

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
            if (len > kMaxLineBytes || joined_.size() + len > kMaxLineBytes) too_long(line_no);
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
    [[noreturn]] void too_long(std::size_t line_no) const {
        throw ParseError(name_, line_no, "line longer than " + std::to_string(kMaxLineBytes) + " bytes");
    }

    std::string_view text_;
    const std::string& name_;
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

}  // namespace detail
}  // namespace raykit
