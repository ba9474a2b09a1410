// cambium — images written with OpenImageIO through the checked writer.
#include "io/image_file.h"

#include "core/files.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cambium {

namespace {

float toSrgb(float v)
{
    v = std::clamp(v, 0.0f, 1.0f);
    return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

}  // namespace

void checkImageOutput(const std::string& path)
{
    fileFormat(path, {"png", "exr"}, "image");
    checkOutputPath(path);
}

void writeImage(const RenderImage& img, const std::string& path)
{
    const std::string ext = fileFormat(path, {"png", "exr"}, "image");
    // OpenImageIO encodes into memory; the checked writer writes the bytes.
    std::vector<unsigned char> bytes;
    {
        auto out = OIIO::ImageOutput::create(path);  // the plugin by the name's extension
        if (!out || !out->supports("ioproxy"))
            throw std::runtime_error(out ? "OpenImageIO cannot encode ." + ext + " into memory"
                                         : OIIO::geterror());
        OIIO::Filesystem::IOVecOutput memory(bytes);
        const size_t n = size_t(img.width) * size_t(img.height);
        std::vector<float> px;
        OIIO::ImageSpec spec;
        if (ext == "png") {
            spec = OIIO::ImageSpec(img.width, img.height, 4, OIIO::TypeDesc::UINT8);
            spec.attribute("oiio:ColorSpace", "sRGB");
            px.resize(4 * n);
            for (size_t i = 0; i < n; ++i) {
                for (int k = 0; k < 3; ++k)
                    px[4 * i + size_t(k)] = toSrgb(img.rgb[3 * i + size_t(k)]);
                px[4 * i + 3] = 1.0f;  // the background is drawn: opaque
            }
        } else {
            spec = OIIO::ImageSpec(img.width, img.height, 8, OIIO::TypeDesc::FLOAT);
            spec.channelnames = {"R", "G", "B", "A", "Z", "N.x", "N.y", "N.z"};
            spec.alpha_channel = 3;
            spec.z_channel = 4;
            px.resize(8 * n);
            for (size_t i = 0; i < n; ++i) {
                for (int k = 0; k < 3; ++k) {
                    px[8 * i + size_t(k)] = img.rgb[3 * i + size_t(k)];
                    px[8 * i + 5 + size_t(k)] = img.normal[3 * i + size_t(k)];
                }
                px[8 * i + 3] = img.alpha[i];
                px[8 * i + 4] = img.depth[i];
            }
        }
        spec.attribute("Software", "cambium");
        if (!out->set_ioproxy(&memory) || !out->open(path, spec) ||
            !out->write_image(OIIO::TypeDesc::FLOAT, px.data()) || !out->close())
            throw std::runtime_error(out->geterror());
    }
    writeFile(path, bytes.data(), bytes.size());
}

}  // namespace cambium
