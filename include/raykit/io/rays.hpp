// raykit/io/rays.hpp — the RAYS text format `raykit trace` reads.
//
// One ray per line: `ox oy oz dx dy dz tmin tmax`, eight numbers separated by
// spaces or tabs. Blank lines and lines whose first non-blank character is `#`
// are skipped; anything else with other than eight fields is an error. LF or
// CRLF line endings. Byte-order marks as in OBJ (io/lexer.hpp's one rule): a
// UTF-8 BOM is skipped, UTF-16 text with a BOM is read as its UTF-8 conversion
// (an odd byte count is an error at line 0; before, UTF-16 failed at line 1
// with "expected 8 fields").
//
// Numbers follow the one rule of lexer.hpp (the same as OBJ and MTL): `1e-46`
// becomes 0, `1e39` is an error naming the value. Only tmax may be infinite,
// written `inf`, `+inf` or `infinity` (any case); NaN is an error everywhere.
// Each ray must also keep math/limits.hpp's range rule (origin within ±2^32, the
// direction's largest component in [2^-16, 2^16]): a ray outside it is an error
// naming the line, since the triangle tests could answer it wrongly.
//
// It lived in the CLI's main file with its own number rule (std::from_chars),
// where neither the fuzz target nor a test could link it. read_rays refuses what
// is not a regular file: `trace` given a directory used to write an empty HITS
// file and exit 0.
#pragma once

#include <filesystem>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "raykit/io/lexer.hpp"
#include "raykit/io/parse_error.hpp"
#include "raykit/math/limits.hpp"
#include "raykit/math/ray.hpp"

namespace raykit {

namespace detail {

/// One RAYS field: a finite float, or +inf where `allow_inf` (tmax).
inline float ray_number(std::string_view tok, const char* what, bool allow_inf, const std::string& file,
                        std::size_t line) {
    if (allow_inf) {
        std::string_view w = tok;
        if (!w.empty() && w[0] == '+') w.remove_prefix(1);
        auto is = [&](std::string_view word) {
            if (w.size() != word.size()) return false;
            for (std::size_t i = 0; i < w.size(); ++i) {
                if ((w[i] | 0x20) != word[i]) return false;
            }
            return true;
        };
        if (is("inf") || is("infinity")) return std::numeric_limits<float>::infinity();
    }
    return obj_number_or_throw(tok, what, file, line);
}

}  // namespace detail

/// Parses RAYS text (format above); errors are ParseError "NAME:LINE: ...".
inline std::vector<Ray> parse_rays(std::string_view text, const std::string& name_for_errors) {
    static constexpr const char* kField[] = {"ox", "oy", "oz", "dx", "dy", "dz", "tmin", "tmax"};
    std::string decoded;  // UTF-16 text converted; `text` then points into it
    text = detail::obj_decode_text(text, decoded, name_for_errors);
    std::vector<Ray> rays;
    std::size_t line = 0;
    std::size_t pos = 0;
    while (pos < text.size()) {
        ++line;
        std::size_t end = text.find('\n', pos);
        if (end == std::string_view::npos) end = text.size();
        std::string_view rest = text.substr(pos, end - pos);
        pos = end + 1;
        if (rest.size() > kMaxLineBytes) {
            throw ParseError(name_for_errors, line, "line longer than " + std::to_string(kMaxLineBytes) + " bytes");
        }
        rest = detail::obj_trim(rest);
        if (rest.empty() || rest[0] == '#') continue;
        std::string_view tok[8];
        std::size_t n = 0;
        for (std::string_view t = detail::obj_next_token(rest); !t.empty(); t = detail::obj_next_token(rest)) {
            if (n < 8) tok[n] = t;
            ++n;
        }
        if (n != 8) {
            throw ParseError(name_for_errors, line,
                             "expected 8 fields (ox oy oz dx dy dz tmin tmax), got " + std::to_string(n));
        }
        float f[8];
        for (int k = 0; k < 8; ++k) f[k] = detail::ray_number(tok[k], kField[k], k == 7, name_for_errors, line);
        Ray r;
        r.org = vec3(f[0], f[1], f[2]);
        r.dir = vec3(f[3], f[4], f[5]);
        r.tmin = f[6];
        r.tmax = f[7];
        if (!ray_in_range(r)) throw ParseError(name_for_errors, line, ray_range_error(r));
        rays.push_back(r);
    }
    return rays;
}

/// Reads a RAYS file (a regular file, see read_text_file's limits) and parses it.
inline std::vector<Ray> read_rays(const std::filesystem::path& file) {
    return parse_rays(detail::read_text_file(file), file.string());
}

}  // namespace raykit
