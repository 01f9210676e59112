// Image decoding (render/image_decode.hpp): formats decode to the pixels they hold, and hostile
// files — oversized headers, truncated pixel data, damaged Huffman tables, unknown formats — are
// refused with an error naming the file before any pixel buffer is allocated.
#include <gtest/gtest.h>
#include <turbojpeg.h>
#include <zlib.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "raykit/render/image_decode.hpp"
#include "raykit/render/texture.hpp"

using namespace raykit;

namespace {

using Bytes = std::vector<std::uint8_t>;

std::filesystem::path temp_dir(const std::string& name) {
    const auto d = std::filesystem::temp_directory_path() / ("raykit_test_decode_" + name);
    std::filesystem::create_directories(d);
    return d;
}

void put_le16(Bytes& b, std::uint32_t v) {
    b.push_back(std::uint8_t(v));
    b.push_back(std::uint8_t(v >> 8));
}
void put_le32(Bytes& b, std::uint32_t v) {
    put_le16(b, v & 0xffff);
    put_le16(b, v >> 16);
}
void put_be32(Bytes& b, std::uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) b.push_back(std::uint8_t(v >> s));
}

/// A 24-bit bottom-up BMP of `rgb` (w * h * 3 bytes, top row first); `claim_w/h` override the header.
Bytes make_bmp(std::uint32_t w, std::uint32_t h, const Bytes& rgb, std::uint32_t claim_w = 0, std::uint32_t claim_h = 0) {
    const std::uint32_t row = (w * 3 + 3) & ~3u;
    Bytes b = {'B', 'M'};
    put_le32(b, 54 + row * h);
    put_le32(b, 0);
    put_le32(b, 54);
    put_le32(b, 40);
    put_le32(b, claim_w ? claim_w : w);
    put_le32(b, claim_h ? claim_h : h);
    put_le16(b, 1);
    put_le16(b, 24);
    for (int i = 0; i < 6; ++i) put_le32(b, 0);
    for (std::uint32_t y = h; y-- > 0;) {
        for (std::uint32_t x = 0; x < w; ++x) {
            const std::uint8_t* p = &rgb[(y * w + x) * 3];
            b.insert(b.end(), {p[2], p[1], p[0]});
        }
        for (std::uint32_t k = w * 3; k < row; ++k) b.push_back(0);
    }
    return b;
}

/// An uncompressed 32-bit top-down TGA (type 2) of `rgba`; `claim_w/h` override the header.
Bytes make_tga(std::uint32_t w, std::uint32_t h, const Bytes& rgba, std::uint32_t claim_w = 0, std::uint32_t claim_h = 0) {
    Bytes b = {0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0};
    put_le16(b, claim_w ? claim_w : w);
    put_le16(b, claim_h ? claim_h : h);
    b.push_back(32);
    b.push_back(0x28);  // 8 alpha bits, top-left origin
    for (std::size_t i = 0; i + 3 < rgba.size(); i += 4) b.insert(b.end(), {rgba[i + 2], rgba[i + 1], rgba[i], rgba[i + 3]});
    return b;
}

/// A PNG made of a valid signature and an IHDR chunk claiming w x h (no pixel data).
Bytes png_header_only(std::uint32_t w, std::uint32_t h) {
    Bytes b = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    put_be32(b, 13);
    Bytes chunk = {'I', 'H', 'D', 'R'};
    put_be32(chunk, w);
    put_be32(chunk, h);
    chunk.insert(chunk.end(), {8, 6, 0, 0, 0});
    b.insert(b.end(), chunk.begin(), chunk.end());
    put_be32(b, std::uint32_t(crc32(0, chunk.data(), uInt(chunk.size()))));
    return b;
}

/// A JPEG of `rgb` from libjpeg-turbo's own encoder (4:4:4, quality 100).
Bytes make_jpeg(int w, int h, const Bytes& rgb, int flags = 0) {
    tjhandle t = tjInitCompress();
    unsigned char* out = nullptr;
    unsigned long size = 0;
    const int rc = tjCompress2(t, rgb.data(), w, 0, h, TJPF_RGB, &out, &size, TJSAMP_444, 100, flags);
    EXPECT_EQ(rc, 0) << tjGetErrorStr2(t);
    Bytes b(out, out + size);
    tjFree(out);
    tjDestroy(t);
    return b;
}

Bytes random_rgb(std::uint32_t w, std::uint32_t h, unsigned seed, int channels = 3) {
    std::mt19937 rng(seed);
    Bytes px(std::size_t(w) * h * channels);
    for (auto& c : px) c = std::uint8_t(rng());
    return px;
}

/// Smooth content: JPEG at quality 100 reproduces it to within a few codes.
Bytes gradient_rgb(std::uint32_t w, std::uint32_t h) {
    Bytes px(std::size_t(w) * h * 3);
    for (std::uint32_t y = 0; y < h; ++y)
        for (std::uint32_t x = 0; x < w; ++x) {
            std::uint8_t* p = &px[(y * w + x) * 3];
            p[0] = std::uint8_t(x * 255 / (w - 1));
            p[1] = std::uint8_t(y * 255 / (h - 1));
            p[2] = std::uint8_t(128);
        }
    return px;
}

/// Decodes and expects an ImageDecodeError whose message names `name` and contains `what`.
void expect_refused(const Bytes& b, const std::string& name, const std::string& what) {
    try {
        decode_image(b.data(), b.size(), name);
        ADD_FAILURE() << name << ": decoded, expected an error containing '" << what << "'";
    } catch (const ImageDecodeError& e) {
        const std::string msg = e.what();
        EXPECT_EQ(msg.rfind(name + ": ", 0), 0u) << msg;
        EXPECT_NE(msg.find(what), std::string::npos) << msg;
    }
}

}  // namespace

TEST(ImageDecode, BmpAndTgaDecodeToTheirExactPixels) {
    const std::uint32_t w = 7, h = 5;  // odd width: BMP rows are padded
    const Bytes rgb = random_rgb(w, h, 1);
    const Bytes bmp = make_bmp(w, h, rgb);
    const DecodedImage a = decode_image(bmp.data(), bmp.size(), "a.bmp");
    ASSERT_EQ(a.width, w);
    ASSERT_EQ(a.height, h);
    for (std::size_t i = 0; i < std::size_t(w) * h; ++i) {
        for (int c = 0; c < 3; ++c) ASSERT_EQ(a.rgba[i * 4 + c], rgb[i * 3 + c]) << "texel " << i;
        ASSERT_EQ(a.rgba[i * 4 + 3], 255);
    }
    const Bytes rgba = random_rgb(w, h, 2, 4);
    const Bytes tga = make_tga(w, h, rgba);
    const DecodedImage b = decode_image(tga.data(), tga.size(), "b.TGA");
    ASSERT_EQ(b.width, w);
    ASSERT_EQ(b.height, h);
    EXPECT_EQ(b.rgba, rgba);
}

TEST(ImageDecode, JpegDecodesCloseToWhatWasEncoded) {
    const int w = 32, h = 24;
    const Bytes rgb = gradient_rgb(w, h);
    for (int flags : {0, TJFLAG_PROGRESSIVE}) {
        const Bytes jpg = make_jpeg(w, h, rgb, flags);
        const DecodedImage d = decode_image(jpg.data(), jpg.size(), "g.jpg");
        ASSERT_EQ(d.width, std::uint32_t(w));
        ASSERT_EQ(d.height, std::uint32_t(h));
        EXPECT_TRUE(d.warnings.empty());
        int worst = 0;
        for (int i = 0; i < w * h; ++i) {
            for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(int(d.rgba[i * 4 + c]) - int(rgb[i * 3 + c])));
            ASSERT_EQ(d.rgba[i * 4 + 3], 255);
        }
        EXPECT_LE(worst, 4) << "flags " << flags;
    }
}

TEST(ImageDecode, PngRoundTripThroughWritePng) {
    Image img(5, 3);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    for (vec4& p : img.pixels) p = vec4(U(rng), U(rng), U(rng), 1.0f);
    const auto dir = temp_dir("decode_png");
    write_png(img, dir / "r.png");
    const Bytes want = to_bytes(img);  // what write_png encodes: 8-bit sRGB RGB
    const DecodedImage d = read_image(dir / "r.png");
    ASSERT_EQ(d.width, 5u);
    ASSERT_EQ(d.height, 3u);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) {
        for (int c = 0; c < 3; ++c) EXPECT_EQ(d.rgba[i * 4 + c], want[i * 3 + c]) << i;
        EXPECT_EQ(d.rgba[i * 4 + 3], 255);
    }
}

// Issue 12, defect 2: tiny headers claiming 23000 x 23000 pixels made stb allocate ~2 GB and
// render on; they are refused from the header, before a pixel buffer exists.
TEST(ImageDecode, OversizedHeadersAreRefusedBeforeAllocation) {
    Bytes tga = make_tga(1, 1, {1, 2, 3, 4}, 23000, 23000);
    tga.resize(18);
    expect_refused(tga, "huge.tga", "over raykit's image limit");
    Bytes bmp = make_bmp(1, 1, {1, 2, 3}, 23000, 23000);
    bmp.resize(54);
    expect_refused(bmp, "huge.bmp", "over raykit's image limit");
    expect_refused(png_header_only(40000, 40000), "huge.png", "over raykit's image limit");
    expect_refused(png_header_only(16384, 16384), "big.png", "over raykit's image limit");  // 2^28 pixels
    // within the limits, but the BMP holds far fewer bytes than its pixels need
    Bytes small = make_bmp(1, 1, {1, 2, 3}, 4000, 4000);
    expect_refused(small, "short.bmp", "too few for its");
    // a caller's tighter limits apply the same way
    const Bytes ok = make_bmp(7, 5, random_rgb(7, 5, 4));
    EXPECT_EQ(decode_image(ok.data(), ok.size(), "ok.bmp").width, 7u);
    EXPECT_THROW(decode_image(ok.data(), ok.size(), "ok.bmp", ImageLimits{6, 1000, 1000}), ImageDecodeError);
    EXPECT_THROW(decode_image(ok.data(), ok.size(), "ok.bmp", ImageLimits{8, 34, 1000}), ImageDecodeError);
    EXPECT_THROW(decode_image(ok.data(), ok.size(), "ok.bmp", ImageLimits{8, 35, 100}), ImageDecodeError);
    EXPECT_EQ(decode_image(ok.data(), ok.size(), "ok.bmp", ImageLimits{7, 35, 1000}).height, 5u);
    // nothing at all
    expect_refused(Bytes{'B', 'M', 0, 0}, "stub.bmp", "too short");
    expect_refused(Bytes{0, 0, 2}, "stub.tga", "too short");
}

// Issue 12, defect 1: a 23-byte JPEG whose DHT code counts add up to more than 256 made
// Debian's stb_image 2.27 write out of bounds (seen under ASan). libjpeg-turbo refuses it.
TEST(ImageDecode, JpegWithOverfullHuffmanTableIsRefused) {
    Bytes j = {0xff, 0xd8, 0xff, 0xc4, 0x00, 0x13, 0x00};  // SOI, DHT (length 19), class 0 id 0
    for (int i = 0; i < 16; ++i) j.push_back(0xff);       // 16 code counts of 255: 4,080 codes
    ASSERT_EQ(j.size(), 23u);
    expect_refused(j, "dht.jpg", "JPEG");
    // and inside a real file: replace the first DHT's counts of a valid JPEG
    Bytes real = make_jpeg(16, 16, gradient_rgb(16, 16));
    std::size_t at = 0;
    for (std::size_t i = 0; i + 1 < real.size(); ++i)
        if (real[i] == 0xff && real[i + 1] == 0xc4) {
            at = i;
            break;
        }
    ASSERT_GT(at, 0u);
    for (int k = 0; k < 16; ++k) real[at + 5 + k] = 0xff;
    expect_refused(real, "dht2.jpg", "JPEG");
    // the same bytes under a .tga name (TGA has no signature) never reach stb's JPEG decoder,
    // which finds a JPEG by content after 0xff fill bytes (found by fuzz_texture)
    Bytes fill = {0xff, 0xff};
    fill.insert(fill.end(), j.begin(), j.end());
    expect_refused(fill, "dht.tga", "not a TGA header");
    expect_refused(j, "dht.tga", "JPEG: ");  // a signature wins over the name
}

TEST(ImageDecode, UnknownFormatsAndEmptyFilesAreRefused) {
    expect_refused(Bytes{'G', 'I', 'F', '8', '9', 'a', 1, 0, 1, 0}, "a.gif", "not a PNG, JPEG, BMP or TGA");
    expect_refused(Bytes{'n', 'o', 't'}, "a.png", "not a PNG, JPEG, BMP or TGA");
    expect_refused(Bytes{}, "e.png", "empty file");
    Bytes png = png_header_only(4, 4);  // valid header, no image data
    expect_refused(png, "nodata.png", "PNG");
}

TEST(ImageDecode, TruncatedJpegDecodesWithAWarning) {
    const Bytes full = make_jpeg(64, 64, gradient_rgb(64, 64));
    const Bytes cut(full.begin(), full.begin() + std::ptrdiff_t(full.size() * 2 / 3));
    const DecodedImage d = decode_image(cut.data(), cut.size(), "cut.jpg");
    EXPECT_EQ(d.width, 64u);
    ASSERT_EQ(d.warnings.size(), 1u);
    EXPECT_NE(d.warnings[0].find("cut.jpg"), std::string::npos) << d.warnings[0];
}

// What a renderer sees: the refused file becomes the placeholder texture with one warning that
// names the file and the reason, never a 4 GB allocation or an uninitialised image.
TEST(ImageDecode, LoadTextureTurnsRefusalsIntoPlaceholderAndWarning) {
    const auto dir = temp_dir("decode_tex");
    Bytes tga = make_tga(1, 1, {1, 2, 3, 4}, 23000, 23000);
    tga.resize(18);
    std::ofstream(dir / "huge.tga", std::ios::binary).write(reinterpret_cast<const char*>(tga.data()), std::streamsize(tga.size()));
    std::vector<std::string> warnings;
    const Texture t = load_texture(dir / "huge.tga", true, &warnings);
    EXPECT_TRUE(t.placeholder);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("huge.tga"), std::string::npos) << warnings[0];
    EXPECT_NE(warnings[0].find("23000 x 23000"), std::string::npos) << warnings[0];
    warnings.clear();
    EXPECT_TRUE(load_texture(dir, true, &warnings).placeholder);  // a folder is not an image
    EXPECT_EQ(warnings.size(), 1u);
}

TEST(ImageDecode, SharedTexturesDecode) {
    const std::filesystem::path root = RAYKIT_SHARED_DATA_DIR;
    if (!std::filesystem::is_directory(root)) GTEST_SKIP() << "no shared data";
    int n = 0;
    for (const auto& e : std::filesystem::recursive_directory_iterator(root)) {
        std::string ext = e.path().extension().string();
        for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
        if (ext != ".png" && ext != ".jpg" && ext != ".jpeg" && ext != ".bmp" && ext != ".tga") continue;
        const DecodedImage d = read_image(e.path());
        EXPECT_GT(d.width, 0u) << e.path();
        EXPECT_EQ(d.rgba.size(), std::size_t(d.width) * d.height * 4) << e.path();
        ++n;
    }
    EXPECT_GT(n, 10);
}

// A PFM header is a few bytes of text: "PF 1048576 1048576 -1" asked for 16 TiB before the size
// was checked against the limits and against the bytes the file holds.
TEST(ImageDecode, PfmHeadersAreCheckedBeforeAllocation) {
    const auto dir = temp_dir("pfm");
    auto write = [&](const std::string& name, const std::string& text) {
        std::ofstream(dir / name, std::ios::binary) << text;
        return dir / name;
    };
    auto refused = [&](const std::filesystem::path& p, const std::string& what) {
        try {
            read_pfm(p);
            ADD_FAILURE() << p << " was read";
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find(p.string()), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
        }
    };
    refused(write("huge.pfm", "PF\n1048576 1048576\n-1\n"), "over raykit's image limit");
    refused(write("short.pfm", "PF\n4000 4000\n-1\n" + std::string(64, '\0')), "truncated data");
    refused(write("grey.pfm", "Pf\n3 2\n-1\n" + std::string(6 * 4 - 1, '\0')), "truncated data");
    refused(dir, "not a regular file");
    // and a real one still reads
    Image img(3, 2);
    for (std::size_t i = 0; i < img.pixels.size(); ++i) img.pixels[i] = vec4(float(i), 0.5f, -1.0f, 1.0f);
    write_pfm(img, dir / "ok.pfm");
    const Image back = read_pfm(dir / "ok.pfm");
    ASSERT_EQ(back.pixels.size(), img.pixels.size());
    for (std::size_t i = 0; i < img.pixels.size(); ++i) EXPECT_EQ(back.pixels[i], img.pixels[i]);
}
