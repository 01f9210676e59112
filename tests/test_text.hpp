// Text in other encodings for the readers' byte-order-mark tests (OBJ, SMD, RAYS): every
// reader decodes through io/lexer.hpp's one rule, so each is fed the same UTF-16 forms.
// A header of its own, not test_support.hpp, which pulls in the whole library.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace raykit::test {

/// Valid UTF-8 `utf8` as UTF-16 bytes after a byte-order mark (FE FF or FF FE), pairs beyond U+FFFF.
inline std::string utf16_with_bom(std::string_view utf8, bool big_endian) {
    std::string out = big_endian ? "\xFE\xFF" : "\xFF\xFE";
    auto unit = [&](std::uint32_t u) {
        const char hi = static_cast<char>(u >> 8), lo = static_cast<char>(u & 0xFF);
        out += big_endian ? std::string{hi, lo} : std::string{lo, hi};
    };
    for (std::size_t i = 0; i < utf8.size();) {
        const auto lead = static_cast<unsigned char>(utf8[i]);
        const std::size_t len = lead < 0x80 ? 1 : lead < 0xE0 ? 2 : lead < 0xF0 ? 3 : 4;
        std::uint32_t cp = len == 1 ? lead : lead & (0x3Fu >> (len - 1));
        for (std::size_t k = 1; k < len; ++k) cp = (cp << 6) | (static_cast<unsigned char>(utf8[i + k]) & 0x3Fu);
        i += len;
        if (cp >= 0x10000) {
            unit(0xD800 + ((cp - 0x10000) >> 10));
            unit(0xDC00 + ((cp - 0x10000) & 0x3FF));
        } else {
            unit(cp);
        }
    }
    return out;
}

}  // namespace raykit::test
