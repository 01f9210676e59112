// What the fuzz targets' oracles need of a text file's encoding, written independently of
// io/lexer.hpp: the readers decode UTF-16 with a byte-order mark (FE FF or FF FE) and refuse
// it with an odd number of bytes as an error at line 0 ("NAME: ..."), so the oracle counts
// lines in the decoded text.
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace raykit_fuzz {

/// True when `text` starts with a UTF-16 byte-order mark.
inline bool utf16(std::string_view text) {
    if (text.size() < 2) return false;
    const auto a = static_cast<unsigned char>(text[0]), b = static_cast<unsigned char>(text[1]);
    return (a == 0xFE && b == 0xFF) || (a == 0xFF && b == 0xFE);
}

/// The text as the readers see its lines: UTF-16 code units become ASCII where they are
/// ASCII and 'x' otherwise (a non-blank character; line structure is all the oracles use);
/// other text is returned as it is. Empty for UTF-16 of an odd length (the readers refuse it).
inline std::string lines_view(std::string_view text) {
    if (!utf16(text)) return std::string(text);
    std::string out;
    if (text.size() % 2 != 0) return out;
    const bool big = static_cast<unsigned char>(text[0]) == 0xFE;
    for (std::size_t i = 2; i + 1 < text.size(); i += 2) {
        const unsigned hi = static_cast<unsigned char>(text[big ? i : i + 1]);
        const unsigned lo = static_cast<unsigned char>(text[big ? i + 1 : i]);
        const unsigned unit = hi << 8 | lo;
        out += unit < 0x80 ? static_cast<char>(unit) : 'x';
    }
    return out;
}

/// True for the one error a reader may report at line 0: odd-length UTF-16.
inline bool line_zero_allowed(std::string_view text) { return utf16(text) && text.size() % 2 != 0; }

}  // namespace raykit_fuzz
