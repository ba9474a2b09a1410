// cambium — images written with OpenImageIO through the checked writer.
#include "io/image_file.h"

#include "core/error.h"
#include "core/math.h"
#include "core/files.h"
#include "core/system.h"
#include "io/image_codec.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <dlfcn.h>
#include <fstream>
#include <future>
#include <mutex>
#include <stdexcept>

namespace cambium {

namespace {

/// The darkest value a linear photo may hold: ringing of a colour transform
/// just below 0 is black; below this a file holds data, not colour.
constexpr float kDarkestLinearPixel = -0.01f;

float toSrgb(float v)
{
    v = std::clamp(v, 0.0f, 1.0f);
    return v <= 0.0031308f ? 12.92f * v : 1.055f * std::pow(v, 1.0f / 2.4f) - 0.055f;
}

float fromSrgb(float v)
{
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

/// A PNG's chunks, walked before libpng reads them: libpng allocates and
/// clears a chunk's declared length before it reads the chunk (2 GB, for
/// seconds, from a 600-byte file whose tEXt length was changed), so a chunk
/// longer than the rest of the file is refused here, by name and place.
/// `size`: the file's, as checkInputFile found it.
void checkPngChunks(const std::string& path, uint64_t size)
{
    std::ifstream in(path, std::ios::binary);
    for (uint64_t at = 8; at + 8 <= size;) {
        unsigned char h[8];
        if (!in.seekg(std::streamoff(at)) || !in.read(reinterpret_cast<char*>(h), 8))
            return;
        const uint64_t length =
            uint64_t(h[0]) << 24 | uint64_t(h[1]) << 16 | uint64_t(h[2]) << 8 | h[3];
        const std::string type = printable(std::string(reinterpret_cast<const char*>(h + 4), 4));
        // Its type, data and CRC.
        if (at + 12 + length > size)
            throw InputError(fmt::format(
                "{}: a truncated or damaged PNG: its chunk {} at byte {} says {} bytes of data, "
                "and the file ends {} bytes after the chunk's name",
                path, type, at, length, size - at - 8));
        if (type == "IEND")
            return;
        at += 12 + length;
    }
}

/// A JPEG's scans counted by walking its markers before libjpeg reads it: a
/// progressive file may hold any number, and each costs a pass over every
/// coefficient of the picture (a few KB of file in 2000 scans is minutes of
/// decoding).  More than libjpeg-turbo's own tools allow (500) is refused.
/// A damaged walk stops quietly: libjpeg then names the damage.
void checkJpegScans(const std::string& path)
{
    constexpr int kMaxScans = 500;
    std::ifstream in(path, std::ios::binary);
    std::streambuf& b = *in.rdbuf();
    const auto eof = std::char_traits<char>::eof();
    auto next = [&] { return b.sbumpc(); };
    if (next() != 0xFF || next() != 0xD8)
        return;
    int scans = 0;
    int c = next();
    while (c != eof) {
        if (c != 0xFF) {  // inside a scan's entropy-coded data
            c = next();
            continue;
        }
        int m = next();
        while (m == 0xFF)  // fill bytes
            m = next();
        if (m == eof || m == 0xD9)  // the end
            return;
        if (m == 0x00 || (m >= 0xD0 && m <= 0xD7) || m == 0x01) {  // stuffed byte, restart
            c = next();
            continue;
        }
        const int hi = next(), lo = next();
        if (hi == eof || lo == eof)
            return;
        const long length = hi << 8 | lo;
        if (length < 2)
            return;
        if (m == 0xDA && ++scans > kMaxScans)
            throw InputError(fmt::format(
                "{}: a JPEG of more than {} scans (each a pass over the whole picture): "
                "damaged or hostile; re-save it",
                path, kMaxScans));
        if (b.pubseekoff(length - 2, std::ios::cur, std::ios::in) < 0)
            return;
        c = next();
    }
}

/// A BMP's headers, checked before OpenImageIO 2.4 reads them: its reader
/// takes a header of any size other than the four it knows as read and
/// leaves every field uninitialised (a 21-byte file was then decoded with a
/// size and channel count from the heap: a find of the photo fuzzer), sizes
/// its palette from the header's count, and unpacks an RLE picture whole in
/// open(), before the pixel count is checked.  `maxPixels`: the most pixels
/// read.
void checkBmpHeader(const std::string& path, uint64_t size, size_t maxPixels)
{
    // (the headers, and the three colour masks after a 40-byte one)
    unsigned char h[66] = {};
    std::ifstream in(path, std::ios::binary);
    in.read(reinterpret_cast<char*>(h), sizeof h);
    const uint64_t got = uint64_t(in.gcount());
    auto u16 = [&](int at) { return uint32_t(h[at]) | uint32_t(h[at + 1]) << 8; };
    auto u32 = [&](int at) { return u16(at) | u16(at + 2) << 16; };
    auto bad = [&](const std::string& what) {
        return InputError(fmt::format("{}: a damaged or unusual BMP: {}; re-save it", path, what));
    };
    if (got < 18)
        throw bad(fmt::format("the file ends at byte {}, inside its headers", got));
    const uint32_t header = u32(14);
    if (header == 12)
        throw bad("an OS/2 1.x header (12 bytes), which OpenImageIO reads wrong");
    if (header != 40 && header != 108 && header != 124)
        throw bad(fmt::format("a header of {} bytes, where a BMP's is 40, 108 or 124", header));
    if (size < 14 + header || got < 54)
        throw bad(fmt::format("the file ends at byte {}, inside its {}-byte header", size, header));
    const int32_t width = int32_t(u32(18)), height = int32_t(u32(22));
    const uint32_t planes = u16(26), bits = u16(28), compression = u32(30), colours = u32(46);
    const uint32_t data = u32(10);
    if (width <= 0 || height == 0 || height == INT32_MIN)
        throw bad(fmt::format("a picture of {} x {} pixels", width, height));
    const uint64_t rows = uint64_t(std::abs(int64_t(height)));
    if (double(width) * double(rows) > double(maxPixels))
        throw InputError(fmt::format(
            "{}: its header says {} x {} pixels, more than the {:g} million pixels read: scale "
            "it down",
            path, width, rows, double(maxPixels) / 1e6));
    if (planes != 1)
        throw bad(fmt::format("{} colour planes, where a BMP has 1", planes));
    if (bits != 1 && bits != 4 && bits != 8 && bits != 16 && bits != 24 && bits != 32)
        throw bad(fmt::format("{} bits a pixel, where a BMP has 1, 4, 8, 16, 24 or 32", bits));
    const bool rle = compression == 1 || compression == 2;
    const bool fits = compression == 0 || (compression == 1 && bits == 8) ||
                      (compression == 2 && bits == 4) ||
                      (compression == 3 && (bits == 16 || bits == 32));
    if (!fits)
        throw bad(fmt::format("compression {} for {} bits a pixel", compression, bits));
    if (rle && height < 0)
        throw bad("a run-length encoded picture stored top down");
    // Colour masks (after a 40-byte header, inside a longer one), as
    // OpenImageIO 2.4 decodes them: 16 bits as 5-5-5 or 5-6-5 (other masks
    // came out as other colours), 32 bits as 8-8-8 whatever they say (a
    // picture with its red in the top byte came out black).
    // (A longer header's masks are used for 16 bits even without bit fields,
    // 5-5-5 where they are zero.)
    const uint64_t maskBytes = header == 40 && compression == 3 ? 12 : 0;
    if (compression == 3 || (bits == 16 && header > 40)) {
        if (got < 66)
            throw bad(fmt::format("the file ends at byte {}, inside its colour masks", got));
        const uint32_t r = u32(54), g = u32(58), b = u32(62);
        const bool known = bits == 16 ? (r == 0x7C00 && g == 0x03E0 && b == 0x001F) ||
                                            (r == 0xF800 && g == 0x07E0 && b == 0x001F) ||
                                            (compression == 0 && r == 0 && g == 0 && b == 0)
                                      : r == 0x00FF0000 && g == 0x0000FF00 && b == 0x000000FF;
        if (!known)
            throw bad(fmt::format(
                "colour masks {:#x}, {:#x}, {:#x} for {} bits a pixel, which OpenImageIO reads "
                "as {}",
                r, g, b, bits, bits == 16 ? "5-5-5 or 5-6-5 only" : "8-8-8 only"));
    }
    // (a palette beside true colour is allowed, for displays of 256 colours)
    if ((bits <= 8 && colours > (1u << bits)) || (bits > 8 && colours > 256))
        throw bad(fmt::format("a palette of {} colours for {} bits a pixel", colours, bits));
    const uint64_t palette = uint64_t(4) * (colours     ? colours
                                            : bits <= 8 ? uint32_t(1) << bits
                                                        : 0);
    if (data < 14 + header + maskBytes + palette || data > size)
        throw bad(fmt::format("its pixels at byte {}, outside the {}-byte file after its headers",
                              data, size));
    const uint64_t rowBytes = (uint64_t(width) * bits + 31) / 32 * 4;
    if (!rle && data + rowBytes * rows > size)
        throw bad(fmt::format(
            "{} x {} pixels of {} bits need {} bytes after byte {}, and the file has {}", width,
            rows, bits, rowBytes * rows, data, size - data));
}

/// The format of a photo, from its first bytes, among those a photo comes
/// in; InputError for any other.  OpenImageIO is then given only that
/// format's reader: its search for a reader tries every format on a file it
/// does not recognise, and some allocate what the file claims before any
/// check of ours can run (a 29-byte GIF claiming a 23170-pixel screen cost
/// 2.2 GB in that search alone).  A PNG's chunks, a JPEG's scans and a
/// BMP's headers (`maxPixels`: the most pixels read) are checked here.
std::string photoFormat(const std::string& path, uint64_t size, size_t maxPixels)
{
    std::ifstream in(path, std::ios::binary);
    char head[12] = {};
    in.read(head, sizeof head);
    const std::string h(head, size_t(in.gcount()));
    auto starts = [&](const char* magic, size_t n, size_t at = 0) {
        return h.size() >= at + n && h.compare(at, n, magic, n) == 0;
    };
    if (starts("\x89PNG\r\n\x1a\n", 8)) {
        checkPngChunks(path, size);
        return "png";
    }
    if (starts("\xFF\xD8\xFF", 3)) {
        checkJpegScans(path);
        return "jpeg";
    }
    if (starts("II*\0", 4) || starts("MM\0*", 4) || starts("II+\0", 4) || starts("MM\0+", 4))
        return "tiff";
    if (starts("\x76\x2f\x31\x01", 4))
        return "openexr";
    if (starts("#?RADIANCE", 10) || starts("#?RGBE", 6))
        return "hdr";
    if (starts("BM", 2)) {
        checkBmpHeader(path, size, maxPixels);
        return "bmp";
    }
    if (starts("RIFF", 4) && starts("WEBP", 4, 8))
        return "webp";
    std::string bytes;
    for (unsigned char ch : h.substr(0, 8))
        bytes += fmt::format("{}{:02x}", bytes.empty() ? "" : " ", ch);
    throw InputError(fmt::format(
        "{}: not a PNG, JPEG, TIFF, OpenEXR, Radiance HDR, BMP or WebP image (its first bytes "
        "are {}), the formats a photo is read from",
        path, bytes.empty() ? "none: it is empty" : bytes));
}

const ImageCodecApi* loadImageCodec()
{
    std::vector<std::string> places;
    if (const char* env = std::getenv("CAMBIUM_IMAGE_CODEC"))
        places.push_back(env);
    places.push_back(executableDirectory() + "/libcambium_oiio.so");
#ifdef CAMBIUM_IMAGE_CODEC_PATH
    places.push_back(CAMBIUM_IMAGE_CODEC_PATH);
#endif
    std::string tried;
    for (const std::string& place : places) {
        if (void* lib = ::dlopen(place.c_str(), RTLD_LAZY | RTLD_LOCAL)) {
            using Entry = const ImageCodecApi* (*)();
            auto entry = reinterpret_cast<Entry>(::dlsym(lib, "cambium_image_codec"));
            const ImageCodecApi* api = entry ? entry() : nullptr;
            if (api && api->abi == kImageCodecAbi)
                return api;
            tried += fmt::format("; {}: not cambium's image codec of this version", place);
        } else {
            tried += fmt::format("; {}", ::dlerror());
        }
    }
    throw std::runtime_error("cannot load the image codec (OpenImageIO)" + tried);
}

/// The one load, started by whichever call comes first (a failed load's
/// error comes back to every caller).
std::shared_future<const ImageCodecApi*> codecLoad()
{
    static std::mutex mutex;
    static std::shared_future<const ImageCodecApi*> load;
    const std::lock_guard<std::mutex> lock(mutex);
    if (!load.valid())
        load = std::async(std::launch::async, loadImageCodec).share();
    return load;
}

}  // namespace

const ImageCodecApi& imageCodec()
{
    return *codecLoad().get();
}

void preloadImageCodec()
{
    codecLoad();
}

Photo readPhoto(const std::string& path, size_t maxPixels, double room)
{
    const std::string format = photoFormat(path, checkInputFile(path, "photo"), maxPixels);
    // What the decode holds at its peak must fit in this process's room,
    // checked from the header before a pixel is held.
    if (room < 0.0)
        room = availableMemoryBytes();
    const size_t fit = size_t(std::min(double(maxPixels), room / kPhotoBytesPerPixel));
    CodecImage img;
    const std::string error = imageCodec().decode(path, format, fit, img);
    if (!error.empty()) {
        const double pixels = double(img.width) * double(img.height);
        if (pixels > double(fit) && pixels <= double(maxPixels))
            throw InputError(fmt::format(
                "{}: a photo of {} x {} pixels needs about {} of memory to decode, and this "
                "process has {} available: scale it down",
                path, img.width, img.height, formatBytes(pixels * kPhotoBytesPerPixel),
                formatBytes(room)));
        throw InputError(error);
    }
    // Float formats (EXR, HDR) hold linear values; the 8- and 16-bit ones
    // are sRGB-encoded unless they say they are linear.
    const std::string& space = img.colourSpace;
    auto lower = [](std::string t) {
        for (char& ch : t)
            ch = char(std::tolower(static_cast<unsigned char>(ch)));
        return t;
    };
    const bool linear = space.empty() ? img.floatFormat : lower(space).rfind("lin", 0) == 0;
    Photo out;
    out.width = img.width;
    out.height = img.height;
    const size_t n = size_t(img.width) * size_t(img.height), c = size_t(img.channels);
    out.rgb.resize(3 * n);
    for (size_t i = 0; i < n; ++i)
        for (size_t k = 0; k < 3; ++k) {
            const float v =
                img.pixels[c * i + (c >= 3 ? k : 0)];  // grey (and grey with alpha) made RGB
            // (beyond a half float's range a colour baked with --half is infinite)
            if (!(std::abs(v) <= float(kLargestHalf)))
                throw InputError(fmt::format(
                    "{}: pixel {} (row {}, column {}) has the value {:g}, not a colour (a finite "
                    "number of magnitude at most {:g})",
                    path, i, i / size_t(img.width), i % size_t(img.width), v, kLargestHalf));
            // A linear pixel a little below 0 is a colour transform's ringing,
            // taken as black; one far below is no colour (a normal or
            // displacement map given as a photo).
            if (linear && v < kDarkestLinearPixel)
                throw InputError(fmt::format(
                    "{}: pixel {} (row {}, column {}) has the value {:g}, not a colour (a linear "
                    "photo's values are at least {:g}: is it a normal or displacement map?)",
                    path, i, i / size_t(img.width), i % size_t(img.width), v, kDarkestLinearPixel));
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
    const size_t n = size_t(img.width) * size_t(img.height);
    CodecImage c;
    c.width = img.width;
    c.height = img.height;
    if (ext == "png") {
        c.channels = 4;
        c.eightBit = true;
        c.colourSpace = "sRGB";
        c.pixels.resize(4 * n);
        for (size_t i = 0; i < n; ++i) {
            for (int k = 0; k < 3; ++k)
                c.pixels[4 * i + size_t(k)] = toSrgb(img.rgb[3 * i + size_t(k)]);
            c.pixels[4 * i + 3] = 1.0f;  // the background is drawn: opaque
        }
    } else {
        c.channels = 8;
        c.channelNames = {"R", "G", "B", "A", "Z", "N.x", "N.y", "N.z"};
        c.alphaChannel = 3;
        c.zChannel = 4;
        c.pixels.resize(8 * n);
        for (size_t i = 0; i < n; ++i) {
            for (int k = 0; k < 3; ++k) {
                c.pixels[8 * i + size_t(k)] = img.rgb[3 * i + size_t(k)];
                c.pixels[8 * i + 5 + size_t(k)] = img.normal[3 * i + size_t(k)];
            }
            c.pixels[8 * i + 3] = img.alpha[i];
            c.pixels[8 * i + 4] = img.depth[i];
        }
    }
    std::vector<unsigned char> bytes;
    const std::string error = imageCodec().encode(path, c, bytes);
    if (!error.empty())
        throw std::runtime_error(error);
    writeFile(path, bytes.data(), bytes.size());
}

}  // namespace cambium
