// Ray marching a level set: hits on an analytic sphere level set within 0.1
// voxel of the exact ray-sphere intersection, the right pixels hit and miss,
// a default camera that frames the bounds, images that read back.
#include "use/mesh.h"
#include "use/render.h"

#include "bake_util.h"
#include "core/error.h"
#include "test_util.h"

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <cmath>
#include <filesystem>

namespace {

using namespace cambium;

/// Distance along a unit ray to a sphere, or -1.
double raySphere(const glm::dvec3& o, const glm::dvec3& d, const glm::dvec3& c, double r)
{
    const glm::dvec3 oc = o - c;
    const double b = glm::dot(oc, d), q = glm::dot(oc, oc) - r * r, disc = b * b - q;
    if (disc < 0.0)
        return -1.0;
    const double t = -b - std::sqrt(disc);
    return t > 0.0 ? t : -1.0;
}

TEST(Render, MarchHitsAnAnalyticSphereWhereTheRayDoes)
{
    const double r = 0.8, h = 0.02;
    const glm::dvec3 c(0.1, -0.05, 0.2);
    auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(float(r), openvdb::Vec3f(float(c.x), float(c.y), float(c.z)),
                                                                        float(h), 3.0f);
    Camera cam;
    cam.eye = c + glm::dvec3(0.7, 0.9, 3.2);
    cam.target = c;
    const int W = 160, H = 120;
    const RenderImage img = renderLevelSetCpu(*grid, nullptr, cam, W, H, 1);
    size_t hits = 0, checked = 0;
    double worst = 0.0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            glm::dvec3 o, d;
            cameraRay(cam, W, H, x + 0.5, y + 0.5, o, d);
            const size_t i = size_t(y) * W + size_t(x);
            // How far the ray passes from the centre, in voxels beyond the radius.
            const double miss = (glm::length(glm::cross(c - o, d)) - r) / h;
            const bool hit = std::isfinite(img.depth[i]);
            if (miss < -1.0) {
                ASSERT_TRUE(hit) << "pixel " << x << "," << y;
            }
            if (miss > 1.0) {
                ASSERT_FALSE(hit) << "pixel " << x << "," << y;
            }
            if (!hit)
                continue;
            ++hits;
            const double t = raySphere(o, d, c, r);
            if (t < 0.0 || miss > -1.0)
                continue;  // grazing rays: the intersection is ill-conditioned
            ++checked;
            worst = std::max(worst, std::abs(double(img.depth[i]) - t) / h);
            const glm::dvec3 p = o + t * d, n = glm::normalize(p - c);
            ASSERT_GT(n.x * img.normal[3 * i] + n.y * img.normal[3 * i + 1] + n.z * img.normal[3 * i + 2], 0.99);
        }
    EXPECT_GT(checked, 1000u);
    std::printf("analytic sphere: largest |t - exact| %.4f voxel over %zu pixels\n", worst, checked);
    EXPECT_LT(worst, 0.1) << "largest |t - exact| in voxels over " << checked << " pixels";
    EXPECT_GT(hits, checked);
}

/// The level-set march and Embree on the level set's mesh, from the framing view.
void expectMarchAgreesWithEmbree(const BlobTree& tree, double h, const char* what)
{
    const BakedGrids g = test::bakeTree(tree, h);
    const Camera cam = framingCamera(activeWorldBounds(*g.surface), 4.0 / 3.0, 35.0, 20.0);
    const int W = 200, H = 150;
    const RenderImage march = renderLevelSetCpu(*g.surface, nullptr, cam, W, H, 1);
    const RenderImage embree = renderMeshEmbree(meshLevelSet(*g.surface), cam, W, H, 1);
    size_t both = 0, close = 0, differ = 0;
    double worst = 0.0;
    for (size_t i = 0; i < size_t(W * H); ++i) {
        const bool a = std::isfinite(march.depth[i]), b = std::isfinite(embree.depth[i]);
        differ += a != b;
        if (!(a && b))
            continue;
        ++both;
        const double e = std::abs(double(march.depth[i]) - double(embree.depth[i])) / h;
        close += e < 0.5;
        worst = std::max(worst, e);
    }
    std::printf("%s: %zu pixels hit by both, %.3f %% within 0.5 voxel (worst %.2f), masks differ on %.3f %%\n", what,
                both, 100.0 * double(close) / double(both), worst, 100.0 * double(differ) / double(W * H));
    EXPECT_GT(both, 1000u) << what;
    EXPECT_GE(double(close), 0.99 * double(both)) << what;
    EXPECT_LT(double(differ), 0.005 * double(W * H)) << what;
}

TEST(Render, MarchAndEmbreeOnTheMeshAgree)
{
    {
        BlobTree tree;
        tree.setRoot(tree.sphere({0.013, -0.021, 0.007}, 0.5));
        tree.finalize();
        expectMarchAgreesWithEmbree(tree, 0.02, "sphere");
    }
    {
        BlobTree tree;
        tree.setRoot(tree.segment({-0.3, -0.2, 0.1}, {0.4, 0.5, -0.2}, 0.17));
        tree.finalize();
        expectMarchAgreesWithEmbree(tree, 0.01, "capsule");
    }
    {
        // A small tree: a trunk and two branches, blended.
        BlobTree tree;
        const int trunk = tree.cone({0, 0, 0}, {0, 1.0, 0}, 0.08, 0.05);
        const int b1 = tree.cone({0, 0.5, 0}, {0.35, 0.85, 0.05}, 0.04, 0.02);
        const int b2 = tree.cone({0, 0.7, 0}, {-0.3, 1.0, -0.1}, 0.035, 0.015);
        tree.setRoot(tree.op(Combiner{}, {trunk, b1, b2}));
        tree.finalize();
        expectMarchAgreesWithEmbree(tree, 0.005, "small tree");
    }
}

TEST(Render, TheDefaultCameraFramesTheBounds)
{
    const Box b(glm::dvec3(-0.5, 0.0, -0.3), glm::dvec3(0.6, 2.2, 0.4));
    for (double aspect : {0.5, 1.0, 4.0 / 3.0, 2.0})
        for (double turn : {0.0, 90.0, 200.0}) {
            const int H = 100, W = int(std::round(H * aspect));
            const Camera cam = parseCamera(fmt::format("turntable:{}", turn), b, double(W) / H);
            const glm::dvec3 w = glm::normalize(cam.target - cam.eye), u = glm::normalize(glm::cross(w, cam.up)),
                             v = glm::cross(u, w);
            const double t = std::tan(glm::radians(0.5 * cam.fovY));
            for (int k = 0; k < 8; ++k) {
                const glm::dvec3 p(k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y, k & 4 ? b.hi.z : b.lo.z);
                const glm::dvec3 e = p - cam.eye;
                const double z = glm::dot(e, w);
                ASSERT_GT(z, 0.0);
                EXPECT_LE(std::abs(glm::dot(e, u) / z), t * W / H) << "aspect " << aspect << " turn " << turn;
                EXPECT_LE(std::abs(glm::dot(e, v) / z), t) << "aspect " << aspect << " turn " << turn;
            }
        }
    EXPECT_THROW(parseCamera("orbit", b, 1.0), InputError);
    EXPECT_THROW(parseCamera("turntable:x", b, 1.0), InputError);
}

TEST(Render, ImagesReadBackWithTheirChannels)
{
    BlobTree tree;
    tree.setRoot(tree.sphere({0, 0, 0}, 0.3));
    tree.finalize();
    const BakedGrids g = test::bakeTree(tree, 0.03);
    const Box bounds = activeWorldBounds(*g.surface);
    const RenderImage img = renderLevelSetCpu(*g.surface, g.color.get(), framingCamera(bounds, 1.5), 60, 40, 2);
    const auto dir = std::filesystem::temp_directory_path() / ("cambium_render_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string png = (dir / "s.png").string(), exr = (dir / "s.exr").string();
    writeImage(img, png);
    writeImage(img, exr);
    {
        auto in = OIIO::ImageInput::open(png);
        ASSERT_TRUE(in);
        EXPECT_EQ(in->spec().width, 60);
        EXPECT_EQ(in->spec().height, 40);
        EXPECT_EQ(in->spec().nchannels, 4);
    }
    {
        auto in = OIIO::ImageInput::open(exr);
        ASSERT_TRUE(in);
        const OIIO::ImageSpec& s = in->spec();
        ASSERT_EQ(s.nchannels, 8);
        EXPECT_EQ(s.channelnames[4], "Z");
        EXPECT_EQ(s.channelnames[5], "N.x");
        std::vector<float> px(size_t(8 * 60 * 40));
        ASSERT_TRUE(in->read_image(0, 0, 0, 8, OIIO::TypeDesc::FLOAT, px.data()));
        size_t hit = 0;
        for (size_t i = 0; i < size_t(60 * 40); ++i) {
            EXPECT_EQ(px[8 * i + 3], img.alpha[i]);
            if (std::isfinite(img.depth[i])) {
                ++hit;
                EXPECT_EQ(px[8 * i + 4], img.depth[i]);
            }
        }
        EXPECT_GT(hit, 100u);
    }
    EXPECT_THROW(writeImage(img, (dir / "s.jpg").string()), InputError);
    std::filesystem::remove_all(dir);
}

}  // namespace
