// Closed meshes into level sets: exact distances (a box against its closed
// form), signs, OpenVDB's checks and meshToLevelSet as the oracle, volumes.
#include "bake/mesh_levelset.h"
#include "bake/stages.h"
#include "shape/base_shapes.h"
#include "subdiv/multires.h"
#include "test_util.h"
#include "use/mesh.h"

#include <openvdb/tools/Diagnostics.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetMeasure.h>
#include <openvdb/tools/MeshToVolume.h>

#include <cmath>

using namespace cambium;

namespace {

/// The sphere of radius 1, fitted at every level: its finest level's mesh.
TriangleMesh sphereMesh(int levels)
{
    const BaseShape sphere = sphereBase(1.0);
    MultiresSurface s(sphere.mesh, levels, "sphere");
    s.analyse(sphere.target);
    return levelMesh(s.finest());
}

double boxDistance(const openvdb::Vec3d& p, double a)
{
    const openvdb::Vec3d q(std::fabs(p.x()) - a, std::fabs(p.y()) - a, std::fabs(p.z()) - a);
    const openvdb::Vec3d o(std::max(q.x(), 0.0), std::max(q.y(), 0.0), std::max(q.z(), 0.0));
    return o.length() + std::min(std::max({q.x(), q.y(), q.z()}), 0.0);
}

}  // namespace

TEST(MeshLevelSet, BoxValuesAreTheExactSignedDistance)
{
    // The cube [-0.5, 0.5]^3 as 12 triangles, with corners and edges whose
    // signs need the pseudo-normals, placed off the voxel grid.
    TriangleMesh box;
    const BaseShape cube = cubeBase(1.0);
    for (const glm::dvec3& p : cube.mesh.points)
        box.points.push_back(openvdb::Vec3s(float(p.x), float(p.y), float(p.z)));
    for (size_t f = 0; f < 6; ++f) {
        const int* c = cube.mesh.faceVerts.data() + 4 * f;
        const uint32_t q[4] = {uint32_t(c[0]), uint32_t(c[1]), uint32_t(c[2]), uint32_t(c[3])};
        box.addPolygon(q, 4);
    }
    MeshBakeOptions opt;
    opt.voxelSize = 0.0371;
    opt.halfWidth = 3.0;
    const BakedGrids g = bakeMeshLevelSet(box, opt, "box");
    // All of OpenVDB's checks but the Eikonal one: at the box's medial axis
    // inside the band the true distance's finite-difference gradient is short.
    EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface, 8), "");
    const double h = opt.voxelSize;
    size_t n = 0;
    double worst = 0.0;
    for (auto it = g.surface->tree().cbeginValueOn(); it; ++it) {
        const openvdb::Vec3d p = g.surface->indexToWorld(it.getCoord());
        worst = std::max(worst, std::fabs(double(*it) - boxDistance(p, 0.5)));
        ++n;
    }
    EXPECT_LT(worst, 1e-5 * h);
    EXPECT_GT(n, size_t(6 * (1.0 / h) * (1.0 / h) * 5));
    // Every voxel, active or not, on the right side (the flood fill's signs).
    size_t wrong = 0;
    for (auto it = g.surface->tree().cbeginValueAll(); it; ++it)
        if (it.isVoxelValue()) {
            const double d = boxDistance(g.surface->indexToWorld(it.getCoord()), 0.5);
            wrong += std::fabs(d) > 1e-9 && (d < 0) != (*it < 0);
        }
    EXPECT_EQ(wrong, 0u);
    test::report("{} band voxels, largest error {:.3g} voxels", n, worst / h);
}

TEST(MeshLevelSet, SphereAgreesWithMeshToLevelSetAndTheMesh)
{
    const TriangleMesh mesh = sphereMesh(5);
    MeshBakeOptions opt;
    opt.voxelSize = 0.02;
    const BakedGrids g = bakeMeshLevelSet(mesh, opt, "sphere");
    EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
    const double h = opt.voxelSize;

    // The mesh's vertices lie on the zero crossing (trilinear), within 0.05 voxel.
    openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> sampler(*g.surface);
    double far = 0.0;
    for (const auto& p : mesh.points)
        far = std::max(far, std::fabs(double(sampler.wsSample(openvdb::Vec3d(p)))) / h);
    EXPECT_LT(far, 0.05);

    // OpenVDB's meshToLevelSet of the same triangles, as the oracle.
    std::vector<openvdb::Vec3s> pts = mesh.points;
    std::vector<openvdb::Vec3I> tris;
    for (const auto& t : mesh.triangles)
        tris.push_back(openvdb::Vec3I(t[0], t[1], t[2]));
    const auto xform = openvdb::math::Transform::createLinearTransform(h);
    const auto oracle = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*xform, pts, tris, 3.0f);
    auto acc = oracle->getConstAccessor();
    double worst = 0.0;
    size_t compared = 0;
    for (auto it = g.surface->tree().cbeginValueOn(); it; ++it) {
        if (std::fabs(*it) > 1.5 * h || !acc.isValueOn(it.getCoord()))
            continue;
        worst = std::max(worst, std::fabs(double(*it - acc.getValue(it.getCoord()))) / h);
        ++compared;
    }
    EXPECT_GT(compared, 10000u);
    EXPECT_LT(worst, 0.05);

    // Volume: the level set's against the mesh's (divergence theorem).
    const double vMesh = meshVolume(mesh), vSet = openvdb::tools::levelSetVolume(*g.surface);
    EXPECT_NEAR(vSet / vMesh, 1.0, 2e-3);
    test::report(
        "{} points within {:.4f} voxel of the zero crossing; {} voxels near the surface "
        "within {:.4f} voxel of meshToLevelSet; volume {:.5f} vs mesh {:.5f}",
        mesh.points.size(), far, compared, worst, vSet, vMesh);
}

TEST(MeshLevelSet, OpenOrNonManifoldMeshesAreRefused)
{
    MultiresSurface plane(planeBase(1.0, 2).mesh, 1, "plane");
    plane.synthesize();
    MeshBakeOptions opt;
    opt.voxelSize = 0.05;
    try {
        bakeMeshLevelSet(levelMesh(plane.finest()), opt, "plane.json");
        ADD_FAILURE() << "an open mesh was baked";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("plane.json: the edge between points"),
                  std::string::npos);
        EXPECT_NE(std::string(e.what()).find("the surface is open"), std::string::npos) << e.what();
    }
    TriangleMesh empty;
    EXPECT_THROW(bakeMeshLevelSet(empty, opt, "empty"), InputError);
}

TEST(MeshLevelSet, FarApartPartsBinSparselyAndAgreeWithOnePart)
{
    // Two boxes 50 apart at voxel size 0.02: the band's bounds would hold
    // about 2e8 leaves, so the triangles are binned by a hash of leaves, not in a
    // dense grid; near each box the values are those of that box alone.
    auto box = [](TriangleMesh& m, const openvdb::Vec3s& at) {
        const BaseShape cube = cubeBase(0.5);
        const uint32_t first = uint32_t(m.points.size());
        for (const glm::dvec3& p : cube.mesh.points)
            m.points.push_back(openvdb::Vec3s(float(p.x), float(p.y), float(p.z)) + at);
        for (size_t f = 0; f < 6; ++f) {
            const int* c = cube.mesh.faceVerts.data() + 4 * f;
            const uint32_t q[4] = {first + uint32_t(c[0]), first + uint32_t(c[1]),
                                   first + uint32_t(c[2]), first + uint32_t(c[3])};
            m.addPolygon(q, 4);
        }
    };
    TriangleMesh one, two;
    box(one, openvdb::Vec3s(0.0f));
    box(two, openvdb::Vec3s(0.0f));
    box(two, openvdb::Vec3s(50.0f));
    MeshBakeOptions opt;
    opt.voxelSize = 0.02;
    const BakedGrids a = bakeMeshLevelSet(one, opt, "one"), b = bakeMeshLevelSet(two, opt, "two");
    EXPECT_EQ(openvdb::tools::checkLevelSet(*b.surface, 8), "");
    // (The far box's corners, 2500 voxels out in single precision, sit a
    // little differently on the grid: its band has nearly as many voxels.)
    EXPECT_NEAR(double(b.surface->activeVoxelCount()) / double(a.surface->activeVoxelCount()), 2.0,
                0.01);
    auto acc = b.surface->getConstAccessor();
    size_t differ = 0;
    for (auto it = a.surface->tree().cbeginValueOn(); it; ++it)
        differ += acc.getValue(it.getCoord()) != *it;
    EXPECT_EQ(differ, 0u);
}

TEST(MeshLevelSet, InwardFacesBakeTheSameAndBadPointsAreRefused)
{
    // The same closed box with every triangle turned inwards encloses a
    // negative volume: its level set is the same, negative inside.
    TriangleMesh out, in;
    const BaseShape cube = cubeBase(1.0);
    for (const glm::dvec3& p : cube.mesh.points)
        out.points.push_back(openvdb::Vec3s(float(p.x), float(p.y), float(p.z)));
    in.points = out.points;
    for (size_t f = 0; f < 6; ++f) {
        const int* c = cube.mesh.faceVerts.data() + 4 * f;
        const uint32_t q[4] = {uint32_t(c[0]), uint32_t(c[1]), uint32_t(c[2]), uint32_t(c[3])};
        const uint32_t r[4] = {q[3], q[2], q[1], q[0]};
        out.addPolygon(q, 4);
        in.addPolygon(r, 4);
    }
    // And a triangle with a point twice (no area, no edges of its own).
    in.triangles.push_back({0, 0, 1});
    MeshBakeOptions opt;
    opt.voxelSize = 0.05;
    const BakedGrids a = bakeMeshLevelSet(out, opt, "out"), b = bakeMeshLevelSet(in, opt, "in");
    EXPECT_EQ(a.surface->activeVoxelCount(), b.surface->activeVoxelCount());
    auto acc = b.surface->getConstAccessor();
    size_t differ = 0;
    for (auto it = a.surface->tree().cbeginValueOn(); it; ++it)
        differ += std::fabs(acc.getValue(it.getCoord()) - *it) > 1e-6f;
    EXPECT_EQ(differ, 0u);
    TriangleMesh bad = out;
    bad.points[3].y() = std::nanf("");
    EXPECT_THROW(bakeMeshLevelSet(bad, opt, "bad"), InputError);
    bad.points[3].y() = 1e30f;
    EXPECT_THROW(bakeMeshLevelSet(bad, opt, "far"), InputError);
    // 2^20 voxels out, less its band and a leaf's margin: floats an eighth
    // of a voxel apart there.
    bad.points[3].y() = float(0.05 * (double(1 << 20) - 3.0 - 16.0) + 0.01);
    test::expectInputError([&] { bakeMeshLevelSet(bad, opt, "far"); },
                           "far: point 3, with its band, reaches 5.243e+04 from the origin",
                           "a point just past the float-precision bound");
    bad.points[3].y() = float(0.05 * (double(1 << 20) - 3.0 - 16.0) - 0.01);
    EXPECT_NO_THROW(checkMeshBake(bad, opt, "near"));
}

TEST(MeshLevelSet, InternalNodesAreCountedOncePerNodeTheLeavesReach)
{
    // A column of 4,096 leaves along z from the origin: 256 nodes of 128^3
    // voxels and 8 of 4096^3; a second column in the same nodes adds none.
    using Lower = openvdb::FloatTree::RootNodeType::ChildNodeType::ChildNodeType;
    using Upper = openvdb::FloatTree::RootNodeType::ChildNodeType;
    using ColourLower = openvdb::Vec3STree::RootNodeType::ChildNodeType::ChildNodeType;
    using ColourUpper = openvdb::Vec3STree::RootNodeType::ChildNodeType;
    auto column = [](size_t l) { return openvdb::Coord(0, 0, int(l) * 8); };
    EXPECT_EQ(internalNodeBytes(4096, false, column), 256.0 * sizeof(Lower) + 8.0 * sizeof(Upper));
    EXPECT_EQ(internalNodeBytes(4096, true, column),
              256.0 * (sizeof(Lower) + sizeof(ColourLower)) +
                  8.0 * (sizeof(Upper) + sizeof(ColourUpper)));
    auto two = [](size_t l) { return openvdb::Coord(8 * int(l % 2), 0, int(l / 2) * 8); };
    EXPECT_EQ(internalNodeBytes(8192, false, two), 256.0 * sizeof(Lower) + 8.0 * sizeof(Upper));
    EXPECT_EQ(internalNodeBytes(0, true, column), 0.0);
}

TEST(MeshLevelSet, ANeedlesInternalNodesAreCountedBeforeItsLeavesAreMade)
{
    // A sliver 1000 long and 0.001 across at voxel 0.002: 250,008 leaves in
    // a column of single leaves, each 128 voxels of it one internal node of
    // 32 KB (and 64 KB for the colour's): 4.7 GB measured, 19 KB a leaf.
    // Counted at 10 KB a leaf (2.5 GB) it fitted in 3 GB and ran out of
    // memory as its grids were made; now refused before.
    TriangleMesh m;
    m.points = {openvdb::Vec3s(0.0f), openvdb::Vec3s(1000.0f, 0.0f, 0.0f),
                openvdb::Vec3s(0.0f, 0.001f, 0.0f), openvdb::Vec3s(0.0f, 0.0f, 0.001f)};
    const uint32_t f[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {0, 3, 2}};
    for (const auto& t : f)
        m.addPolygon(t, 3);
    MeshBakeOptions opt;
    opt.voxelSize = 0.002;
    cambium::test::expectRefusedUnderAddressSpaceLimit(
        3e9, [&] { bakeMeshLevelSet(m, opt, "sliver.obj"); },
        [](const std::string& what) {
            return what.find(
                       "sliver.obj: the band at voxel size 0.002 has at least 250008 "
                       "leaves, which need at least 5.") != std::string::npos;
        });
}

TEST(MeshLevelSet, ABandOfMoreLeavesThanFitIsRefusedWhileBinning)
{
    // A thin slanted tetrahedron 10^5 voxels across: its band crosses some
    // 10^8 leaves (a petabyte of leaves), refused as soon as the leaves met
    // pass what fits, within the first triangle, not after binning them all
    // (a tentacle 1000 long at voxel 0.5 took 25 s and 2.4 GB to refuse).
    TriangleMesh m;
    const float s = 100.0f;
    m.points = {openvdb::Vec3s(0.0f), openvdb::Vec3s(s, 0.0f, s), openvdb::Vec3s(0.0f, s, s),
                openvdb::Vec3s(0.01f, 0.01f, 0.03f)};
    const uint32_t f[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
    for (const auto& t : f)
        m.addPolygon(t, 3);
    MeshBakeOptions opt;
    opt.voxelSize = 1e-3;
    try {
        bakeMeshLevelSet(m, opt, "sheet.obj");
        ADD_FAILURE() << "a band of a petabyte was baked";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("sheet.obj: the band at voxel size 0.001 has at least"),
                  std::string::npos)
            << what;
        EXPECT_NE(what.find("use a larger voxel size"), std::string::npos) << what;
    }
}
