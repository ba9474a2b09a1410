// Ray marching a level set: hits on an analytic sphere level set within 0.1
// voxel of the exact ray-sphere intersection, the right pixels hit and miss,
// a default camera that frames the bounds, images that read back.
#include "use/mesh.h"
#include "use/render.h"
#include "model/turtle.h"

#include "bake_util.h"
#include "temp_dir.h"
#include "core/error.h"
#include "io/vdb.h"
#include "test_util.h"

#include <OpenImageIO/imageio.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <random>

namespace {

using namespace cambium;
using cambium::test::report;

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

/// A small L-system tree: ABOP's sympodial tree (figure 2.7) after 5 steps, thicker.
BlobTree smallLSystemTree()
{
    const LSystem sys = parseLSystem(
        "#define r1 0.9\n#define r2 0.7\n#define wr 0.8\n"
        "Axiom: A(1,0.6)\n"
        "A(l,w) --> !(w)F(l)[&(5)B(l*r1,w*wr)]/(180)[&(65)B(l*r2,w*wr)]\n"
        "B(l,w) --> !(w)F(l)[+(5)$B(l*r1,w*wr)][-(65)$B(l*r2,w*wr)]\n",
        "sympodial.l");
    return skeletonToBlend(interpretTurtle(sys, derive(sys, 5, 1, 100000)));
}

/// The baked scenes both cross-checks use: a sphere, a capsule and a small
/// tree of three cones (each cone its own colour when `coloured`).
const glm::dvec3 kSphereCentre(0.013, -0.021, 0.007);
BlobTree sphereScene()
{
    BlobTree tree;
    tree.setRoot(tree.sphere(kSphereCentre, 0.5));
    tree.finalize();
    return tree;
}
BlobTree capsuleScene()
{
    BlobTree tree;
    tree.setRoot(tree.segment({-0.3, -0.2, 0.1}, {0.4, 0.5, -0.2}, 0.17));
    tree.finalize();
    return tree;
}
BlobTree threeConeTree(bool coloured)
{
    BlobTree tree;
    const int trunk = tree.cone({0, 0, 0}, {0, 1.0, 0}, 0.08, 0.05);
    const int b1 = tree.cone({0, 0.5, 0}, {0.35, 0.85, 0.05}, 0.04, 0.02);
    const int b2 = tree.cone({0, 0.7, 0}, {-0.3, 1.0, -0.1}, 0.035, 0.015);
    if (coloured) {
        tree.setColor(trunk, {0.5, 0.3, 0.2});
        tree.setColor(b1, {0.2, 0.6, 0.2});
        tree.setColor(b2, {0.2, 0.2, 0.7});
    }
    tree.setRoot(tree.op(Combiner{}, {trunk, b1, b2}));
    tree.finalize();
    return tree;
}

using Renderer = std::function<RenderImage(const openvdb::FloatGrid&, const openvdb::Vec3fGrid*,
                                           const Camera&, int, int, int)>;

/// Both marches hit an analytic sphere level set where the ray does.
void expectHitsAnAnalyticSphere(const Renderer& render, const char* what)
{
    const double r = 0.8, h = 0.02;
    const glm::dvec3 c(0.1, -0.05, 0.2);
    auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        float(r), openvdb::Vec3f(float(c.x), float(c.y), float(c.z)), float(h), 3.0f);
    Camera cam;
    cam.eye = c + glm::dvec3(0.7, 0.9, 3.2);
    cam.target = c;
    const int W = 160, H = 120;
    const RenderImage img = render(*grid, nullptr, cam, W, H, 1);
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
            ASSERT_GT(
                n.x * img.normal[3 * i] + n.y * img.normal[3 * i + 1] + n.z * img.normal[3 * i + 2],
                0.99);
        }
    EXPECT_GT(checked, 1000u);
    report("analytic sphere, {}: largest |t - exact| {:.4f} voxel over {} pixels", what, worst,
           checked);
    EXPECT_LT(worst, 0.1) << what << ": largest |t - exact| in voxels over " << checked
                          << " pixels";
    EXPECT_GT(hits, checked);
}

TEST(Render, MarchHitsAnAnalyticSphereWhereTheRayDoes)
{
    expectHitsAnAnalyticSphere(
        [](const openvdb::FloatGrid& s, const openvdb::Vec3fGrid* c, const Camera& cam, int w,
           int h, int spp) { return renderLevelSetCpu(s, c, cam, w, h, spp); },
        "cpu");
}

TEST(Render, OpenCLMarchHitsAnAnalyticSphereWhereTheRayDoes)
{
    expectHitsAnAnalyticSphere(renderLevelSetOpenCL, "opencl");
}

/// How far two tracers' answers to the same rays differ.
struct TraceComparison {
    size_t both = 0, maskDiffers = 0, beyondTenth = 0;
    double worstT = 0.0, worstNormal = 0.0, worstAlbedo = 0.0;  // voxels, 1 - cos, max channel
};

TraceComparison compareTraces(const std::vector<TraceHit>& a, const std::vector<TraceHit>& b,
                              double h)
{
    TraceComparison c;
    for (size_t i = 0; i < a.size(); ++i) {
        if (a[i].hit != b[i].hit) {
            ++c.maskDiffers;
            continue;
        }
        if (!a[i].hit)
            continue;
        ++c.both;
        const double e = std::abs(a[i].t - b[i].t) / h;
        c.beyondTenth += e > 0.1;
        c.worstT = std::max(c.worstT, e);
        c.worstNormal = std::max(c.worstNormal, 1.0 - double(glm::dot(a[i].normal, b[i].normal)));
        for (int k = 0; k < 3; ++k)
            c.worstAlbedo =
                std::max(c.worstAlbedo, double(std::abs(a[i].albedo[k] - b[i].albedo[k])));
    }
    return c;
}

/// The OpenCL march against OpenVDB's intersector: the same rays (the view's
/// pixels, then random and adversarial ones) give the same hits within 0.1
/// voxel, the same normals and colours.
/// `exact`: where known, the exact distance along a ray to the surface, or
/// -1 where the ray misses it or grazes it (ill-conditioned).
void expectOpenCLMatchesCpu(const BlobTree& tree, double h, const char* what,
                            const std::function<double(const TraceRay&)>& exact = {})
{
    const BakedGrids g = test::bakeTree(tree, h);
    const Box bounds = activeWorldBounds(*g.surface);
    const CpuMarcher cpu(*g.surface, g.color.get());
    const OpenCLMarcher cl(*g.surface, g.color.get());

    std::vector<TraceRay> rays;
    // The framing view's pixel centres, from two sides.
    for (double turn : {0.0, 150.0}) {
        const Camera cam = framingCamera(bounds, 4.0 / 3.0, 35.0 + turn, 20.0);
        const int W = 160, H = 120;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                TraceRay r;
                cameraRay(cam, W, H, x + 0.5, y + 0.5, r.origin, r.direction);
                rays.push_back(r);
            }
    }
    // Random rays from outside the surface's bounds towards a random point in
    // them; rays along the axes (direction components exactly zero) through
    // the bounds, from outside and from inside the box; rays that start in
    // the narrow band outside the surface.
    std::mt19937 rng(7);
    const glm::dvec3 mid = bounds.center();
    const double far = 2.0 * glm::length(bounds.size()) + 1.0;
    auto inBox = [&] { return test::randomIn(rng, bounds.lo, bounds.hi); };
    for (int i = 0; i < 4000; ++i) {
        const glm::dvec3 d = test::randomUnit(rng);
        const glm::dvec3 target = inBox();
        rays.push_back({target - far * d, d});
    }
    for (int axis = 0; axis < 3; ++axis)
        for (double sign : {-1.0, 1.0})
            for (int i = 0; i < 500; ++i) {
                glm::dvec3 d(0.0);
                d[axis] = sign;
                glm::dvec3 o = inBox();
                if (i % 2 == 0)
                    o[axis] = mid[axis] - sign * far;  // from outside the box
                rays.push_back({o, d});
            }
    {
        // Starting points in the band just outside the surface: points along
        // random rays where the level set is between 0.5 and 2 voxels.
        openvdb::FloatGrid::ConstAccessor acc = g.surface->getConstAccessor();
        int added = 0;
        for (int i = 0; i < 100000 && added < 500; ++i) {
            const glm::dvec3 p = inBox();
            const openvdb::Coord ijk =
                g.surface->transform().worldToIndexCellCentered(openvdb::Vec3d(p.x, p.y, p.z));
            const float v = acc.getValue(ijk);
            if (v > 0.5 * h && v < 2.0 * h) {
                const glm::dvec3 d =
                    glm::normalize(glm::normalize(mid - p) + 0.3 * test::randomUnit(rng));
                rays.push_back({p, d});
                ++added;
            }
        }
        EXPECT_EQ(added, 500) << what;
    }

    std::vector<TraceHit> a, b;
    cpu.tracer()(rays, a);
    cl.trace(rays, b);
    const TraceComparison c = compareTraces(a, b, h);
    report(
        "{}: {} rays, {} hit by both, masks differ on {}, {} beyond 0.1 voxel (worst {:.3f} "
        "voxel), "
        "worst normal 1-cos {:.2g}, worst albedo {:.3g}",
        what, rays.size(), c.both, c.maskDiffers, c.beyondTenth, c.worstT, c.worstNormal,
        c.worstAlbedo);
    EXPECT_GT(c.both, 2000u) << what;
    EXPECT_EQ(c.maskDiffers, 0u) << what;
    // OpenVDB's intersector ends with one secant step between two samples of
    // the interpolant, the OpenCL march refines to the interpolant's root:
    // they differ by more than 0.1 voxel on a few rays, where the exact
    // distance (below, on the sphere) sides with the OpenCL march.
    EXPECT_LE(double(c.beyondTenth), 0.005 * double(c.both)) << what;
    // The worst single ray: 0.13-0.42 voxel with GCC; 0.75 in the clang build
    // of tools/sanitize.sh (other rounding in the bake's sweeps and in the
    // intersector's secant step).  Within one voxel either way.
    EXPECT_LT(c.worstT, 1.0) << what;
    // The two normals come from different stencils (OpenVDB's gradient at
    // the hit, the march's trilinear one), which reach voxels two or three
    // inside; at a capsule's caps those are up to 0.17 voxel off, and one
    // ray in 8,000 sees normals 2.6 degrees apart (1 - cos 1.05e-3).
    EXPECT_LT(c.worstNormal, 2e-3) << what;
    EXPECT_LT(c.worstAlbedo, 0.01) << what;
    if (exact) {
        double worstCpu = 0.0, worstCl = 0.0;
        size_t checked = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
            const double t = exact(rays[i]);
            if (!(t > 0.0) || !a[i].hit || !b[i].hit)
                continue;
            ++checked;
            worstCpu = std::max(worstCpu, std::abs(a[i].t - t) / h);
            worstCl = std::max(worstCl, std::abs(b[i].t - t) / h);
        }
        report(
            "{}: largest |t - exact| over {} rays: cpu intersector {:.3f} voxel, OpenCL march "
            "{:.3f} "
            "voxel",
            what, checked, worstCpu, worstCl);
        EXPECT_GT(checked, 5000u) << what;
        EXPECT_LT(worstCl, 0.1) << what;
    }
}

TEST(Render, OpenCLMarchAgreesWithTheCpuIntersector)
{
    {
        const glm::dvec3 c = kSphereCentre;
        const double r = 0.5, h = 0.02;  // sphere() takes the surface's radius
        expectOpenCLMatchesCpu(sphereScene(), h, "sphere", [&](const TraceRay& ray) {
            const double miss = (glm::length(glm::cross(c - ray.origin, ray.direction)) - r) / h;
            return miss < -1.0 ? raySphere(ray.origin, ray.direction, c, r) : -1.0;
        });
    }
    expectOpenCLMatchesCpu(capsuleScene(), 0.01, "capsule");
    // A small tree of three colours: the albedo from Cd on both paths.
    expectOpenCLMatchesCpu(threeConeTree(true), 0.005, "small coloured tree");
    expectOpenCLMatchesCpu(smallLSystemTree(), 0.01, "small L-system tree");
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
    report(
        "{}: {} pixels hit by both, {:.3f} % within 0.5 voxel (worst {:.2f}), masks differ on "
        "{:.3f} "
        "%",
        what, both, 100.0 * double(close) / double(both), worst,
        100.0 * double(differ) / double(W * H));
    EXPECT_GT(both, 1000u) << what;
    EXPECT_GE(double(close), 0.99 * double(both)) << what;
    EXPECT_LT(double(differ), 0.005 * double(W * H)) << what;
}

TEST(Render, MarchAndEmbreeOnTheMeshAgree)
{
    expectMarchAgreesWithEmbree(sphereScene(), 0.02, "sphere");
    expectMarchAgreesWithEmbree(capsuleScene(), 0.01, "capsule");
    expectMarchAgreesWithEmbree(threeConeTree(false), 0.005, "small tree");
    expectMarchAgreesWithEmbree(smallLSystemTree(), 0.01, "small L-system tree");
}

TEST(Render, AMeshFileRendersAsTheMeshItWasWrittenFrom)
{
    const BakedGrids g = test::bakeTree(capsuleScene(), 0.02);
    const TriangleMesh mesh = meshLevelSet(*g.surface);
    const auto path = std::filesystem::temp_directory_path() /
                      ("cambium_render_mesh_" + std::to_string(::getpid()) + ".ply");
    writeMesh(mesh, path.string());
    const TriangleMesh back = readMesh(path.string());
    std::filesystem::remove(path);
    const Camera cam = framingCamera(meshBounds(mesh), 1.0);
    const RenderImage a = renderMeshEmbree(mesh, cam, 64, 64, 1),
                      b = renderMeshEmbree(back, cam, 64, 64, 1);
    size_t hits = 0;
    for (size_t i = 0; i < a.depth.size(); ++i) {
        ASSERT_EQ(a.depth[i], b.depth[i]) << "pixel " << i;
        ASSERT_EQ(a.rgb[3 * i], b.rgb[3 * i]) << "pixel " << i;
        hits += std::isfinite(a.depth[i]);
    }
    EXPECT_GT(hits, 500u);
}

TEST(Render, ALevelSetOfActiveTilesIsDrawn)
{
    // Another tool's level set whose band is two active tiles of 128^3
    // voxels, one inside and one outside, half a voxel from the surface: its
    // surface is the face between them.  Its tiles made voxels, the marches
    // step through them (they drew an empty picture with exit 0, sweep 20).
    openvdb::initialize();
    const auto grid = openvdb::FloatGrid::create(0.3f);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName("surface");
    grid->tree().addTile(2, openvdb::Coord(0, 0, 0), -0.05f, true);
    grid->tree().addTile(2, openvdb::Coord(128, 0, 0), 0.05f, true);
    const std::string dir = test::freshDir("cambium_render_tiles").string(),
                      path = dir + "/tiles.vdb";
    openvdb::io::File(path).write({grid});
    const LevelSetGrids g = readLevelSet(path);
    voxelizeActiveTiles(*g.surface);
    EXPECT_EQ(g.surface->activeVoxelCount(), openvdb::Index64(2) * 128 * 128 * 128);
    EXPECT_EQ(g.surface->tree().activeTileCount(), 0u);
    // (seen from +x: the rays cross the outside tile into the inside one)
    const Camera cam = parseCamera("look:40,6.4,6.4:12.8,6.4,6.4:40", Box(), 1.0);
    const RenderImage img = renderLevelSetCpu(*g.surface, nullptr, cam, 64, 64, 1);
    size_t covered = 0;
    for (float a : img.alpha)
        covered += a > 0.0f;
    EXPECT_GT(covered, 64u * 64u / 10u) << "the face between the tiles is drawn";
}

TEST(Render, TheDefaultCameraFramesTheBounds)
{
    const Box b(glm::dvec3(-0.5, 0.0, -0.3), glm::dvec3(0.6, 2.2, 0.4));
    for (double aspect : {0.5, 1.0, 4.0 / 3.0, 2.0})
        for (double turn : {0.0, 90.0, 200.0}) {
            const int H = 100, W = int(std::round(H * aspect));
            const Camera cam = parseCamera(fmt::format("turntable:{}", turn), b, double(W) / H);
            const glm::dvec3 w = glm::normalize(cam.target - cam.eye),
                             u = glm::normalize(glm::cross(w, cam.up)), v = glm::cross(u, w);
            const double t = std::tan(glm::radians(0.5 * cam.fovY));
            for (int k = 0; k < 8; ++k) {
                const glm::dvec3 p(k & 1 ? b.hi.x : b.lo.x, k & 2 ? b.hi.y : b.lo.y,
                                   k & 4 ? b.hi.z : b.lo.z);
                const glm::dvec3 e = p - cam.eye;
                const double z = glm::dot(e, w);
                ASSERT_GT(z, 0.0);
                EXPECT_LE(std::abs(glm::dot(e, u) / z), t * W / H)
                    << "aspect " << aspect << " turn " << turn;
                EXPECT_LE(std::abs(glm::dot(e, v) / z), t)
                    << "aspect " << aspect << " turn " << turn;
            }
        }
    EXPECT_THROW(parseCamera("orbit", b, 1.0), InputError);
    EXPECT_THROW(parseCamera("turntable:x", b, 1.0), InputError);
}

TEST(Render, ALookCameraIsWhereItIsToldAndTheTargetIsInTheMiddle)
{
    const Box b(glm::dvec3(0.0), glm::dvec3(1.0));
    const Camera cam = parseCamera("look:1,2,3:0.5,0.25,-1:20", b, 1.5);
    EXPECT_EQ(cam.eye, glm::dvec3(1, 2, 3));
    EXPECT_EQ(cam.target, glm::dvec3(0.5, 0.25, -1));
    EXPECT_EQ(cam.fovY, 20.0);
    // The target projects to the image's centre.
    glm::dvec3 o, d;
    cameraRay(cam, 300, 200, 150.0, 100.0, o, d);
    EXPECT_NEAR(glm::length(glm::cross(d, glm::normalize(cam.target - cam.eye))), 0.0, 1e-12);
    EXPECT_EQ(parseCamera("look:1,2,3:0,0,0", b, 1.0).fovY, 35.0);
    for (const char* bad : {"look:1,2,3", "look:1,2,3:1,2,3", "look:0,5,0:0,0,0",
                            "look:1,2,3:0,0,0:200", "look:1,2,x:0,0,0", "look:1,2,3:0,0,0:20:1"})
        EXPECT_THROW(parseCamera(bad, b, 1.0), InputError) << bad;
}

TEST(Render, ImagesReadBackWithTheirChannels)
{
    BlobTree tree;
    tree.setRoot(tree.sphere({0, 0, 0}, 0.3));
    tree.finalize();
    const BakedGrids g = test::bakeTree(tree, 0.03);
    const Box bounds = activeWorldBounds(*g.surface);
    const RenderImage img =
        renderLevelSetCpu(*g.surface, g.color.get(), framingCamera(bounds, 1.5), 60, 40, 2);
    const auto dir =
        std::filesystem::temp_directory_path() / ("cambium_render_" + std::to_string(::getpid()));
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

TEST(Camera, AnOrbitKeepsTheTargetDistanceAndFieldOfViewAndStopsShortOfThePoles)
{
    Camera cam;
    cam.eye = {3.0, 2.0, 4.0};
    cam.target = {1.0, 1.0, 1.0};
    cam.fovY = 40.0;
    const double r = glm::length(cam.eye - cam.target);
    auto near = [](const glm::dvec3& a, const glm::dvec3& b) { return glm::length(a - b) < 1e-9; };
    EXPECT_TRUE(near(orbitCamera(cam, 0.0, 0.0).eye, cam.eye));
    EXPECT_TRUE(near(orbitCamera(cam, 360.0, 0.0).eye, cam.eye));
    // A quarter turn about the vertical through the target: x and z swap
    // roles, the height kept.
    const Camera q = orbitCamera(cam, 90.0, 0.0);
    EXPECT_TRUE(near(q.eye - q.target, glm::dvec3(3.0, 1.0, -2.0)));
    EXPECT_EQ(q.fovY, 40.0);
    EXPECT_TRUE(near(q.target, cam.target));
    // Raised past the pole: held at 85 degrees above the horizon.
    const Camera top = orbitCamera(cam, 0.0, 170.0);
    EXPECT_NEAR(glm::length(top.eye - top.target), r, 1e-9);
    EXPECT_NEAR(std::asin((top.eye.y - top.target.y) / r), glm::radians(85.0), 1e-9);
}

TEST(Render, RaysOnlyWhereLeavesCouldBeGiveTheSamePicture)
{
    // CpuMarcher::render traces a pixel's rays only over the range where the
    // projections of active leaves cover it (rayRanges): the picture of every
    // ray traced from the eye to infinity, for a tree from outside, from
    // within its leaves' boxes (every pixel then) and from below.
    const BakedGrids g = test::bakeTree(smallLSystemTree(), 0.01);
    const Box b = activeWorldBounds(*g.surface);
    const CpuMarcher cpu(*g.surface, g.color.get());
    const BatchTracer everyRay = cpu.tracer();
    const glm::dvec3 mid = b.center();
    const Camera views[] = {framingCamera(b, 4.0 / 3.0),
                            Camera{mid + glm::dvec3(0.001, 0.002, 0.003),
                                   glm::dvec3(mid.x, b.lo.y, mid.z), glm::dvec3(1, 0, 0), 60.0},
                            Camera{glm::dvec3(mid.x, b.lo.y - 0.2, mid.z + 0.01), mid}};
    for (int view = 0; view < 3; ++view) {
        SCOPED_TRACE(view);
        const Camera& cam = views[view];
        const int W = 120, H = 90, spp = 2;
        const RenderImage ranged = cpu.render(cam, W, H, spp),
                          all = renderBatches(cam, W, H, spp, everyRay, 1 << 14);
        ASSERT_EQ(ranged.rgb.size(), all.rgb.size());
        size_t differ = 0, covered = 0;
        for (size_t i = 0; i < all.alpha.size(); ++i) {
            covered += all.alpha[i] > 0.0f;
            differ += std::abs(ranged.alpha[i] - all.alpha[i]) > 0.0f ||
                      std::abs(ranged.depth[i] - all.depth[i]) > 1e-6f * all.depth[i] ||
                      std::abs(ranged.rgb[3 * i] - all.rgb[3 * i]) > 1e-5f;
        }
        EXPECT_EQ(differ, 0u);
        EXPECT_GT(covered, 50u);
        // Where the ranges leave a pixel out, no ray of it meets the surface.
        const RayRanges r = rayRanges(*g.surface, cam, W, H);
        size_t skipped = 0;
        for (size_t i = 0; i < r.near.size(); ++i) {
            if (!(r.near[i] <= r.far[i])) {
                ++skipped;
                EXPECT_EQ(all.alpha[i], 0.0f) << i;
            }
        }
        if (view == 0) {
            EXPECT_GT(skipped, size_t(W * H / 4));  // from outside: most of the sky
        }
    }
}

TEST(Render, AStripOfRowsAtATimeGivesTheSamePicture)
{
    // cambium render reads the level set's topology, then decodes its
    // leaves a strip of the picture's rows at a time (those whose
    // footprints reach the strip's rows) and drops each after the last
    // strip that needs it.  A leaf not decoded holds no values: a lookup in
    // it gives it unset ones (counted: none) or reads nothing, and the
    // picture is the whole grid's to the bit, from outside (many strips, a
    // few leaves held at once), from
    // close by (leaves off the picture never decoded) and from inside the
    // tree's box (every leaf, one strip).
    openvdb::initialize();
    const BakedGrids g = test::bakeTree(threeConeTree(true), 0.005);
    ASSERT_TRUE(g.color);
    const std::string path = test::freshDir("cambium_render_strips").string() + "/tree.vdb";
    writeVdb(g, path, VdbFileInfo());
    const size_t leafCount = g.surface->tree().leafCount();
    ASSERT_GT(leafCount, 400u);
    const Box b = activeWorldBounds(*g.surface);
    const Camera outside = framingCamera(b, 4.0 / 3.0, 35.0, 20.0);
    Camera close = outside;
    close.eye = outside.target + 0.35 * (outside.eye - outside.target);
    Camera inside = outside;
    inside.eye = b.center() + 0.3 * (b.hi - b.center());
    inside.target = b.lo;
    const int W = 120, H = 90, spp = 2;
    const Camera views[] = {outside, close, inside};
    for (int view = 0; view < 3; ++view) {
        const Camera& cam = views[view];
        const RenderImage whole = renderLevelSetCpu(*g.surface, g.color.get(), cam, W, H, spp);
        VdbSummary summary;
        LevelSetGrids r = readLevelSetDelayed(path, summary, kSurfaceGrid, ColourRead::None, false);
        ASSERT_FALSE(r.color);
        LazySurface lazy;
        lazy.leaves = std::make_unique<LazyLeaves>(path, summary, *r.surface);
        lazy.leavesAtOnce = 60;
        LazySurface::Stats stats;
        lazy.stats = &stats;
        const RenderImage strips = renderLevelSetCpu(
            std::move(r.surface),
            [&](const std::vector<openvdb::Coord>&) { return g.color->deepCopy(); }, cam, W, H, spp,
            std::move(lazy));
        EXPECT_EQ(whole.rgb, strips.rgb) << view;
        EXPECT_EQ(whole.alpha, strips.alpha) << view;
        EXPECT_EQ(whole.depth, strips.depth) << view;
        EXPECT_EQ(whole.normal, strips.normal) << view;
        EXPECT_EQ(stats.strayLeaves, 0u) << view;
        size_t hit = 0;
        for (float a : whole.alpha)
            hit += a > 0.0f;
        EXPECT_GT(hit, 100u) << view;
        report(fmt::format("view {}: {} strips, at most {} of {} leaves held, {} decoded", view,
                           stats.strips, stats.mostHeld, leafCount, stats.decoded));
        if (view == 0) {
            EXPECT_GT(stats.strips, 5u);
            EXPECT_LT(stats.mostHeld, leafCount / 4);
            EXPECT_LE(stats.decoded, leafCount);
        } else if (view == 1) {
            EXPECT_GT(stats.strips, 1u);
            EXPECT_LT(stats.decoded, leafCount);  // (some leaves off the picture)
        } else {
            EXPECT_EQ(stats.strips, 1u);
            EXPECT_EQ(stats.decoded, leafCount);
        }
    }
}

TEST(Render, OneGridAtATimeGivesTheSamePicture)
{
    // cambium render traces against the level set alone, drops it, then
    // looks the hits' colours up in Cd: the picture of both grids held at
    // once, to the bit (a two-colour tree, two views).
    const BakedGrids g = test::bakeTree(threeConeTree(true), 0.01);
    ASSERT_TRUE(g.color);
    ASSERT_GT(g.color->tree().leafCount(), 0u);
    const Box b = activeWorldBounds(*g.surface);
    for (double turn : {0.0, 120.0}) {
        const Camera cam = framingCamera(b, 4.0 / 3.0, 35.0 + turn, 20.0);
        const RenderImage both = renderLevelSetCpu(*g.surface, g.color.get(), cam, 120, 90, 2);
        bool asked = false;
        // (the colour of every leaf the render does not ask for is wrong:
        // a lookup in one would change the picture)
        const RenderImage apart = renderLevelSetCpu(
            g.surface->deepCopy(),
            [&](const std::vector<openvdb::Coord>& leaves) {
                asked = true;
                EXPECT_TRUE(std::is_sorted(leaves.begin(), leaves.end()));
                EXPECT_FALSE(leaves.empty());
                openvdb::Vec3fGrid::Ptr c = g.color->deepCopy();
                size_t wrong = 0;
                for (auto leaf = c->tree().beginLeaf(); leaf; ++leaf)
                    if (!std::binary_search(leaves.begin(), leaves.end(), leaf->origin())) {
                        leaf->fill(openvdb::Vec3f(1.0f, 0.0f, 1.0f));
                        ++wrong;
                    }
                EXPECT_GT(wrong, 0u) << "every leaf looked up: the test shows nothing";
                return c;
            },
            cam, 120, 90, 2);
        EXPECT_TRUE(asked);
        EXPECT_EQ(both.rgb, apart.rgb) << turn;
        EXPECT_EQ(both.alpha, apart.alpha) << turn;
        EXPECT_EQ(both.depth, apart.depth) << turn;
        EXPECT_EQ(both.normal, apart.normal) << turn;
        size_t hit = 0;
        for (float a : both.alpha)
            hit += a > 0.0f;
        EXPECT_GT(hit, 100u);
    }
}
