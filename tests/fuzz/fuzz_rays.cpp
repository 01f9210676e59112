// The RAYS reader `raykit trace` uses (io/rays.hpp: parse_rays). Bad input must be a
// ParseError "fuzz.rays:LINE: ..." with LINE inside the text. Text that parses must
// give one ray per line that is neither blank nor a `#` comment (counted here by an
// independent scan), with finite org, dir and tmin, and tmax finite or +inf.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_text.hpp"
#include "raykit/io/rays.hpp"

namespace {

void check(bool ok) {
    if (!ok) __builtin_trap();
}

bool blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/// Lines that must each give a ray: not blank, first non-blank character not `#`.
std::size_t data_lines(std::string_view text, std::size_t& lines) {
    if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
    std::size_t n = 0;
    lines = 0;
    std::size_t i = 0;
    while (i < text.size()) {
        ++lines;
        std::size_t e = text.find('\n', i);
        if (e == std::string_view::npos) e = text.size();
        std::size_t b = i;
        while (b < e && blank(text[b])) ++b;
        if (b < e && text[b] != '#') ++n;
        i = e + 1;
    }
    return n;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view text(reinterpret_cast<const char*>(data), size);
    std::size_t lines = 0;
    const std::string decoded = raykit_fuzz::lines_view(text);  // UTF-16 is read decoded
    const std::size_t expected = data_lines(decoded, lines);
    std::vector<raykit::Ray> rays;
    try {
        rays = raykit::parse_rays(text, "fuzz.rays");
    } catch (const raykit::ParseError& e) {
        if (e.line() == 0) {  // only odd-length UTF-16 is an error of no line
            check(e.file() == "fuzz.rays" && raykit_fuzz::line_zero_allowed(text));
            check(std::string(e.what()).rfind("fuzz.rays: ", 0) == 0);
            return 0;
        }
        check(e.file() == "fuzz.rays" && e.line() <= lines);
        check(std::string(e.what()).rfind("fuzz.rays:" + std::to_string(e.line()) + ": ", 0) == 0);
        return 0;
    }
    check(rays.size() == expected);
    for (const raykit::Ray& r : rays) {
        for (int k = 0; k < 3; ++k) check(std::isfinite(r.org[k]) && std::isfinite(r.dir[k]));
        check(std::isfinite(r.tmin));
        check(std::isfinite(r.tmax) || r.tmax == INFINITY);
    }
    return 0;
}
