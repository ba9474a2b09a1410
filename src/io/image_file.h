// cambium — rendered images and their files: PNG for people, EXR with depth
// and normals for tools.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace cambium {

/// A rendered image: rows top to bottom.
struct RenderImage {
    int width = 0, height = 0;
    std::vector<float> rgb;    ///< linear colour, 3 per pixel
    std::vector<float> alpha;  ///< fraction of a pixel's samples that hit the surface
    std::vector<float>
        depth;  ///< distance to the hit along the pixel's central ray, +inf where it misses
    std::vector<float> normal;  ///< unit normal at that hit, 3 per pixel (0 where it misses)
};

/// Writes an image by the extension of `path`: .png (8-bit sRGB with alpha,
/// for people) or .exr (float R G B A, Z, N.x N.y N.z, for tools), through a
/// temporary file.  InputError for another extension.
void writeImage(const RenderImage& image, const std::string& path);

/// Throws InputError, before any work, when `path` is not a .png or .exr
/// file that can be written.
void checkImageOutput(const std::string& path);

/// A photograph's pixels as linear RGB (rows top to bottom).
struct Photo {
    int width = 0, height = 0;
    std::vector<float> rgb;  ///< 3 per pixel, linear
};

/// Reads a photo in the formats photos come in (PNG, JPEG, TIFF, OpenEXR,
/// Radiance HDR, BMP, WebP: known by their first bytes; 8, 16 or
/// 32 bits, grey or colour, with or without alpha: alpha ignored, grey made
/// RGB), as linear colour: files that store sRGB-encoded values (what
/// OpenImageIO's colour space or the format says) are decoded.  InputError
/// naming the file when it is missing, unreadable or empty.
/// Far more than a bark photo needs (8192 x 6144), and at most 7 floats a
/// pixel held (at most 4 decoded channels, then RGB): 1.4 GB.  Counted in
/// pixels from the header, so a grey or a lying file is no bomb.
constexpr size_t kMaxPhotoPixels = 50'000'000;
/// A photo's bytes a pixel at the decode's peak: 4 decoded float channels,
/// 3 linear ones and the reader's native row buffers.  A photo whose header
/// needs more than this process has room for is refused before decoding.
constexpr double kPhotoBytesPerPixel = 32.0;
/// `room`: the bytes the decode may take (negative: this process's room,
/// availableMemoryBytes()).
Photo readPhoto(const std::string& path, size_t maxPixels = kMaxPhotoPixels, double room = -1.0);

}  // namespace cambium
