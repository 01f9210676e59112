// raykit/render/image_decode.hpp — image files to 8-bit RGBA, bounded before anything is allocated.
//
// Textures come from files a user did not write (an OBJ's map_Kd, an SMD's material), so the
// decoders must be safe on hostile bytes. Measured here (issue 12): a 23-byte JPEG whose DHT
// segment's code counts add up to more than 256 makes Debian's stb_image 2.27 write out of
// bounds, and an 18-byte TGA or a 54-byte BMP header claiming 23000 x 23000 pixels made it
// allocate ~2 GB. So:
//   * PNG goes through libpng's simplified API and JPEG through libjpeg-turbo's TurboJPEG API
//     (both fuzzed upstream; Debian's libpng-dev and libturbojpeg0-dev), with progressive
//     scans limited (TJFLAG_LIMITSCANS) so a crafted JPEG cannot take minutes.
//   * BMP and TGA, which no fuzzed Debian library decodes, still go to stb_image, but only after
//     raykit has read their header itself: a size over the limits below or a file too short
//     for the pixels it claims (uncompressed layouts) is refused before stb sees it.
//   * Every format: the dimensions are read from the header and checked against
//     ImageLimits (by default kMaxImageSide, kMaxImagePixels) before a pixel buffer exists, and
//     the file itself is refused above ImageLimits::max_file_bytes. Anything else (GIF, PSD, HDR, ...) is refused.
// Safety costs no speed: on the 18 textures of the shared data (8.6 M pixels, mostly JPEG)
// bench_texture's BM_DecodeTextures took 124 ms of CPU time against 130 ms for stb_image alone
// (medians of 5, one run).
//
// Errors are ImageDecodeError (a std::runtime_error) whose message names the file.
#pragma once

#include <png.h>
#include <turbojpeg.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "raykit/render/image.hpp"  // stb_image (BMP, TGA), compiled as image.hpp describes

namespace raykit {

/// An image file that cannot be decoded, or is over the limits; the message names the file.
struct ImageDecodeError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

/// File formats raykit decodes.
enum class ImageFormat { png, jpeg, bmp, tga };

/// An image decoded to 8-bit RGBA, 4 bytes per pixel, top row first.
struct DecodedImage {
    std::uint32_t width = 0;
    std::uint32_t height = 0;
    std::vector<std::uint8_t> rgba;
    std::vector<std::string> warnings;  ///< decoded, but the decoder reported damage (e.g. truncated JPEG data)
};

namespace detail {

[[noreturn]] inline void image_fail(const std::string& name, const std::string& why) {
    throw ImageDecodeError(name + ": " + why);
}

inline std::uint32_t image_le16(const std::uint8_t* p) noexcept { return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8; }
inline std::uint32_t image_le32(const std::uint8_t* p) noexcept {
    return image_le16(p) | std::uint32_t(p[2]) << 16 | std::uint32_t(p[3]) << 24;
}
inline std::uint32_t image_be32(const std::uint8_t* p) noexcept {
    return std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 | std::uint32_t(p[2]) << 8 | std::uint32_t(p[3]);
}

/// Throws unless w x h is a non-empty size within the limits.
inline void image_check_size(std::uint64_t w, std::uint64_t h, const std::string& name, const ImageLimits& lim) {
    if (std::string why = image_size_problem(w, h, lim); !why.empty()) image_fail(name, why);
}

inline bool image_ends_with_tga(std::string_view name) noexcept {
    if (name.size() < 4) return false;
    std::string ext(name.substr(name.size() - 4));
    for (char& c : ext) c = char(c >= 'A' && c <= 'Z' ? c + 32 : c);
    return ext == ".tga";
}

inline DecodedImage decode_png(const std::uint8_t* data, std::size_t size, const std::string& name,
                               const ImageLimits& lim) {
    // the size from IHDR (always the first chunk) before libpng reads further
    if (size < 24 || std::string_view(reinterpret_cast<const char*>(data) + 12, 4) != "IHDR")
        image_fail(name, "PNG: no IHDR chunk");
    image_check_size(image_be32(data + 16), image_be32(data + 20), name, lim);
    png_image img{};
    img.version = PNG_IMAGE_VERSION;
    // png_image_free is safe on a failed or finished image; this frees on every path
    auto guard = std::unique_ptr<png_image, void (*)(png_image*)>(&img, [](png_image* p) { png_image_free(p); });
    if (!png_image_begin_read_from_memory(&img, data, size)) image_fail(name, std::string("PNG: ") + img.message);
    image_check_size(img.width, img.height, name, lim);
    img.format = PNG_FORMAT_RGBA;
    DecodedImage out;
    out.width = img.width;
    out.height = img.height;
    out.rgba.resize(std::size_t(img.width) * img.height * 4);
    if (!png_image_finish_read(&img, nullptr, out.rgba.data(), 0, nullptr))
        image_fail(name, std::string("PNG: ") + img.message);
    if (img.warning_or_error & PNG_IMAGE_WARNING) out.warnings.push_back(name + ": PNG: " + img.message);
    return out;
}

inline DecodedImage decode_jpeg(const std::uint8_t* data, std::size_t size, const std::string& name,
                                const ImageLimits& lim) {
    if (size > 0xffffffffu) image_fail(name, "JPEG file too large");
    auto handle = std::unique_ptr<void, int (*)(tjhandle)>(tjInitDecompress(), tjDestroy);
    if (!handle) image_fail(name, "JPEG: cannot create a decoder");
    int w = 0, h = 0, subsamp = 0, colorspace = 0;
    if (tjDecompressHeader3(handle.get(), data, static_cast<unsigned long>(size), &w, &h, &subsamp, &colorspace) != 0)
        image_fail(name, std::string("JPEG: ") + tjGetErrorStr2(handle.get()));
    if (w <= 0 || h <= 0) image_fail(name, "JPEG: no pixels");
    image_check_size(std::uint64_t(w), std::uint64_t(h), name, lim);
    DecodedImage out;
    out.width = std::uint32_t(w);
    out.height = std::uint32_t(h);
    out.rgba.resize(std::size_t(w) * std::size_t(h) * 4);
    if (tjDecompress2(handle.get(), data, static_cast<unsigned long>(size), out.rgba.data(), w, 0, h, TJPF_RGBA,
                      TJFLAG_LIMITSCANS) != 0) {
        if (tjGetErrorCode(handle.get()) != TJERR_WARNING) image_fail(name, std::string("JPEG: ") + tjGetErrorStr2(handle.get()));
        out.warnings.push_back(name + ": JPEG: " + tjGetErrorStr2(handle.get()));
    }
    return out;
}

/// BMP and TGA: the header checked here, the pixels decoded by stb_image.
inline DecodedImage decode_stb(ImageFormat f, const std::uint8_t* data, std::size_t size, const std::string& name,
                               const ImageLimits& lim) {
    const char* what = f == ImageFormat::bmp ? "BMP" : "TGA";
    if (f == ImageFormat::bmp) {
        if (size < 26) image_fail(name, "BMP: file too short for its header");
        const std::uint32_t dib = image_le32(data + 14);
        std::uint64_t w = 0, h = 0;
        std::uint32_t bpp = 0, compression = 0;
        if (dib == 12) {  // OS/2 BITMAPCOREHEADER: 16-bit sizes
            w = image_le16(data + 18);
            h = image_le16(data + 20);
            bpp = image_le16(data + 24);
        } else {
            if (size < 34 || dib < 40) image_fail(name, "BMP: unsupported or truncated header");
            const auto sw = std::int32_t(image_le32(data + 18)), sh = std::int32_t(image_le32(data + 22));
            if (sw <= 0 || sh == 0 || sh == INT32_MIN) image_fail(name, "BMP: bad size");
            w = std::uint64_t(sw);
            h = std::uint64_t(sh < 0 ? -std::int64_t(sh) : sh);
            bpp = image_le16(data + 28);
            compression = image_le32(data + 30);
        }
        image_check_size(w, h, name, lim);
        if ((compression == 0 || compression == 3) && (bpp == 1 || bpp == 4 || bpp == 8 || bpp == 16 || bpp == 24 || bpp == 32)) {
            const std::uint64_t row = ((w * bpp + 31) / 32) * 4, offset = image_le32(data + 10);
            if (offset > size || row * h > size - offset)
                image_fail(name, "BMP: file holds " + std::to_string(size) + " bytes, too few for its " +
                                     std::to_string(w) + " x " + std::to_string(h) + " pixels");
        }
    } else {
        if (size < 18) image_fail(name, "TGA: file too short for its header");
        // stb_image picks its decoder by content, trying JPEG, PNG, BMP, GIF, PSD, PIC, PNM and
        // HDR before TGA, so a file named .tga holding a JPEG (its SOI after 0xff fill bytes)
        // would reach stb's JPEG decoder (found by fuzz_texture: out-of-bounds index in
        // stbi__build_huffman). A TGA's colour-map type (byte 1) is 0 or 1 and its image type
        // (byte 2) one of 1, 2, 3, 9, 10, 11; no other format stb knows passes its own test
        // with such a byte 1, so with these checks only stb's TGA decoder runs.
        const std::uint8_t map_type = data[1], image_type = data[2];
        const bool type_ok = image_type == 1 || image_type == 2 || image_type == 3 || image_type == 9 ||
                             image_type == 10 || image_type == 11;
        if (map_type > 1 || !type_ok)
            image_fail(name, "TGA: not a TGA header (colour-map type " + std::to_string(map_type) + ", image type " +
                                 std::to_string(image_type) + ")");
        image_check_size(image_le16(data + 12), image_le16(data + 14), name, lim);
    }
    if (size > 0x7fffffffu) image_fail(name, std::string(what) + " file too large");
    int w = 0, h = 0, comp = 0;
    stbi_uc* px = stbi_load_from_memory(data, int(size), &w, &h, &comp, 4);
    auto guard = std::unique_ptr<stbi_uc, void (*)(void*)>(px, stbi_image_free);
    if (!px || w <= 0 || h <= 0) {
        const char* reason = stbi_failure_reason();
        image_fail(name, std::string(what) + ": " + (reason ? reason : "cannot decode"));
    }
    image_check_size(std::uint64_t(w), std::uint64_t(h), name, lim);
    DecodedImage out;
    out.width = std::uint32_t(w);
    out.height = std::uint32_t(h);
    out.rgba.assign(px, px + std::size_t(w) * std::size_t(h) * 4);
    return out;
}

}  // namespace detail

/// The format of an image in memory: PNG, JPEG and BMP by their signatures, TGA (which has
/// none) by a name ending in ".tga". Throws ImageDecodeError naming `name` for anything else.
inline ImageFormat sniff_image_format(const std::uint8_t* data, std::size_t size, const std::string& name) {
    static constexpr std::uint8_t png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (size >= 8 && std::equal(png_sig, png_sig + 8, data)) return ImageFormat::png;
    if (size >= 3 && data[0] == 0xff && data[1] == 0xd8 && data[2] == 0xff) return ImageFormat::jpeg;
    if (size >= 2 && data[0] == 'B' && data[1] == 'M') return ImageFormat::bmp;
    if (detail::image_ends_with_tga(name)) return ImageFormat::tga;
    detail::image_fail(name, "not a PNG, JPEG, BMP or TGA image");
}

/// Decodes an image held in memory (`name` names it in errors and picks TGA). Throws
/// ImageDecodeError for a damaged file, an unsupported format or a size over the limits.
inline DecodedImage decode_image(const std::uint8_t* data, std::size_t size, const std::string& name,
                                 const ImageLimits& lim = {}) {
    if (size == 0) detail::image_fail(name, "empty file");
    if (size > lim.max_file_bytes) detail::image_fail(name, "file larger than raykit's image limit");
    const ImageFormat f = sniff_image_format(data, size, name);
    switch (f) {
        case ImageFormat::png: return detail::decode_png(data, size, name, lim);
        case ImageFormat::jpeg: return detail::decode_jpeg(data, size, name, lim);
        default: return detail::decode_stb(f, data, size, name, lim);
    }
}

/// Reads and decodes an image file; throws ImageDecodeError naming the file on any failure.
inline DecodedImage read_image(const std::filesystem::path& file, const ImageLimits& lim = {}) {
    const std::string name = file.string();
    std::error_code ec;
    if (!std::filesystem::is_regular_file(file, ec)) detail::image_fail(name, "file not found or not a regular file");
    const std::uintmax_t bytes = std::filesystem::file_size(file, ec);
    if (ec) detail::image_fail(name, "cannot read its size");
    if (bytes > lim.max_file_bytes) detail::image_fail(name, "file larger than raykit's image limit");
    std::ifstream in(file, std::ios::binary);
    if (!in) detail::image_fail(name, "cannot open");
    std::vector<std::uint8_t> data(static_cast<std::size_t>(bytes));
    in.read(reinterpret_cast<char*>(data.data()), std::streamsize(data.size()));
    if (std::size_t(in.gcount()) != data.size()) detail::image_fail(name, "cannot read");
    return decode_image(data.data(), data.size(), name, lim);
}

}  // namespace raykit
