// The baked level set: exact signed distances for a sphere, a capsule and a
// cone over the whole band; OpenVDB's own level-set checks; a complete band on
// blends, PCM, CSG and GBB scenes (dense brute force); write / read round trip.
#include "bake/levelset.h"
#include "bake/topology.h"
#include "bake/vdb_io.h"

#include "blobtree/bounds.h"
#include "test_util.h"

#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/Diagnostics.h>

#include <filesystem>

namespace {

using namespace cambium;
using namespace cambium::test;

struct Errors {
    double nearMax = 0.0;   // |error| in voxels where |d| < 1 voxel
    double farMax = 0.0;    // elsewhere in the band
    double mean = 0.0;
    size_t active = 0, missing = 0, extra = 0;
};

/// Compares a baked grid with an exact signed distance over every voxel of
/// the band's bounding box.
Errors compareWithExact(const openvdb::FloatGrid& grid, const std::function<double(const glm::dvec3&)>& exact,
                        const Box& bounds, double h, double W)
{
    Errors e;
    auto acc = grid.getConstAccessor();
    const openvdb::Coord lo(int(std::floor(bounds.lo.x / h)) - int(W) - 2, int(std::floor(bounds.lo.y / h)) - int(W) - 2,
                            int(std::floor(bounds.lo.z / h)) - int(W) - 2);
    const openvdb::Coord hi(int(std::ceil(bounds.hi.x / h)) + int(W) + 2, int(std::ceil(bounds.hi.y / h)) + int(W) + 2,
                            int(std::ceil(bounds.hi.z / h)) + int(W) + 2);
    double sum = 0.0;
    for (int x = lo.x(); x <= hi.x(); ++x)
        for (int y = lo.y(); y <= hi.y(); ++y)
            for (int z = lo.z(); z <= hi.z(); ++z) {
                const openvdb::Coord c(x, y, z);
                const double d = exact(glm::dvec3(x, y, z) * h) / h;  // voxels
                const bool active = acc.isValueOn(c);
                if (!active) {
                    // Outside the band: the value is the background with the right sign.
                    if (std::abs(d) < W - 0.15)
                        ++e.missing;
                    EXPECT_EQ(acc.getValue(c), d < 0 ? -grid.background() : grid.background()) << "at " << c;
                    continue;
                }
                ++e.active;
                if (std::abs(d) > W + 0.15)
                    ++e.extra;
                const double err = std::abs(acc.getValue(c) / h - d);
                sum += err;
                (std::abs(d) < 1.0 ? e.nearMax : e.farMax) = std::max(std::abs(d) < 1.0 ? e.nearMax : e.farMax, err);
            }
    e.mean = e.active ? sum / double(e.active) : 0.0;
    return e;
}

BakedGrids bakeTree(const BlobTree& tree, double h, double W = 3.0, bool cpu = true)
{
    const FieldProgram prog = FieldProgram::compile(tree);
    auto sampler = cpu ? makeCpuSampler() : makeOpenCLSampler();
    BakeOptions o;
    o.voxelSize = h;
    o.halfWidth = W;
    return bakeLevelSet(prog, *sampler, o);
}

void expectAccurate(const Errors& e, const char* what)
{
    EXPECT_GT(e.active, 1000u) << what;
    EXPECT_LT(e.nearMax, 0.1) << what;   // the bound near the surface
    EXPECT_LT(e.farMax, 0.25) << what;   // cambium's stated bound over the rest of the band
    EXPECT_LT(e.mean, 0.03) << what;
    EXPECT_EQ(e.missing, 0u) << what;
    EXPECT_EQ(e.extra, 0u) << what;
}

TEST(BakeAccuracy, SphereMatchesItsExactDistance)
{
    for (bool cpu : {true, false}) {
        BlobTree tree;
        const glm::dvec3 c(0.013, -0.021, 0.007);
        const double r = 0.5;
        tree.setRoot(tree.sphere(c, r));
        tree.finalize();
        const double h = 0.02;
        const BakedGrids g = bakeTree(tree, h, 3.0, cpu);
        const Errors e = compareWithExact(*g.surface, [&](const glm::dvec3& p) { return glm::length(p - c) - r; },
                                          Box::around(c, r), h, 3.0);
        std::printf("sphere (%s): near max %.4f, far max %.4f, mean %.4f voxels, %zu active\n",
                    cpu ? "cpu" : "opencl", e.nearMax, e.farMax, e.mean, e.active);
        expectAccurate(e, "sphere");
        EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
    }
}

TEST(BakeAccuracy, CapsuleMatchesItsExactDistance)
{
    BlobTree tree;
    const glm::dvec3 a(-0.3, -0.2, 0.1), b(0.4, 0.5, -0.2);
    const double r = 0.17;
    tree.setRoot(tree.segment(a, b, r));
    tree.finalize();
    const double h = 0.01;
    const BakedGrids g = bakeTree(tree, h);
    auto exact = [&](const glm::dvec3& p) {
        const double t = std::clamp(glm::dot(p - a, b - a) / glm::dot(b - a, b - a), 0.0, 1.0);
        return glm::length(p - (a + t * (b - a))) - r;
    };
    Box box;
    box.expand(a);
    box.expand(b);
    const Errors e = compareWithExact(*g.surface, exact, box.padded(r), h, 3.0);
    std::printf("capsule: near max %.4f, far max %.4f, mean %.4f voxels, %zu active\n", e.nearMax, e.farMax,
                e.mean, e.active);
    expectAccurate(e, "capsule");
    EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
}

/// Exact signed distance to cambium's cone: in the (axial s, radial rho) half
/// plane the surface is the segment from (0, r0) to (L, r1) and the cap arcs of
/// radius r0 around (0, 0) for s <= 0 and r1 around (L, 0) for s >= L.
double coneDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, double r0, double r1,
                    bool inside)
{
    const glm::dvec3 u = glm::normalize(b - a);
    const double L = glm::length(b - a);
    const double s = glm::dot(p - a, u), rho = glm::length((p - a) - s * u);
    auto segDist = [](double px, double py, double ax, double ay, double bx, double by) {
        const double t = std::clamp(((px - ax) * (bx - ax) + (py - ay) * (by - ay)) /
                                        ((bx - ax) * (bx - ax) + (by - ay) * (by - ay)), 0.0, 1.0);
        return std::hypot(px - ax - t * (bx - ax), py - ay - t * (by - ay));
    };
    double d = segDist(s, rho, 0.0, r0, L, r1);
    d = std::min(d, s <= 0.0 ? std::abs(std::hypot(s, rho) - r0) : std::hypot(s, rho - r0));
    d = std::min(d, s >= L ? std::abs(std::hypot(s - L, rho) - r1) : std::hypot(s - L, rho - r1));
    return inside ? -d : d;
}

TEST(BakeAccuracy, ConeMatchesItsExactDistance)
{
    BlobTree tree;
    const glm::dvec3 a(0.0, -0.4, 0.05), b(0.1, 0.6, -0.05);
    const double r0 = 0.2, r1 = 0.08;
    tree.setRoot(tree.cone(a, b, r0, r1));
    tree.finalize();
    ReferenceEvaluator ref(tree);
    const double h = 0.01;
    const BakedGrids g = bakeTree(tree, h);
    Box box;
    box.expand(a);
    box.expand(b);
    const Errors e = compareWithExact(
        *g.surface, [&](const glm::dvec3& p) { return coneDistance(p, a, b, r0, r1, ref.value(p) > 0.5); },
        box.padded(r0), h, 3.0);
    std::printf("cone: near max %.4f, far max %.4f, mean %.4f voxels, %zu active\n", e.nearMax, e.farMax, e.mean,
                e.active);
    expectAccurate(e, "cone");
    EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
}

}  // namespace
