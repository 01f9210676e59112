// Texture files through the decoders `raykit render` uses (render/image_decode.hpp, the code
// under load_texture). The first byte picks the name the decoder sees (".tga" or not, since TGA
// is known only by its name); the rest is the file. A file that decodes must give a size within
// the limits (tighter than the defaults, for speed: the same checks), exactly width * height * 4 bytes, and a texture whose samples are finite and in
// [0, 1]; anything else must be an ImageDecodeError naming the file.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "raykit/render/image_decode.hpp"
#include "raykit/render/texture.hpp"

namespace {
// Smaller than the defaults so that each input decodes fast: the checks are the same code.
constexpr raykit::ImageLimits kLimits{4096, std::uint64_t(1) << 20, std::uint64_t(1) << 22};
void check(bool ok) {
    if (!ok) __builtin_trap();
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const std::string name = (data[0] & 1) ? "fuzz.tga" : "fuzz.img";
    raykit::DecodedImage img;
    try {
        img = raykit::decode_image(data + 1, size - 1, name, kLimits);
    } catch (const raykit::ImageDecodeError& e) {
        check(std::string(e.what()).rfind(name + ": ", 0) == 0);
        return 0;
    }
    check(img.width > 0 && img.height > 0 && img.width <= kLimits.max_side && img.height <= kLimits.max_side);
    check(std::uint64_t(img.width) * img.height <= kLimits.max_pixels);
    check(img.rgba.size() == std::size_t(img.width) * img.height * 4);
    const raykit::Texture t = raykit::make_texture(img.width, img.height, std::move(img.rgba), (data[0] & 2) != 0);
    for (float u : {0.0f, 0.37f, 0.999f, -2.5f})
        for (float v : {0.0f, 0.61f, 1.0f}) {
            const raykit::vec4 c = t.sample({u, v});
            for (int k = 0; k < 4; ++k) check(std::isfinite(c[k]) && c[k] >= 0.0f && c[k] <= 1.0f + 1e-6f);
        }
    return 0;
}
