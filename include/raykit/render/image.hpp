// raykit/render/image.hpp — RGBA float image; PNG and PFM output; sRGB transfer functions.
//
// Interface
// ---------
//   Image img(640, 480);                        // all pixels (0, 0, 0, 1)
//   img.at(x, y) = vec4(r, g, b, a);            // linear RGB, alpha = coverage; (0, 0) is top-left
//   write_png(img, "out.png");                  // sRGB-encoded 8-bit RGB (PngOptions: alpha, linear)
//   write_pfm(img, "out.pfm");                  // 32-bit float RGB, linear, little-endian
//   Image back = read_pfm("out.pfm");           // PF (RGB) or Pf (grey), either byte order
//   double e = rmse(a, b);                      // root-mean-square error over R, G, B
//   float l = srgb_to_linear(0.5f);             // IEC 61966-2-1 transfer functions
//   float s = linear_to_srgb(l);
//
// Errors: write_png / write_pfm throw std::runtime_error naming the file when it cannot be
// written; read_pfm throws std::runtime_error for an unreadable or malformed file, or one whose
// header claims more pixels than ImageLimits or than the file holds (checked before allocating); rmse throws
// std::invalid_argument for images of different sizes.
//
// stb (Debian libstb-dev, <stb/stb_image.h> and <stb/stb_image_write.h>)
// ---------------------------------------------------------------------
// raykit is header-only, so it cannot compile stb's implementation into exactly one object
// file. Unless told otherwise it compiles it into every translation unit that includes this
// header with STB_IMAGE_STATIC / STB_IMAGE_WRITE_STATIC, which gives every stb function
// internal linkage: no multiple-definition errors at link time, at the price of one private
// copy of the decoder per translation unit that uses it. These four STB_ macros are the only
// non-RAYKIT_ macros raykit defines (stb requires exactly these names), and raykit #undefs
// them right after the include (stb's own STBI_* / STBIW* macros stay, as with any stb use).
//   * If the translation unit included stb_image.h / stb_image_write.h *before* raykit, raykit
//     uses those declarations and compiles no implementation of that header; the program must
//     then provide it (as it must for its own use anyway).
//   * Define RAYKIT_STB_EXTERNAL before including raykit to never compile stb's implementation:
//     raykit then includes the plain headers, and one translation unit of the program must
//     define STB_IMAGE_IMPLEMENTATION and STB_IMAGE_WRITE_IMPLEMENTATION (non-static).
//   * Do not include stb's implementation *after* raykit in the same translation unit (stb's
//     implementation section has no include guard); include it before, or use the option above.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "raykit/math/types.hpp"

// ---------------------------------------------------------------- stb (see above)
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wdouble-promotion"
#pragma GCC diagnostic ignored "-Wcast-qual"
#pragma GCC diagnostic ignored "-Wshadow"
#endif
#if !defined(STBI_INCLUDE_STB_IMAGE_H)
#if !defined(RAYKIT_STB_EXTERNAL)
#define STB_IMAGE_STATIC
#define STB_IMAGE_IMPLEMENTATION
#include <stb/stb_image.h>
#undef STB_IMAGE_IMPLEMENTATION
#undef STB_IMAGE_STATIC
#else
#include <stb/stb_image.h>
#endif
#endif
#if !defined(INCLUDE_STB_IMAGE_WRITE_H)
#if !defined(RAYKIT_STB_EXTERNAL)
#define STB_IMAGE_WRITE_STATIC
#define STB_IMAGE_WRITE_IMPLEMENTATION
#include <stb/stb_image_write.h>
#undef STB_IMAGE_WRITE_IMPLEMENTATION
#undef STB_IMAGE_WRITE_STATIC
#else
#include <stb/stb_image_write.h>
#endif
#endif
#if defined(__GNUC__) || defined(__clang__)
#pragma GCC diagnostic pop
#endif

namespace raykit {

// ---------------------------------------------------------------- sRGB

/// sRGB-encoded value in [0, 1] to linear (IEC 61966-2-1); values outside [0, 1] are clamped.
inline float srgb_to_linear(float c) noexcept {
    c = std::clamp(c, 0.0f, 1.0f);
    return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

/// Linear value to sRGB-encoded, clamped to [0, 1] (NaN gives 0).
inline float linear_to_srgb(float l) noexcept {
    if (!(l > 0.0f)) return 0.0f;
    if (l >= 1.0f) return 1.0f;
    return l <= 0.0031308f ? 12.92f * l : 1.055f * std::pow(l, 1.0f / 2.4f) - 0.055f;
}

namespace detail {
/// 256-entry table: 8-bit sRGB code -> linear float (computed at compile time, so lookups need
/// no initialisation guard). pow(x, 2.4) = exp(2.4 · ln x) by series, accurate to float rounding.
constexpr double constexpr_ln(double x) {
    // ln x = 2 atanh((x - 1) / (x + 1)), after scaling x into [0.5, 1] by powers of 2
    int k = 0;
    while (x > 1.0) x *= 0.5, ++k;
    while (x < 0.5) x *= 2.0, --k;
    const double y = (x - 1.0) / (x + 1.0), y2 = y * y;
    double term = y, sum = 0.0;
    for (int n = 1; n < 200; n += 2) {
        sum += term / n;
        term *= y2;
    }
    return 2.0 * sum + k * 0.69314718055994530942;
}
constexpr double constexpr_exp(double x) {
    // exp x = (exp(x / 2^8))^(2^8)
    const double r = x / 256.0;
    double term = 1.0, sum = 1.0;
    for (int n = 1; n < 30; ++n) {
        term *= r / n;
        sum += term;
    }
    for (int i = 0; i < 8; ++i) sum *= sum;
    return sum;
}
constexpr float srgb8_decode(int i) {
    const double c = i / 255.0;
    return float(c <= 0.04045 ? c / 12.92 : constexpr_exp(2.4 * constexpr_ln((c + 0.055) / 1.055)));
}
inline constexpr std::array<float, 256> srgb8_lut_array = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[std::size_t(i)] = srgb8_decode(i);
    return t;
}();
inline constexpr const float* srgb8_lut = srgb8_lut_array.data();
inline std::uint8_t to_byte(float v01) noexcept {
    if (!(v01 > 0.0f)) return 0;
    if (v01 >= 1.0f) return 255;
    return static_cast<std::uint8_t>(v01 * 255.0f + 0.5f);
}
}  // namespace detail

/// Linear value to an 8-bit sRGB code (clamped, rounded to nearest).
inline std::uint8_t linear_to_srgb8(float l) noexcept { return detail::to_byte(linear_to_srgb(l)); }

// ---------------------------------------------------------------- Image

/// Row-major RGBA float image; pixel (0, 0) is the top-left one (as in scene/camera.hpp).
/// Colours are linear; alpha is coverage (1 = opaque).
/// Default largest width or height a decoded image may have.
inline constexpr std::uint32_t kMaxImageSide = 32768;
/// Default largest pixel count a decoded image may have (2^26 = 64 Mi pixels, 256 MiB as RGBA8).
inline constexpr std::uint64_t kMaxImagePixels = std::uint64_t(1) << 26;
/// Default largest image file read at all (256 MiB).
inline constexpr std::uint64_t kMaxImageFileBytes = std::uint64_t(1) << 28;

/// What a decoder accepts before it allocates; tighter limits suit a tool that knows its textures.
struct ImageLimits {
    std::uint32_t max_side = kMaxImageSide;          ///< largest width or height
    std::uint64_t max_pixels = kMaxImagePixels;      ///< largest width * height
    std::uint64_t max_file_bytes = kMaxImageFileBytes;  ///< largest file
};

/// Empty when a w x h image is within `lim`, else the reason (naming the size and the limits).
inline std::string image_size_problem(std::uint64_t w, std::uint64_t h, const ImageLimits& lim) {
    if (w == 0 || h == 0) return "image has no pixels (" + std::to_string(w) + " x " + std::to_string(h) + ")";
    if (w <= lim.max_side && h <= lim.max_side && w * h <= lim.max_pixels) return {};
    return std::to_string(w) + " x " + std::to_string(h) + " pixels is over raykit's image limit (" +
           std::to_string(lim.max_side) + " per side, " + std::to_string(lim.max_pixels) + " pixels)";
}

struct Image {
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::vector<vec4> pixels;  ///< width * height, index y * width + x

    Image() = default;
    Image(std::uint32_t w, std::uint32_t h, vec4 fill = vec4(0.0f, 0.0f, 0.0f, 1.0f))
        : width(w), height(h), pixels(std::size_t(w) * h, fill) {}

    bool empty() const noexcept { return pixels.empty(); }
    std::size_t size() const noexcept { return pixels.size(); }
    vec4& at(std::uint32_t x, std::uint32_t y) noexcept { return pixels[std::size_t(y) * width + x]; }
    const vec4& at(std::uint32_t x, std::uint32_t y) const noexcept { return pixels[std::size_t(y) * width + x]; }
};

struct PngOptions {
    bool alpha = false;  ///< write RGBA (coverage as alpha) instead of RGB
    bool srgb = true;    ///< encode with the sRGB curve (false: store linear values * 255)
};

/// 8-bit interleaved RGB or RGBA of `img` (top row first), encoded as `o` says.
inline std::vector<std::uint8_t> to_bytes(const Image& img, const PngOptions& o = {}) {
    const int comp = o.alpha ? 4 : 3;
    const auto stride = static_cast<std::size_t>(comp);
    std::vector<std::uint8_t> out(img.pixels.size() * stride);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) {
        const vec4& p = img.pixels[i];
        for (std::size_t c = 0; c < 3; ++c)
            out[i * stride + c] = o.srgb ? linear_to_srgb8(p[int(c)]) : detail::to_byte(p[int(c)]);
        if (o.alpha) out[i * stride + 3] = detail::to_byte(p.w);
    }
    return out;
}

/// Writes `img` as PNG. Pixels are taken as linear values and, by default, encoded with the
/// sRGB curve, as a display expects rendered radiance; an image whose values are meant as
/// they are (depth, normals as colours, masks, heat maps) is written with PngOptions{.srgb =
/// false}, or it looks washed out. Throws std::runtime_error for an empty image or a write
/// failure.
inline void write_png(const Image& img, const std::filesystem::path& file, const PngOptions& o = {}) {
    if (img.empty() || img.width == 0 || img.height == 0)
        throw std::runtime_error("raykit::write_png: " + file.string() + ": empty image");
    const std::vector<std::uint8_t> bytes = to_bytes(img, o);
    const int comp = o.alpha ? 4 : 3;
    std::vector<char> encoded;
    auto sink = [](void* ctx, void* data, int size) {
        auto* v = static_cast<std::vector<char>*>(ctx);
        const char* d = static_cast<const char*>(data);
        v->insert(v->end(), d, d + size);
    };
    const int ok = stbi_write_png_to_func(sink, &encoded, int(img.width), int(img.height), comp, bytes.data(),
                                          int(img.width) * comp);
    if (!ok) throw std::runtime_error("raykit::write_png: " + file.string() + ": PNG encoding failed");
    std::ofstream out(file, std::ios::binary);
    if (!out) throw std::runtime_error("raykit::write_png: cannot open " + file.string() + " for writing");
    out.write(encoded.data(), std::streamsize(encoded.size()));
    if (!out) throw std::runtime_error("raykit::write_png: error writing " + file.string());
}

namespace detail {
inline bool host_is_little_endian() noexcept {
    const std::uint16_t one = 1;
    unsigned char b;
    std::memcpy(&b, &one, 1);
    return b == 1;
}
}  // namespace detail

/// Writes `img` as a colour PFM ("PF"): linear 32-bit floats, little-endian (scale -1),
/// rows bottom to top as the format requires. Alpha is not stored. Throws std::runtime_error.
inline void write_pfm(const Image& img, const std::filesystem::path& file) {
    if (img.width == 0 || img.height == 0)
        throw std::runtime_error("raykit::write_pfm: " + file.string() + ": empty image");
    std::ofstream out(file, std::ios::binary);
    if (!out) throw std::runtime_error("raykit::write_pfm: cannot open " + file.string() + " for writing");
    const std::string header = "PF\n" + std::to_string(img.width) + " " + std::to_string(img.height) + "\n-1.0\n";
    out.write(header.data(), std::streamsize(header.size()));
    const bool le = detail::host_is_little_endian();
    std::vector<unsigned char> row(std::size_t(img.width) * 12);
    for (std::uint32_t yy = 0; yy < img.height; ++yy) {
        const std::uint32_t y = img.height - 1 - yy;
        for (std::uint32_t x = 0; x < img.width; ++x)
            for (int c = 0; c < 3; ++c) {
                const float v = img.at(x, y)[c];
                unsigned char b[4];
                std::memcpy(b, &v, 4);
                if (!le) std::swap(b[0], b[3]), std::swap(b[1], b[2]);
                std::memcpy(&row[(std::size_t(x) * 3 + std::size_t(c)) * 4], b, 4);
            }
        out.write(reinterpret_cast<const char*>(row.data()), std::streamsize(row.size()));
    }
    if (!out) throw std::runtime_error("raykit::write_pfm: error writing " + file.string());
}

/// Reads a PFM ("PF" colour or "Pf" greyscale, either byte order). Alpha is set to 1.
/// Throws std::runtime_error naming the file when it is unreadable or malformed.
inline Image read_pfm(const std::filesystem::path& file, const ImageLimits& lim = {}) {
    std::ifstream in(file, std::ios::binary);
    auto fail = [&](const std::string& why) {
        return std::runtime_error("raykit::read_pfm: " + file.string() + ": " + why);
    };
    if (!in) throw fail("cannot open");
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) throw fail("not a regular file");
    const std::uintmax_t file_bytes = std::filesystem::file_size(file, ec);
    if (ec) throw fail("cannot read its size");
    std::string magic;
    long long w = 0, h = 0;
    double scale = 0.0;
    if (!(in >> magic >> w >> h >> scale)) throw fail("malformed header");
    if (magic != "PF" && magic != "Pf") throw fail("not a PFM file (magic '" + magic + "')");
    if (w <= 0 || h <= 0 || scale == 0.0 || !std::isfinite(scale)) throw fail("bad size or scale");
    if (std::string why = image_size_problem(std::uint64_t(w), std::uint64_t(h), lim); !why.empty()) throw fail(why);
    const int comp = magic == "PF" ? 3 : 1;
    // the pixels must be in the file before an image is allocated for them
    const std::uint64_t need = std::uint64_t(w) * std::uint64_t(h) * std::uint64_t(comp) * 4;
    const auto at = in.tellg();
    if (at < 0 || std::uint64_t(at) + 1 + need > file_bytes) throw fail("truncated data");
    in.get();  // the single whitespace character after the scale
    const bool file_le = scale < 0.0;
    const bool swap = file_le != detail::host_is_little_endian();
    Image img(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h));
    std::vector<unsigned char> row(std::size_t(w) * std::size_t(comp) * 4);
    for (long long yy = 0; yy < h; ++yy) {
        if (!in.read(reinterpret_cast<char*>(row.data()), std::streamsize(row.size()))) throw fail("truncated data");
        const auto y = std::uint32_t(h - 1 - yy);
        for (long long x = 0; x < w; ++x) {
            vec4 p(0.0f, 0.0f, 0.0f, 1.0f);
            for (int c = 0; c < comp; ++c) {
                unsigned char* b = &row[(std::size_t(x) * std::size_t(comp) + std::size_t(c)) * 4];
                if (swap) std::swap(b[0], b[3]), std::swap(b[1], b[2]);
                float v;
                std::memcpy(&v, b, 4);
                p[c] = v;
            }
            if (comp == 1) p.y = p.z = p.x;
            img.at(std::uint32_t(x), y) = p;
        }
    }
    return img;
}

/// Root-mean-square difference over the R, G, B channels of all pixels (linear values).
/// Throws std::invalid_argument when the sizes differ; 0 for two empty images.
inline double rmse(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height || a.pixels.size() != b.pixels.size())
        throw std::invalid_argument("raykit::rmse: images differ in size");
    if (a.pixels.empty()) return 0.0;
    double sum = 0.0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i)
        for (int c = 0; c < 3; ++c) {
            const double d = double(a.pixels[i][c]) - double(b.pixels[i][c]);
            sum += d * d;
        }
    return std::sqrt(sum / (3.0 * double(a.pixels.size())));
}

}  // namespace raykit
