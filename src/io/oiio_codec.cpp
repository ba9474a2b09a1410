// cambium — the OpenImageIO plugin (libcambium_oiio.so, io/image_codec.h):
// decoding any image OpenImageIO reads, encoding PNG and EXR into memory.
#include "io/image_codec.h"

#include <fmt/format.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <exception>

namespace {

/// An image library's message on one line: its lines joined with "; "
/// (libpng's come as three: "Read error ...\nPNG read error: ...\nPNG
/// library error").
std::string oneLine(const std::string& text)
{
    std::string out;
    size_t at = 0;
    while (at < text.size()) {
        size_t end = text.find('\n', at);
        if (end == std::string::npos)
            end = text.size();
        std::string line = text.substr(at, end - at);
        while (!line.empty() && (line.back() == '\r' || line.back() == ' '))
            line.pop_back();
        if (!line.empty())
            out += (out.empty() ? "" : "; ") + line;
        at = end + 1;
    }
    return out;
}

std::string decode(const std::string& path, size_t maxPixels, cambium::CodecImage& out)
try {
    auto in = OIIO::ImageInput::open(path);
    if (!in)
        return fmt::format("{}: not an image OpenImageIO can read ({})", path,
                           oneLine(OIIO::geterror()));
    // OpenImageIO's "null" reader invents a picture for any name it is given.
    if (std::string(in->format_name()) == "null")
        return fmt::format("{}: not an image file (OpenImageIO would invent one)", path);
    const OIIO::ImageSpec& spec = in->spec();
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
        return fmt::format("{}: the image is empty", path);
    // A volume (a .vdb, a DDS volume texture) reads every slice: one is read.
    if (spec.depth > 1)
        return fmt::format("{}: a volume image of {} slices, not a photo", path, spec.depth);
    if (double(spec.width) * spec.height > double(maxPixels))
        return fmt::format(
            "{}: its header says {} x {} pixels, more than the {:g} million pixels read: scale "
            "it down",
            path, spec.width, spec.height, double(maxPixels) / 1e6);
    out.width = spec.width;
    out.height = spec.height;
    // At most four channels read (grey, grey and alpha, RGB, RGBA): a header
    // claiming a thousand channels is no bomb.
    out.channels = std::min(spec.nchannels, 4);
    out.pixels.resize(size_t(spec.width) * size_t(spec.height) * size_t(out.channels));
    if (!in->read_image(0, 0, 0, out.channels, OIIO::TypeDesc::FLOAT, out.pixels.data()))
        return fmt::format("{}: cannot read the image: {}", path, oneLine(in->geterror()));
    out.colourSpace = spec.get_string_attribute("oiio:ColorSpace");
    out.floatFormat = spec.format.basetype == OIIO::TypeDesc::FLOAT ||
                      spec.format.basetype == OIIO::TypeDesc::HALF ||
                      spec.format.basetype == OIIO::TypeDesc::DOUBLE;
    return {};
} catch (const std::exception& e) {
    return fmt::format("{}: {}", path, e.what());
}

std::string encode(const std::string& path, const cambium::CodecImage& img,
                   std::vector<unsigned char>& bytes)
try {
    auto out = OIIO::ImageOutput::create(path);  // the plugin by the name's extension
    if (!out)
        return oneLine(OIIO::geterror());
    if (!out->supports("ioproxy"))
        return "OpenImageIO cannot encode " + path + " into memory";
    OIIO::Filesystem::IOVecOutput memory(bytes);
    OIIO::ImageSpec spec(img.width, img.height, img.channels,
                         img.eightBit ? OIIO::TypeDesc::UINT8 : OIIO::TypeDesc::FLOAT);
    if (!img.channelNames.empty())
        spec.channelnames = img.channelNames;
    if (img.alphaChannel >= 0)
        spec.alpha_channel = img.alphaChannel;
    if (img.zChannel >= 0)
        spec.z_channel = img.zChannel;
    if (!img.colourSpace.empty())
        spec.attribute("oiio:ColorSpace", img.colourSpace);
    spec.attribute("Software", "cambium");
    if (!out->set_ioproxy(&memory) || !out->open(path, spec) ||
        !out->write_image(OIIO::TypeDesc::FLOAT, img.pixels.data()) || !out->close())
        return oneLine(out->geterror());
    return {};
} catch (const std::exception& e) {
    return e.what();
}

const cambium::ImageCodecApi kApi = {cambium::kImageCodecAbi, decode, encode};

}  // namespace

extern "C" __attribute__((visibility("default"))) const cambium::ImageCodecApi*
cambium_image_codec()
{
    return &kApi;
}
