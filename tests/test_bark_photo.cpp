// Bark colour from a photograph (paper 002, section 3.5): photos read in any
// format, the histogram's draws, and the baked bark's colours against the
// photo's histogram (chi-square), random and coherent.
#include "bake/bake.h"
#include "bake/bark_photo.h"
#include "bake/levelset.h"
#include "bake/sequence.h"
#include "bake/sampler.h"
#include "core/error.h"
#include "io/image_file.h"
#include "io/vdb.h"
#include "model/tree_builder.h"
#include "test_util.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <tuple>

namespace {

using namespace cambium;
using namespace cambium::test;

/// Four bark colours (linear) and their shares of the generated photos.
const glm::dvec3 kColours[4] = {
    {0.05, 0.04, 0.03}, {0.15, 0.12, 0.09}, {0.30, 0.25, 0.20}, {0.55, 0.50, 0.42}};
const double kShares[4] = {0.4, 0.3, 0.2, 0.1};

double srgb(double v)
{
    return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

/// Writes a photo of the four colours in their shares (stripes, shuffled
/// rows) as `format` ("uint8" PNG, "uint16" TIFF, "float" EXR, "grey" PNG).
std::string writePhoto(const std::string& dir, const std::string& format)
{
    const int w = 64, hgt = 50;  // 3,200 pixels: 1,280, 960, 640, 320
    const bool grey = format == "grey";
    const int channels = grey ? 1 : 3;
    std::vector<float> px;
    for (int y = 0; y < hgt; ++y)
        for (int x = 0; x < w; ++x) {
            const int i = (y * w + x) * 7919 % (w * hgt);  // scattered
            const int c = i < 1280 ? 0 : i < 2240 ? 1 : i < 2880 ? 2 : 3;
            for (int k = 0; k < channels; ++k) {
                const double v = grey ? kColours[c].g : kColours[c][k];
                px.push_back(float(format == "float" ? v : srgb(v)));
            }
        }
    const std::string ext = format == "float" ? "exr" : format == "uint16" ? "tif" : "png";
    const std::string path = dir + "/photo_" + format + "." + ext;
    auto out = OIIO::ImageOutput::create(path);
    const OIIO::TypeDesc type = format == "float"    ? OIIO::TypeDesc::FLOAT
                                : format == "uint16" ? OIIO::TypeDesc::UINT16
                                                     : OIIO::TypeDesc::UINT8;
    OIIO::ImageSpec spec(w, hgt, channels, type);
    EXPECT_TRUE(out->open(path, spec));
    EXPECT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
    out->close();
    return path;
}

/// A directory of the running test's own: ctest runs the tests as processes
/// side by side, and two writing photo_float.exr in one directory read each
/// other's half-written file ("not an OpenEXR file", once in CI).
std::string tempDir()
{
    const std::string dir = ::testing::TempDir() + "/bark_photo_" +
                            ::testing::UnitTest::GetInstance()->current_test_info()->name();
    std::filesystem::create_directories(dir);
    return dir;
}

/// Chi-square of observed counts against expected shares.
double chiSquare(const std::vector<double>& observed, const double* shares)
{
    double n = 0.0, chi = 0.0;
    for (double o : observed)
        n += o;
    for (size_t k = 0; k < observed.size(); ++k) {
        const double e = n * shares[k];
        chi += (observed[k] - e) * (observed[k] - e) / e;
    }
    return chi;
}

/// The 0.001 critical value of chi-square with 3 degrees of freedom.
constexpr double kChi3At001 = 16.27;

}  // namespace

TEST(BarkPhoto, EveryFormatGivesTheSameHistogram)
{
    const std::string dir = tempDir();
    for (const char* format : {"uint8", "uint16", "float"}) {
        SCOPED_TRACE(format);
        const ColourHistogram h = ColourHistogram::fromPhoto(writePhoto(dir, format));
        ASSERT_EQ(h.bins(), 4u);
        for (int c = 0; c < 4; ++c) {
            // In order of luminance, the generated shares; colours linear.
            EXPECT_NEAR(h.share(size_t(c)), kShares[c], 1e-12);
            EXPECT_NEAR(glm::length(h.colour(size_t(c)) - kColours[c]), 0.0,
                        std::string(format) == "uint8" ? 8e-3 : 1e-4);
        }
        // The inverse CDF: u below 0.4 is the first colour, and so on.
        EXPECT_EQ(h.bin(0.0), 0u);
        EXPECT_EQ(h.bin(0.399), 0u);
        EXPECT_EQ(h.bin(0.401), 1u);
        EXPECT_EQ(h.bin(0.95), 3u);
    }
    // Grey: one channel made RGB.
    const ColourHistogram g = ColourHistogram::fromPhoto(writePhoto(dir, "grey"));
    ASSERT_EQ(g.bins(), 4u);
    for (int c = 0; c < 4; ++c)
        EXPECT_NEAR(g.colour(size_t(c)).r, kColours[c].g, 4e-3);
    // A missing or unreadable photo is named.
    expectInputError([&] { ColourHistogram::fromPhoto(dir + "/none.png"); }, "none.png", "missing");
    std::ofstream(dir + "/text.png") << "not an image";
    expectInputError([&] { ColourHistogram::fromPhoto(dir + "/text.png"); }, "text.png",
                     "unreadable");
    // A 536-byte PNG whose tEXt chunk says 2 GB (a fuzzer's find: libpng
    // allocated and cleared all of it before reading) is refused by the
    // chunk's name and place, before the decoder sees it.
    const std::string bomb =
        CAMBIUM_SOURCE_DIR "/tests/fuzz/regressions/photo/png-text-chunk-of-2gb";
    expectInputError([&] { ColourHistogram::fromPhoto(bomb); },
                     "a truncated or damaged PNG: its chunk tEXt at byte 159 says 2113929327 "
                     "bytes of data, and the file ends 369 bytes after",
                     "a chunk longer than the file");
}

TEST(BarkPhoto, TheBarksColoursFollowThePhotosHistogram)
{
    openvdb::initialize();
    const std::string dir = tempDir();
    const ColourHistogram photo = ColourHistogram::fromPhoto(writePhoto(dir, "float"));
    // A bent branch of three internodes with bark coordinates.
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 0.6, 0}, 0.12, 0.11, 6),
                     internode(1, 0, {0, 0.6, 0}, {0.05, 1.2, 0}, 0.11, 0.1, 5),
                     internode(2, 1, {0.05, 1.2, 0}, {0.15, 1.8, 0}, 0.1, 0.09, 4)};
    TreeBuildOptions o;
    const BlobTree tree = buildTree(sk, o);
    const FieldProgram prog = FieldProgram::compile(tree);
    auto sampler = makeCpuSampler();
    BakeOptions opt;
    opt.voxelSize = 0.004;
    const BakedGrids base = bakeLevelSet(prog, *sampler, opt);
    for (BarkColouring mode : {BarkColouring::Random, BarkColouring::Coherent}) {
        const bool coherent = mode == BarkColouring::Coherent;
        SCOPED_TRACE(coherent ? "coherent" : "random");
        BakedGrids g;
        g.surface = base.surface;
        g.color = base.color->deepCopy();
        const size_t n = colourBarkFromPhoto(g, tree, photo, mode, o.bark);
        ASSERT_GT(n, 10000u);
        // The surface voxels' colours: each one of the photo's, counted.
        // Coherent colours come in patches: count voxels far enough apart to
        // be independent.
        std::vector<double> counts(4, 0.0);
        const auto phi = g.surface->getConstAccessor();
        std::map<openvdb::Coord, int> index;  // voxel -> colour, for the correlation
        std::set<openvdb::Coord> sampled;     // coherent: the cells counted
        for (auto v = g.color->cbeginValueOn(); v; ++v) {
            const openvdb::Coord c = v.getCoord();
            if (std::fabs(phi.getValue(c)) > 0.5 * opt.voxelSize)
                continue;
            const openvdb::Vec3f cv = *v;
            const size_t bin = photo.binOf(glm::dvec3(cv[0], cv[1], cv[2]));
            ASSERT_LT(bin, 4u) << "a colour the photo does not have";
            index[c] = int(bin);
            if (!coherent) {
                counts[bin] += 1.0;
            } else {
                // One voxel of each cell of 12^3 (4.8 cm, beyond the
                // correlation length): the first met.
                const openvdb::Coord cell(c.x() < 0 ? (c.x() - 11) / 12 : c.x() / 12,
                                          c.y() < 0 ? (c.y() - 11) / 12 : c.y() / 12,
                                          c.z() < 0 ? (c.z() - 11) / 12 : c.z() / 12);
                if (sampled.insert(cell).second)
                    counts[bin] += 1.0;
            }
        }
        double total = 0.0;
        for (double c : counts)
            total += c;
        const double chi = chiSquare(counts, kShares);
        report(
            "{}: {} surface voxels counted, shares {:.3f} {:.3f} {:.3f} {:.3f} (photo 0.4 0.3 "
            "0.2 0.1), chi-square {:.2f} (0.001 critical value {})",
            coherent ? "coherent" : "random", total, counts[0] / total, counts[1] / total,
            counts[2] / total, counts[3] / total, chi, kChi3At001);
        EXPECT_GT(total, 300.0);
        EXPECT_LT(chi, kChi3At001);
        // Spatial correlation of the colour index along x between surface
        // voxels: its length (where it falls below 1/e).
        auto correlationAt = [&](int lag) {
            double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0, m = 0;
            for (const auto& [c, a] : index) {
                const auto it = index.find(c.offsetBy(lag, 0, 0));
                if (it == index.end())
                    continue;
                const double b = it->second;
                sa += a, sb += b, saa += a * a, sbb += b * b, sab += a * b, m += 1;
            }
            const double cov = sab / m - sa / m * sb / m;
            return cov / std::sqrt((saa / m - sa / m * sa / m) * (sbb / m - sb / m * sb / m));
        };
        int length = 0;
        while (length < 40 && correlationAt(length + 1) > std::exp(-1.0))
            ++length;
        report("{}: correlation length {} voxels ({:.3f} m); neighbours agree {:.2f}",
               coherent ? "coherent" : "random", length, length * opt.voxelSize, correlationAt(1));
        if (coherent) {
            EXPECT_GE(length, 2);
            EXPECT_LT(length, 12);
        } else {
            EXPECT_EQ(length, 0);
        }
    }
}

/// The bytes of `hex` (pairs of hex digits, spaces ignored).
std::string fromHex(const std::string& hex)
{
    std::string bytes, digits;
    for (char c : hex)
        if (c != ' ')
            digits += c;
    for (size_t i = 0; i + 1 < digits.size(); i += 2)
        bytes.push_back(char(std::stoi(digits.substr(i, 2), nullptr, 16)));
    return bytes;
}

TEST(BarkPhoto, PhotosThatLieAreRefusedFromTheirBytesBeforeTheyCost)
{
    const std::string dir = tempDir();
    auto write = [&](const std::string& name, const std::string& bytes) {
        std::ofstream(dir + "/" + name, std::ios::binary) << bytes;
        return dir + "/" + name;
    };
    auto refused = [&](const std::string& name, const std::string& bytes,
                       const std::string& message) {
        const std::string path = write(name, bytes);
        expectInputError([&] { readPhoto(path); }, path + ": " + message, name);
    };
    // A 29-byte GIF claiming a 23170-pixel screen: OpenImageIO's search for
    // a reader cost 2.2 GB on it.  Only a photo's formats are handed over.
    refused("screen.gif",
            fromHex("474946383961 825a 825a 000000 2c 0000 0000 0100 0100 00 02024401 00 3b"),
            "not a PNG, JPEG, TIFF, OpenEXR, Radiance HDR, BMP or WebP image (its first bytes "
            "are 47 49 46 38 39 61 82 5a)");
    refused("empty.png", "",
            "not a PNG, JPEG, TIFF, OpenEXR, Radiance HDR, BMP or WebP image (its first bytes are "
            "none: it is empty)");
    // A 150-byte 16 x 16 grey TIFF of 65536 x 65536 tiles (8.9 GB decoded).
    refused(
        "tiles.tif",
        fromHex("49492a00080000000a00000104000100000010000000010104000100000010000000020103000100"
                "00000800000003010300010000000100000006010300010000000100000015010300010000000100"
                "00004201040001000000000001004301040001000000000001004401040001000000860000004501"
                "0400010000001000000000000000") +
            std::string(16, '\0'),
        "its header says tiles of 65536 x 65536 pixels for a picture of 16 x 16");
    // BMPs: OpenImageIO 2.4 reads a header of a size it does not know as
    // read, every field uninitialised (a 21-byte find of the photo fuzzer
    // was decoded with a channel count from the heap), sizes a palette from
    // its header and unpacks an RLE picture in open().
    // (`masks`: the bytes after a 40-byte header, before any palette)
    auto bmp = [](uint32_t header, int32_t width, int32_t height, uint16_t bits,
                  uint32_t compression, uint32_t colours, uint32_t pixelBytes,
                  const std::string& masks = "") {
        std::string b = "BM";
        auto put = [&](uint64_t v, int n) {
            for (int i = 0; i < n; ++i)
                b.push_back(char(v >> (8 * i) & 0xff));
        };
        const uint32_t palette = 4 * (colours     ? std::min(colours, 256u)
                                      : bits <= 8 ? 1u << bits
                                                  : 0);
        const uint32_t data = 14 + header + uint32_t(masks.size()) + palette;
        put(data + pixelBytes, 4);
        put(0, 4);
        put(data, 4);
        put(header, 4);
        put(uint32_t(width), 4);
        put(uint32_t(height), 4);
        put(1, 2);
        put(bits, 2);
        put(compression, 4);
        put(pixelBytes, 4);
        put(0, 8);
        put(colours, 4);
        put(0, 4);
        b += std::string(header - 40, '\0') + masks + std::string(palette + pixelBytes, '\x7f');
        return b;
    };
    refused("header.bmp", fromHex("424d 76020000 00210000 36000300 8880ffff 0000 00"),
            "a damaged or unusual BMP: a header of 4294934664 bytes, where a BMP's is 40, 108 or "
            "124; re-save it");
    refused("os2.bmp", bmp(40, 4, 2, 24, 0, 0, 24).replace(14, 1, "\x0c"),
            "a damaged or unusual BMP: an OS/2 1.x header (12 bytes), which OpenImageIO reads "
            "wrong; re-save it");
    refused("rle.bmp", bmp(40, 60000, 60000, 8, 1, 2, 2),
            "its header says 60000 x 60000 pixels, more than the 50 million pixels read");
    refused("palette.bmp", bmp(40, 4, 2, 8, 0, 0x7fffffff, 16),
            "a damaged or unusual BMP: a palette of 2147483647 colours for 8 bits a pixel");
    refused("depth.bmp", bmp(40, 4, 2, 7, 0, 0, 16),
            "a damaged or unusual BMP: 7 bits a pixel, where a BMP has 1, 4, 8, 16, 24 or 32");
    // Colour masks OpenImageIO 2.4 would read otherwise than they say.
    refused("masks.bmp", bmp(40, 4, 2, 16, 3, 0, 16, fromHex("00f80000 e0070000 ff000000")),
            "a damaged or unusual BMP: colour masks 0xf800, 0x7e0, 0xff for 16 bits a pixel, "
            "which OpenImageIO reads as 5-5-5 or 5-6-5 only");
    refused("masks32.bmp", bmp(40, 4, 2, 32, 3, 0, 32, fromHex("000000ff 0000ff00 00ff0000")),
            "a damaged or unusual BMP: colour masks 0xff000000, 0xff0000, 0xff00 for 32 bits a "
            "pixel, which OpenImageIO reads as 8-8-8 only");
    refused("masks108.bmp", bmp(108, 4, 2, 16, 0, 0, 16).replace(54, 4, fromHex("ffffffff")),
            "a damaged or unusual BMP: colour masks 0xffffffff, 0x0, 0x0 for 16 bits a pixel");
    refused("palette24.bmp", bmp(40, 4, 2, 24, 0, 257, 24),
            "a damaged or unusual BMP: a palette of 257 colours for 24 bits a pixel");
    refused("cut.bmp", bmp(40, 4, 2, 24, 0, 0, 20),
            "a damaged or unusual BMP: 4 x 2 pixels of 24 bits need 24 bytes after byte 54, and "
            "the file has 20");
    // What passes is read: 24-bit, and an 8-bit RLE picture with a V5 header.
    {
        const std::string path = write("whole.bmp", bmp(40, 4, 2, 24, 0, 0, 24));
        const Photo p = readPhoto(path);
        EXPECT_EQ(p.width, 4);
        EXPECT_EQ(p.height, 2);
        EXPECT_NEAR(p.rgb[0], std::pow((127.0 / 255.0 + 0.055) / 1.055, 2.4), 1e-6);
        std::string rle = bmp(124, 4, 2, 8, 1, 2, 8);
        // A palette of black and white; rows of 4 white, then 4 black.
        rle.replace(14 + 124, 8, fromHex("00000000 ffffff00"));
        rle.replace(14 + 124 + 8, 8, fromHex("0401 0000 0400 0001"));
        const Photo q = readPhoto(write("rle.bmp", rle));
        ASSERT_EQ(q.rgb.size(), 24u);
        EXPECT_EQ(q.rgb[0], 0.0f);   // the top row: the file's second
        EXPECT_EQ(q.rgb[12], 1.0f);  // the bottom row: the first
        // 16 bits: 5-5-5 after a 40-byte header (no masks), 5-6-5 by its
        // masks; 24 bits with a palette beside (for 256-colour displays).
        std::string rgb555 = bmp(40, 2, 1, 16, 0, 0, 4);
        rgb555.replace(54, 4, fromHex("007c 007c"));
        std::string rgb565 = bmp(40, 2, 1, 16, 3, 0, 4, fromHex("00f80000 e0070000 1f000000"));
        rgb565.replace(66, 4, fromHex("e007 e007"));
        std::string palette24 = bmp(40, 4, 2, 24, 0, 4, 24);
        for (const auto& [name, bytes, colour] :
             {std::tuple{"rgb555.bmp", rgb555, glm::vec3(1.0f, 0.0f, 0.0f)},
              std::tuple{"rgb565.bmp", rgb565, glm::vec3(0.0f, 1.0f, 0.0f)},
              std::tuple{"palette24.bmp", palette24, glm::vec3(127.0f / 255.0f)}}) {
            const Photo r = readPhoto(write(name, bytes));
            ASSERT_GE(r.rgb.size(), 3u) << name;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(r.rgb[size_t(c)],
                            colour[c] <= 0.04045f ? colour[c] / 12.92f
                                                  : std::pow((colour[c] + 0.055f) / 1.055f, 2.4f),
                            1e-5)
                    << name << c;
        }
    }
    // 501 scans (each a pass over the picture; thousands are minutes).
    std::string scans = fromHex("ffd8");
    for (int i = 0; i < 501; ++i)
        scans += fromHex("ffda 0008 01 0100 003f00 1234");
    refused("scans.jpg", scans + fromHex("ffd9"), "a JPEG of more than 500 scans");
    // A real JPEG's scans pass the walk and are read.
    {
        const std::string path = dir + "/real.jpg";
        auto out = OIIO::ImageOutput::create(path);
        OIIO::ImageSpec spec(40, 30, 3, OIIO::TypeDesc::UINT8);
        spec.attribute("jpeg:progressive", 1);
        std::vector<float> px(40 * 30 * 3, 0.5f);
        ASSERT_TRUE(out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        out->close();
        const Photo p = readPhoto(path);
        EXPECT_EQ(p.width, 40);
        EXPECT_NEAR(p.rgb[0], 0.214, 0.01);  // sRGB 0.5, linear
    }
    // A TIFF cut inside its strips: its reader reports the damage and still
    // said success, and the histogram came from zeros.
    const std::string tif = writePhoto(dir, "uint16");
    std::ifstream in(tif, std::ios::binary);
    const std::string whole((std::istreambuf_iterator<char>(in)), {});
    refused("cut.tif", whole.substr(0, whole.size() * 6 / 10), "cannot read the tiff image: ");
    // A linear pixel beyond a half float's range (baked with --half: inf),
    // and one far below black (a normal map: it was taken as black); a
    // transform's ringing just below 0 is black.
    auto exr = [&](const char* name, float value) {
        const std::string path = dir + "/" + name;
        auto out = OIIO::ImageOutput::create(path);
        OIIO::ImageSpec spec(4, 2, 3, OIIO::TypeDesc::FLOAT);
        std::vector<float> px(4 * 2 * 3, 0.5f);
        px[3 * 6 + 1] = value;
        EXPECT_TRUE(out->open(path, spec) && out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
        out->close();
        return path;
    };
    expectInputError([&] { readPhoto(exr("bright.exr", 3e38f)); },
                     "bright.exr: pixel 6 (row 1, column 2) has the value 3e+38, not a colour",
                     "a pixel beyond half");
    expectInputError([&] { readPhoto(exr("normals.exr", -0.7f)); },
                     "normals.exr: pixel 6 (row 1, column 2) has the value -0.7, not a colour (a "
                     "linear photo's values are at least -0.01",
                     "a pixel far below black");
    EXPECT_EQ(readPhoto(exr("ringing.exr", -0.004f)).rgb[3 * 6 + 1], 0.0f);
}

TEST(BarkPhoto, APhotoThatWouldNotFitInMemoryIsRefusedFromItsHeader)
{
    // A 3000 x 3000 grey PNG (9 M pixels, under the 50 M cap, a few KB)
    // decodes into about 290 MB: with 100 MB of room (the room itself is
    // System's test) it is refused from its header with the numbers.  It
    // was decoded: a 36 M pixel one ran out of memory or into swap.
    const std::string dir = ::testing::TempDir() + "/cambium_photo_room";
    std::filesystem::create_directories(dir);
    const std::string path = dir + "/big.png";
    {
        auto out = OIIO::ImageOutput::create(path);
        OIIO::ImageSpec spec(3000, 3000, 1, OIIO::TypeDesc::UINT8);
        std::vector<uint8_t> px(3000u * 3000u, 128);
        ASSERT_TRUE(out->open(path, spec) && out->write_image(OIIO::TypeDesc::UINT8, px.data()));
        out->close();
    }
    expectInputError([&] { readPhoto(path, kMaxPhotoPixels, 100e6); },
                     "big.png: a photo of 3000 x 3000 pixels needs about 288 MB of memory to "
                     "decode, and this process has 100 MB available",
                     "a photo beyond the room");
    // With the room it needs, it is read.
    EXPECT_EQ(readPhoto(path, kMaxPhotoPixels, 300e6).width, 3000);
    std::filesystem::remove_all(dir);
}

TEST(BarkPhoto, ABakeRefusesAMissingPhotoBeforeWork)
{
    const std::string dir = tempDir();
    BakeRequest req;
    req.input = CAMBIUM_SOURCE_DIR "/examples/populus/populus.json";
    req.output = dir + "/never.vdb";
    req.voxelSize = 0.05;
    req.barkPhoto = dir + "/missing.jpg";
    expectInputError([&] { runBake(req); }, "missing.jpg", "missing photo");
    EXPECT_FALSE(std::filesystem::exists(req.output));
}

TEST(BarkPhoto, ASceneFileNamesItsPhotoAndTheColourItReplaces)
{
    openvdb::initialize();
    const std::string dir = tempDir();
    const std::string photo = writePhoto(dir, "uint16");
    std::ofstream(dir + "/branch.json")
        << R"({"bark": {"photo": ")" + std::filesystem::path(photo).filename().string() +
               R"(", "color": [0.5, 0.4, 0.3], "colouring": "random"},
        "root": {"type": "cone", "p0": [0, 0, 0], "p1": [0, 1, 0], "r0": 0.1, "r1": 0.08,
                 "color": [0.5, 0.4, 0.3]}})";
    BakeRequest req;
    req.input = dir + "/branch.json";
    req.output = dir + "/branch.vdb";
    req.voxelSize = 0.01;
    req.device = Device::Cpu;
    runBake(req);
    const ColourHistogram h = ColourHistogram::fromPhoto(photo);
    const LevelSetGrids g = readLevelSet(req.output);
    const auto phi = g.surface->getConstAccessor();
    size_t surface = 0;
    for (auto v = g.color->cbeginValueOn(); v; ++v)
        if (std::fabs(phi.getValue(v.getCoord())) < 0.005) {
            ++surface;
            ASSERT_LT(h.binOf(glm::dvec3((*v)[0], (*v)[1], (*v)[2])), h.bins());
        }
    EXPECT_GT(surface, 1000u);
    // Without its colour the scene is refused, named.
    std::ofstream(dir + "/nocolour.json") << R"({"bark": {"photo": "photo_uint16.tif"},
        "root": {"type": "sphere", "center": [0, 0, 0], "radius": 1}})";
    req.input = dir + "/nocolour.json";
    expectInputError([&] { runBake(req); }, "bark.color: missing", "no colour");
    // A colouring that is neither, in a scene file and in a species file,
    // is refused with its path, as is a species file's missing photo.
    req.output = dir + "/never.vdb";
    std::ofstream(dir + "/sideways.json")
        << R"({"bark": {"photo": "photo_uint16.tif", "color": [0.5, 0.4, 0.3],
                        "colouring": "sideways"},
        "root": {"type": "sphere", "center": [0, 0, 0], "radius": 1}})";
    req.input = dir + "/sideways.json";
    expectInputError([&] { runBake(req); },
                     R"(bark.colouring: must be "coherent" or "random" (got 'sideways'))",
                     "scene colouring");
    nlohmann::json species = nlohmann::json::parse(
        readTextFile(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json", "species"));
    species["bark"]["colouring"] = "sideways";
    std::ofstream(dir + "/species.json") << species.dump();
    req.input = dir + "/species.json";
    expectInputError([&] { runBake(req); },
                     R"(bark.colouring: must be "coherent" or "random" (got 'sideways'))",
                     "species colouring");
    species["bark"]["colouring"] = "random";
    species["bark"]["photo"] = "no_such_photo.jpg";
    std::ofstream(dir + "/species.json") << species.dump();
    expectInputError([&] { runBake(req); }, "bark.photo", "species photo");
    EXPECT_FALSE(std::filesystem::exists(req.output));
}

TEST(BarkPhoto, ResumeDoesNotKeepFramesMadeFromAnotherPhoto)
{
    // A sequence's key holds its photo's bytes, not only its name: frames
    // of the same photo are kept, a repainted photo under the same name
    // makes the old frames another bake's.
    openvdb::initialize();
    const std::string dir = tempDir() + "/resume";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const std::string photo = writePhoto(dir, "uint8");
    SequenceRequest r;
    r.bake.input = CAMBIUM_SOURCE_DIR "/examples/populus/populus.json";
    r.bake.output = dir + "/s.##.vdb";
    r.bake.voxelSize = 0.05;
    r.bake.device = Device::Cpu;
    r.bake.barkPhoto = photo;
    r.frames = "2-3";
    r.fpsPerYear = 1.0;
    bakeSequence(r);
    r.resume = true;
    for (const FrameReport& f : bakeSequence(r).frames)
        EXPECT_EQ(f.outcome, FrameReport::Outcome::Skipped) << f.frame;
    std::filesystem::copy_file(writePhoto(dir, "grey"), photo,
                               std::filesystem::copy_options::overwrite_existing);
    expectInputError([&] { bakeSequence(r); }, "s.02.vdb exists from another bake",
                     "a repainted photo");
}
