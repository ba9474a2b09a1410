// cambium — images written with OpenImageIO through the checked writer.
#include "io/image_file.h"

#include "core/error.h"
#include "core/files.h"

#include <fmt/format.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

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

float fromSrgb(float v)
{
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

}  // namespace

Photo readPhoto(const std::string& path)
{
    checkInputFile(path, "photo");
    auto in = OIIO::ImageInput::open(path);
    if (!in)
        throw InputError(
            fmt::format("{}: not an image OpenImageIO can read ({})", path, OIIO::geterror()));
    const OIIO::ImageSpec& spec = in->spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
        throw InputError(fmt::format("{}: the image is empty", path));
    if (double(spec.width) * spec.height * spec.nchannels > 4e8)
        throw InputError(
            fmt::format("{}: {} x {} pixels is more than a bark photo needs "
                        "(at most 100 million values): scale it down",
                        path, spec.width, spec.height));
    std::vector<float> px(size_t(spec.width) * size_t(spec.height) * size_t(spec.nchannels));
    if (!in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, px.data()))
        throw InputError(fmt::format("{}: cannot read the image: {}", path, in->geterror()));
    // Float formats (EXR, HDR) hold linear values; the 8- and 16-bit ones
    // are sRGB-encoded unless they say they are linear.
    const std::string space = spec.get_string_attribute("oiio:ColorSpace");
    const bool linear = space.empty() ? spec.format.basetype == OIIO::TypeDesc::FLOAT ||
                                            spec.format.basetype == OIIO::TypeDesc::HALF ||
                                            spec.format.basetype == OIIO::TypeDesc::DOUBLE
                                      : OIIO::Strutil::iequals(space, "linear") ||
                                            OIIO::Strutil::istarts_with(space, "lin");
    Photo out;
    out.width = spec.width;
    out.height = spec.height;
    const size_t n = size_t(spec.width) * size_t(spec.height), c = size_t(spec.nchannels);
    out.rgb.resize(3 * n);
    for (size_t i = 0; i < n; ++i)
        for (size_t k = 0; k < 3; ++k) {
            const float v = px[c * i + (c >= 3 ? k : 0)];  // grey (and grey with alpha) made RGB
            if (!std::isfinite(v))
                throw InputError(fmt::format("{}: pixel {} is not finite", path, i));
            out.rgb[3 * i + k] = linear ? std::max(v, 0.0f) : fromSrgb(std::clamp(v, 0.0f, 1.0f));
        }
    return out;
}

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
