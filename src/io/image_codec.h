// cambium — image files' pixels through OpenImageIO, loaded on first use.
// OpenImageIO brings some 240 shared libraries (codecs, GDAL, OpenCV,
// FFmpeg): linked into cambium they cost every command 0.4 s and 130 MB
// before main, and a cold first start far more.  So it lives in a plugin,
// libcambium_oiio.so (src/io/oiio_codec.cpp), which only the commands that
// read or write an image load.
#pragma once

#include <string>
#include <vector>

namespace cambium {

/// Pixels as float channels, interleaved, rows top to bottom.
struct CodecImage {
    int width = 0, height = 0, channels = 0;
    std::vector<float> pixels;
    /// Encoding: channel names (empty: the format's), the alpha and depth
    /// channels (-1: none), 8 bits per channel (else float).
    std::vector<std::string> channelNames;
    int alphaChannel = -1, zChannel = -1;
    bool eightBit = false;
    /// Decoding: the file's colour space (oiio:ColorSpace, may be empty) and
    /// whether it stores floating-point values.  Encoding: the colour space
    /// to record (empty: none).
    std::string colourSpace;
    bool floatFormat = false;
};

/// The plugin's entry points.  Errors come back as messages (exceptions do
/// not cross the plugin's boundary): an empty string is success.
struct ImageCodecApi {
    int abi;
    /// Reads `path` with OpenImageIO's reader of `format` (its name: "png",
    /// "jpeg", ...) and no other; refuses, from its header, before any pixel
    /// is read or held, an image of more than `maxPixels` pixels or of tiles
    /// far larger than it.  The message names the file; `out`'s width and
    /// height are the header's once it was read, refused or not.
    std::string (*decode)(const std::string& path, const std::string& format, size_t maxPixels,
                          CodecImage& out);
    /// Encodes `image` into `bytes` in the format of `path`'s extension.
    std::string (*encode)(const std::string& path, const CodecImage& image,
                          std::vector<unsigned char>& bytes);
};

constexpr int kImageCodecAbi = 3;

/// The plugin, loaded on the first call: from $CAMBIUM_IMAGE_CODEC, else
/// beside the executable, else where the build put it.  std::runtime_error
/// naming the places tried when none loads.
const ImageCodecApi& imageCodec();

/// Starts loading the plugin on a thread of its own (0.2-0.3 s and some
/// 120 MB of libraries' pages), for a command that will write an image once
/// its other work is done; imageCodec() then waits for that load.
void preloadImageCodec();

}  // namespace cambium

/// The plugin's one exported symbol.
extern "C" const cambium::ImageCodecApi* cambium_image_codec();
