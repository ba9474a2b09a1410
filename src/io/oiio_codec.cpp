// cambium — the OpenImageIO plugin (libcambium_oiio.so, io/image_codec.h):
// decoding any image OpenImageIO reads, encoding PNG and EXR into memory.
#include "io/image_codec.h"

#include <fmt/format.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <mutex>
#include <string>

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

/// While alive, what the image libraries write to stderr themselves (libpng's
/// default handler prints "libpng error: ..." before OpenImageIO hears of
/// it, an unprefixed line ahead of cambium's one) goes to a memory file,
/// dropped: OpenImageIO's error carries it.  Nothing of cambium's is lost:
/// only src/app writes to stderr, and only its last word on exit.
class LibraryChatter {
public:
    LibraryChatter()
    {
        lock_ = std::unique_lock<std::mutex>(mutex());
        std::fflush(stderr);
        memory_ = ::memfd_create("cambium-image-stderr", MFD_CLOEXEC);
        saved_ = memory_ >= 0 ? ::dup(2) : -1;
        if (saved_ >= 0 && ::dup2(memory_, 2) < 0) {
            ::close(saved_);
            saved_ = -1;
        }
    }
    ~LibraryChatter()
    {
        if (saved_ >= 0) {
            std::fflush(stderr);
            ::dup2(saved_, 2);
            ::close(saved_);
        }
        if (memory_ >= 0)
            ::close(memory_);
    }
    LibraryChatter(const LibraryChatter&) = delete;
    LibraryChatter& operator=(const LibraryChatter&) = delete;

private:
    static std::mutex& mutex()
    {
        static std::mutex m;
        return m;
    }
    std::unique_lock<std::mutex> lock_;
    int memory_ = -1, saved_ = -1;
};

std::string decode(const std::string& path, const std::string& format, size_t maxPixels,
                   cambium::CodecImage& out)
try {
    const LibraryChatter quiet;
    // The format's reader alone (a name without an extension names the
    // format): OpenImageIO's search over every reader is never run.
    auto in = OIIO::ImageInput::create(format, false);
    if (!in)
        return fmt::format("{}: OpenImageIO has no {} reader ({})", path, format,
                           oneLine(OIIO::geterror()));
    OIIO::ImageSpec spec;
    if (!in->open(path, spec))
        return fmt::format("{}: not a {} image OpenImageIO can read ({})", path, format,
                           oneLine(in->geterror()));
    if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0)
        return fmt::format("{}: the image is empty", path);
    out.width = spec.width;  // for the caller's message when it is refused
    out.height = spec.height;
    // A volume (a .vdb, a DDS volume texture) reads every slice: one is read.
    if (spec.depth > 1)
        return fmt::format("{}: a volume image of {} slices, not a photo", path, spec.depth);
    if (double(spec.width) * spec.height > double(maxPixels))
        return fmt::format(
            "{}: its header says {} x {} pixels, more than the {:g} million pixels read: scale "
            "it down",
            path, spec.width, spec.height, double(maxPixels) / 1e6);
    // A tile is decoded whole, every channel, whatever part of it the image
    // covers: a 402-byte 16 x 16 TIFF of 65536 x 65536 tiles cost 8.9 GB.
    // A tile side past 2^31 reads as negative (a TIFF's 2^32 - 1 as -1), and
    // the reader's loop over tile rows then never ends: refused too.
    const bool tiled = spec.tile_width != 0 || spec.tile_height != 0;
    const double tile = double(std::max(spec.tile_width, 1)) * std::max(spec.tile_height, 1) *
                        std::max(spec.tile_depth, 1);
    const double pixels = double(spec.width) * spec.height;
    if (tiled && (spec.tile_width <= 0 || spec.tile_height <= 0 || spec.tile_depth < 0 ||
                  tile > double(maxPixels) || tile > 4.0 * std::max(pixels, 65536.0)))
        return fmt::format(
            "{}: its header says tiles of {} x {} pixels for a picture of {} x {}: damaged or "
            "hostile",
            path, spec.tile_width, spec.tile_height, spec.width, spec.height);
    out.width = spec.width;
    out.height = spec.height;
    // At most four channels read (grey, grey and alpha, RGB, RGBA): a header
    // claiming a thousand channels is no bomb.
    out.channels = std::min(spec.nchannels, 4);
    out.pixels.resize(size_t(spec.width) * size_t(spec.height) * size_t(out.channels));
    // Some readers report damage (a TIFF's strip cut short, read as zeros)
    // and still return success: any error they leave is a failure.
    const bool read =
        in->read_image(0, 0, 0, out.channels, OIIO::TypeDesc::FLOAT, out.pixels.data());
    const std::string error = oneLine(in->geterror());
    if (!read || !error.empty())
        return fmt::format("{}: cannot read the {} image: {}", path, format,
                           error.empty() ? "its reader gives no reason" : error);
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
