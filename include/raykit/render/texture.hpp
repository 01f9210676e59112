// raykit/render/texture.hpp — 8-bit RGBA textures: loading (PNG, JPEG, BMP, TGA through image_decode.hpp),
// sRGB decoding, bilinear or nearest sampling with wrap addressing, alpha.
//
// Interface
// ---------
//   std::vector<std::string> warnings;
//   Texture t = load_texture("bark.png", /*srgb=*/true, &warnings);
//       Never throws for a missing or undecodable file: it returns placeholder_texture()
//       (an 8x8 magenta/black checker, Texture::placeholder = true) and appends one warning
//       ("texture FILE: REASON") to `warnings` (when given). raykit never prints.
//   Texture t = make_texture(w, h, rgba_bytes, srgb);   // from memory (4 bytes per texel, top row first)
//   vec4 c = t.sample(uv);                              // bilinear, linear RGBA
//   vec4 c = t.sample(uv, TextureFilter::nearest);
//   float a = t.sample_alpha(uv, filter);               // alpha only (for alpha testing)
//   vec4 c = t.texel(x, y);                             // one texel, (x, y) wrapped, row 0 = top
//
// Conventions
// -----------
// * Texture coordinates follow OBJ: (0, 0) is the bottom-left corner of the image, v grows
//   upwards. Texel (x, y) (y counted from the top row of the file) covers
//   u in [x/W, (x+1)/W) and v in [(H-1-y)/H, (H-y)/H); its centre is at ((x+0.5)/W, (H-y-0.5)/H).
// * Wrap addressing (repeat) in both directions: uv and uv + (i, j) sample the same value for
//   all integers i, j; bilinear filtering blends across the u = 0/1 and v = 0/1 seams.
// * Colour maps are stored sRGB-encoded (Texture::srgb = true) and decoded to linear per texel
//   before filtering, so filtering happens in linear space. Alpha is always linear (byte/255).
// * Non-finite texture coordinates sample the texel at uv = (0, 0).
#pragma once

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "raykit/math/types.hpp"
#include "raykit/render/image.hpp"
#include "raykit/render/image_decode.hpp"

namespace raykit {

enum class TextureFilter { bilinear, nearest };

inline const char* texture_filter_name(TextureFilter f) noexcept {
    return f == TextureFilter::nearest ? "nearest" : "bilinear";
}
/// "bilinear" or "nearest"; throws std::invalid_argument otherwise.
inline TextureFilter parse_texture_filter(std::string_view s) {
    if (s == "bilinear") return TextureFilter::bilinear;
    if (s == "nearest") return TextureFilter::nearest;
    throw std::invalid_argument("unknown texture filter '" + std::string(s) + "' (known: bilinear, nearest)");
}

struct Texture {
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::vector<std::uint8_t> rgba;  ///< 4 bytes per texel, row-major, row 0 = top row of the file
    bool srgb = true;                ///< colour bytes are sRGB-encoded (decoded to linear when sampled)
    bool has_alpha = false;          ///< some texel has alpha < 255
    bool has_cutout = false;         ///< some texel has alpha < 0.5 (alpha testing can cut something)
    bool placeholder = false;        ///< stands in for a file that could not be loaded
    std::string source;              ///< the file it came from ("" when made in memory)

    bool empty() const noexcept { return width == 0 || height == 0; }

    /// Texel (x, y), both wrapped into range; row 0 is the top row. Linear RGBA.
    vec4 texel(std::int64_t x, std::int64_t y) const noexcept {
        if (empty()) return vec4(0.0f);
        x %= std::int64_t(width);
        y %= std::int64_t(height);
        if (x < 0) x += width;
        if (y < 0) y += height;
        return decode(std::uint32_t(x), std::uint32_t(y));
    }

    /// Filtered value at texture coordinates `uv` (OBJ convention, wrap addressing), linear RGBA.
    vec4 sample(vec2 uv, TextureFilter f = TextureFilter::bilinear) const noexcept {
        if (empty()) return vec4(0.0f);
        if (f == TextureFilter::nearest) {
            std::uint32_t x, y;
            nearest(uv, x, y);
            return decode(x, y);
        }
        std::uint32_t x0, x1, y0, y1;
        float ax, ay;
        bilinear(uv, x0, x1, y0, y1, ax, ay);
        const vec4 a = decode(x0, y0), b = decode(x1, y0), c = decode(x0, y1), d = decode(x1, y1);
        return (a * (1.0f - ax) + b * ax) * (1.0f - ay) + (c * (1.0f - ax) + d * ax) * ay;
    }

    /// Filtered alpha only (what alpha testing needs; cheaper than sample()).
    float sample_alpha(vec2 uv, TextureFilter f = TextureFilter::bilinear) const noexcept {
        if (empty()) return 1.0f;
        constexpr float k = 1.0f / 255.0f;
        if (f == TextureFilter::nearest) {
            std::uint32_t x, y;
            nearest(uv, x, y);
            return float(byte(x, y, 3)) * k;
        }
        std::uint32_t x0, x1, y0, y1;
        float ax, ay;
        bilinear(uv, x0, x1, y0, y1, ax, ay);
        const float a = float(byte(x0, y0, 3)), b = float(byte(x1, y0, 3)), c = float(byte(x0, y1, 3)),
                    d = float(byte(x1, y1, 3));
        return ((a * (1.0f - ax) + b * ax) * (1.0f - ay) + (c * (1.0f - ax) + d * ax) * ay) * k;
    }

    std::size_t memory_bytes() const noexcept { return rgba.size(); }

  private:
    std::uint8_t byte(std::uint32_t x, std::uint32_t y, int c) const noexcept {
        return rgba[(std::size_t(y) * width + x) * 4 + std::size_t(c)];
    }
    RAYKIT_INLINE vec4 decode(std::uint32_t x, std::uint32_t y) const noexcept {
        const std::uint8_t* p = &rgba[(std::size_t(y) * width + x) * 4];
        constexpr float k = 1.0f / 255.0f;
        if (srgb) {
            const float* lut = detail::srgb8_lut;
            return vec4(lut[p[0]], lut[p[1]], lut[p[2]], float(p[3]) * k);
        }
        return vec4(float(p[0]) * k, float(p[1]) * k, float(p[2]) * k, float(p[3]) * k);
    }
    /// Fractional parts of u and v in [0, 1) (0 for non-finite input).
    static RAYKIT_INLINE float frac(float a) noexcept {
        if (!std::isfinite(a)) return 0.0f;
        const float f = a - std::floor(a);
        return f < 1.0f ? f : 0.0f;  // a tiny negative a rounds a - floor(a) up to 1
    }
    void nearest(vec2 uv, std::uint32_t& x, std::uint32_t& y) const noexcept {
        const float u = frac(uv.x), v = frac(uv.y);
        x = std::min(std::uint32_t(u * float(width)), width - 1);
        const std::uint32_t yu = std::min(std::uint32_t(v * float(height)), height - 1);  // from the bottom
        y = height - 1 - yu;
    }
    void bilinear(vec2 uv, std::uint32_t& x0, std::uint32_t& x1, std::uint32_t& y0, std::uint32_t& y1, float& ax,
                  float& ay) const noexcept {
        const float fx = frac(uv.x) * float(width) - 0.5f;   // in [-0.5, W - 0.5)
        const float fy = frac(uv.y) * float(height) - 0.5f;  // rows counted from the bottom
        const float flx = std::floor(fx), fly = std::floor(fy);
        ax = fx - flx;
        ay = fy - fly;
        auto wrap = [](std::int64_t i, std::uint32_t n) {
            return std::uint32_t(i < 0 ? i + n : (i >= std::int64_t(n) ? i - n : i));
        };
        const auto ix = std::int64_t(flx), iy = std::int64_t(fly);
        x0 = wrap(ix, width);
        x1 = wrap(ix + 1, width);
        // bottom-up row j is top-down row H - 1 - j; ay weights the upper (j + 1) row
        y0 = height - 1 - wrap(iy, height);
        y1 = height - 1 - wrap(iy + 1, height);
    }
};

/// A texture from 8-bit RGBA bytes (4 per texel, top row first). Throws std::invalid_argument
/// when `rgba` does not hold w * h texels or a size is 0.
inline Texture make_texture(std::uint32_t w, std::uint32_t h, std::vector<std::uint8_t> rgba, bool srgb = true) {
    if (w == 0 || h == 0) throw std::invalid_argument("raykit::make_texture: size must be positive");
    if (rgba.size() != std::size_t(w) * h * 4)
        throw std::invalid_argument("raykit::make_texture: expected w * h * 4 bytes");
    Texture t;
    t.width = w;
    t.height = h;
    t.rgba = std::move(rgba);
    t.srgb = srgb;
    for (std::size_t i = 3; i < t.rgba.size(); i += 4) {
        t.has_alpha |= t.rgba[i] < 255;
        t.has_cutout |= t.rgba[i] < 128;
    }
    return t;
}

/// The stand-in for a missing texture: an 8x8 checker of magenta (1, 0, 1) and black, opaque.
inline Texture placeholder_texture() {
    std::vector<std::uint8_t> px(8 * 8 * 4);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            std::uint8_t* p = &px[std::size_t(y * 8 + x) * 4];
            const bool on = ((x + y) & 1) == 0;
            p[0] = on ? 255 : 0;
            p[1] = 0;
            p[2] = on ? 255 : 0;
            p[3] = 255;
        }
    Texture t = make_texture(8, 8, std::move(px), false);
    t.placeholder = true;
    return t;
}

/// Loads a PNG, JPEG, BMP or TGA file (render/image_decode.hpp: bounded, fuzzed decoders) as
/// 8-bit RGBA. `srgb` says whether the colour channels are sRGB-encoded (true for colour maps
/// such as map_Kd). A file that is missing, cannot be decoded or is over the image limits gives
/// placeholder_texture() (with `source` set) and one message naming the file appended to
/// `warnings` when it is not null; nothing is thrown for that. A decoder's report of damaged
/// data it could still decode (a truncated JPEG, say) is appended to `warnings` too.
inline Texture load_texture(const std::filesystem::path& file, bool srgb = true,
                            std::vector<std::string>* warnings = nullptr) {
    DecodedImage img;
    try {
        img = read_image(file);
    } catch (const ImageDecodeError& e) {
        if (warnings) warnings->push_back(std::string("texture ") + e.what() + " (using a placeholder)");
        Texture t = placeholder_texture();
        t.source = file.string();
        return t;
    }
    if (warnings)
        for (const std::string& w : img.warnings) warnings->push_back("texture " + w);
    Texture t = make_texture(img.width, img.height, std::move(img.rgba), srgb);
    t.source = file.string();
    return t;
}

}  // namespace raykit
