// The baked level set: exact signed distances for a sphere, a capsule and a
// cone over the whole band; OpenVDB's own level-set checks; a complete band on
// blends, PCM, CSG and GBB scenes (dense brute force); write / read round trip.
#include "bake/levelset.h"
#include "bake/topology.h"
#include "core/files.h"
#include "core/system.h"
#include "blobtree/scene_io.h"
#include "io/vdb.h"

#include "blobtree/bounds.h"
#include "blobtree/evaluator.h"
#include "bake_util.h"
#include "scenes.h"
#include "test_util.h"
#include "temp_dir.h"

#include <gtest/gtest.h>
#include <new>
#include <openvdb/io/File.h>
#include <openvdb/tools/Diagnostics.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <filesystem>
#include <fstream>
#include <numeric>
#include <random>
#include <unistd.h>
#include <sys/resource.h>
#include <sys/wait.h>

namespace {

using namespace cambium;
using namespace cambium::test;

struct Errors {
    double nearMax = 0.0;  // |error| in voxels where |d| < 1 voxel
    double farMax = 0.0;   // elsewhere in the band
    double mean = 0.0;
    size_t active = 0, missing = 0, extra = 0;
};

/// Compares a baked grid with an exact signed distance over every voxel of
/// the band's bounding box.
Errors compareWithExact(const openvdb::FloatGrid& grid,
                        const std::function<double(const glm::dvec3&)>& exact, const Box& bounds,
                        double h, double W)
{
    Errors e;
    auto acc = grid.getConstAccessor();
    const openvdb::Coord lo(int(std::floor(bounds.lo.x / h)) - int(W) - 2,
                            int(std::floor(bounds.lo.y / h)) - int(W) - 2,
                            int(std::floor(bounds.lo.z / h)) - int(W) - 2);
    const openvdb::Coord hi(int(std::ceil(bounds.hi.x / h)) + int(W) + 2,
                            int(std::ceil(bounds.hi.y / h)) + int(W) + 2,
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
                    if (std::abs(d) < W - 0.4)
                        ++e.missing;
                    EXPECT_EQ(acc.getValue(c), d < 0 ? -grid.background() : grid.background())
                        << "at " << c;
                    continue;
                }
                ++e.active;
                if (std::abs(d) > W + 0.4)
                    ++e.extra;
                const double err = std::abs(acc.getValue(c) / h - d);
                sum += err;
                (std::abs(d) < 1.0 ? e.nearMax : e.farMax) =
                    std::max(std::abs(d) < 1.0 ? e.nearMax : e.farMax, err);
            }
    e.mean = e.active ? sum / double(e.active) : 0.0;
    return e;
}

void expectAccurate(const Errors& e, const char* what)
{
    EXPECT_GT(e.active, 1000u) << what;
    EXPECT_LT(e.nearMax, 0.1) << what;  // the issue's bound near the surface
    EXPECT_LT(e.farMax, 0.4) << what;   // cambium's stated bound over the rest of the band
    EXPECT_LT(e.mean, 0.03) << what;
    EXPECT_EQ(e.missing, 0u) << what;
    EXPECT_EQ(e.extra, 0u) << what;
}

/// A red and a blue sphere of radius 0.3 at x = -0.3 and 0.3, blended.

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
        const Errors e = compareWithExact(
            *g.surface, [&](const glm::dvec3& p) { return glm::length(p - c) - r; },
            Box::around(c, r), h, 3.0);
        report("sphere ({}): near max {:.4f}, far max {:.4f}, mean {:.4f} voxels, {} active",
               cpu ? "cpu" : "opencl", e.nearMax, e.farMax, e.mean, e.active);
        expectAccurate(e, "sphere");
        EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
    }
}

/// A capsule from a to b of radius r, and its baked grid's errors against
/// its exact signed distance.
struct Capsule {
    glm::dvec3 a, b;
    double r;
    BlobTree tree() const
    {
        BlobTree t;
        t.setRoot(t.segment(a, b, r));
        t.finalize();
        return t;
    }
    Errors errors(const openvdb::FloatGrid& grid, double h) const
    {
        auto exact = [&](const glm::dvec3& p) {
            const double t = std::clamp(glm::dot(p - a, b - a) / glm::dot(b - a, b - a), 0.0, 1.0);
            return glm::length(p - (a + t * (b - a))) - r;
        };
        Box box;
        box.expand(a);
        box.expand(b);
        return compareWithExact(grid, exact, box.padded(r), h, 3.0);
    }
};

TEST(BakeAccuracy, CapsuleMatchesItsExactDistance)
{
    const Capsule c{{-0.3, -0.2, 0.1}, {0.4, 0.5, -0.2}, 0.17};
    const double h = 0.01;
    const BakedGrids g = bakeTree(c.tree(), h);
    const Errors e = c.errors(*g.surface, h);
    report("capsule: near max {:.4f}, far max {:.4f}, mean {:.4f} voxels, {} active", e.nearMax,
           e.farMax, e.mean, e.active);
    expectAccurate(e, "capsule");
    EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
}

TEST(BakeAccuracy, ThinTwigsMatchTheirExactDistance)
{
    // Twigs a voxel or two thick: the falloff spans two to four voxels, far
    // from linear at the voxels next to the surface, and the surface curves
    // away from its tangent planes within a voxel.  The first layer's
    // points come from two Newton steps (one linear in the field
    // overestimated outside by up to a fifth of a voxel), and the Euclidean
    // distance takes over from the plane where the radius is small.
    for (const double rv : {1.0, 1.5, 2.0}) {
        const double h = 0.01;
        const Capsule c{{-0.3, -0.2, 0.1}, {0.4, 0.5, -0.2}, rv * h};
        const BakedGrids g = bakeTree(c.tree(), h);
        const Errors e = c.errors(*g.surface, h);
        report("twig of radius {} voxels: near max {:.4f}, far max {:.4f}, mean {:.4f} voxels", rv,
               e.nearMax, e.farMax, e.mean);
        EXPECT_LT(e.nearMax, 0.1) << rv;  // linear in F and planes only: 0.26, 0.18, 0.14
        EXPECT_LT(e.farMax, 0.45) << rv;
        EXPECT_LT(e.mean, 0.04) << rv;  // then: 0.091, 0.064, 0.040
        EXPECT_EQ(e.missing, 0u) << rv;
    }
}

/// The distance (voxels) from p to the surface F = T of `ref`, where it is
/// within `reach` voxels: the nearest crossing of rays in 600 directions
/// (a Fibonacci sphere), then the best direction refined by a pattern search
/// on the sphere.  Independent of the bake: the reference evaluator, rays and
/// bisection only.
double rayDistance(const ReferenceEvaluator& ref, double T, const glm::dvec3& p, double h,
                   double reach)
{
    const bool inside = ref.value(p) > T;
    auto crossing = [&](const glm::dvec3& dir) {
        const double step = 0.05 * h;
        double lo = 0.0;
        for (double t = step; t <= reach * h; t += step) {
            if ((ref.value(p + t * dir) > T) != inside) {
                double hi = t;
                for (int i = 0; i < 30; ++i) {
                    const double mid = 0.5 * (lo + hi);
                    ((ref.value(p + mid * dir) > T) != inside ? hi : lo) = mid;
                }
                return 0.5 * (lo + hi);
            }
            lo = t;
        }
        return double(INFINITY);
    };
    const int n = 600;
    double best = INFINITY;
    glm::dvec3 bestDir(0.0);
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - (2.0 * i + 1.0) / n, r = std::sqrt(1.0 - z * z);
        const double phi = 2.39996322972865332 * i;  // the golden angle
        const glm::dvec3 dir(r * std::cos(phi), r * std::sin(phi), z);
        const double d = crossing(dir);
        if (d < best) {
            best = d;
            bestDir = dir;
        }
    }
    if (!std::isfinite(best))
        return INFINITY;
    // Refine: turn the direction about two axes across it while it shortens.
    glm::dvec3 u = glm::normalize(
        glm::cross(bestDir, std::abs(bestDir.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0)));
    for (double a = 0.05; a > 1e-4; a *= 0.5) {
        bool better = true;
        while (better) {
            better = false;
            const glm::dvec3 v = glm::cross(bestDir, u);
            for (const glm::dvec3& off : {u, -u, v, -v}) {
                const glm::dvec3 dir = glm::normalize(bestDir + a * off);
                const double d = crossing(dir);
                if (d < best) {
                    best = d;
                    bestDir = dir;
                    better = true;
                }
            }
            u = glm::normalize(glm::cross(bestDir, glm::cross(u, bestDir)));
        }
    }
    return best / h;
}

TEST(BakeAccuracy, BlendedJunctionsMatchTheirExactDistance)
{
    // A twig forking in two, three segments of 2.5 voxels radius blended by
    // summation: around the fork the field is a sum of falloffs, neither
    // linear in the distance nor the falloff of one argument, and its
    // gradient turns on the way to the surface.  The voxels next to the
    // surface there against the distance found by casting rays.
    const double h = 0.01, r = 2.5 * h;
    const glm::dvec3 fork(0.003, 0.002, -0.001);
    BlobTree t;
    const int stem = t.segment(fork - glm::dvec3(0.01, 0.3, 0.02), fork, r);
    const int left = t.segment(fork, fork + glm::dvec3(-0.15, 0.2, 0.05), r);
    const int right = t.segment(fork, fork + glm::dvec3(0.18, 0.17, -0.04), r);
    t.setRoot(t.op({NodeType::BLEND}, {stem, left, right}));
    t.finalize();
    const BakedGrids g = bakeTree(t, h);
    const ReferenceEvaluator ref(t);
    auto acc = g.surface->getConstAccessor();
    std::vector<openvdb::Coord> near;
    for (auto it = g.surface->cbeginValueOn(); it; ++it)
        if (std::abs(*it) < h &&
            glm::length(glm::dvec3(it.getCoord().x(), it.getCoord().y(), it.getCoord().z()) * h -
                        fork) < 8.0 * h)
            near.push_back(it.getCoord());
    ASSERT_GT(near.size(), 400u);
    // (The grid's values read here, on one thread: an accessor caches nodes
    // and must not be shared by the threads below.)
    std::vector<double> err(near.size());
    for (size_t i = 0; i < near.size(); ++i)
        err[i] = std::abs(acc.getValue(near[i])) / h;
    tbb::parallel_for(size_t(0), near.size(), [&](size_t i) {
        const glm::dvec3 p = glm::dvec3(near[i].x(), near[i].y(), near[i].z()) * h;
        err[i] = std::abs(err[i] - rayDistance(ref, t.threshold(), p, h, 1.8));
    });
    const double worst = *std::max_element(err.begin(), err.end());
    const double mean = std::accumulate(err.begin(), err.end(), 0.0) / double(err.size());
    report("fork of two twigs: {} voxels next to the surface, error max {:.4f}, mean {:.4f} voxels",
           near.size(), worst, mean);
    // The first step alone, with the voxel's gradient for the normal: 0.51 and 0.034.
    EXPECT_LT(worst, 0.15);
    EXPECT_LT(mean, 0.015);
}

TEST(BakeStreaming, ALongBranchIsBakedSlabBySlabAndStaysExact)
{
    // Twelve units of branch at 0.01: 19 slabs of 64 voxels, 150 layers of
    // leaves.  The bake holds the values and surface points of a few layers
    // at a time, not of the whole band, and the distances across the slabs'
    // borders are exact.
    const Capsule c{{0.003, 0.002, -0.001}, {12.0, 0.05, 0.02}, 0.1};
    const double h = 0.01;
    BakeOptions opt;
    opt.voxelSize = h;
    opt.layerGroupLeaves = 64;  // a layer is about 30 leaves here
    auto sampler = makeCpuSampler();
    const BakedGrids g = bakeLevelSet(FieldProgram::compile(c.tree()), *sampler, opt);
    const BakeStats& s = g.stats;
    report("long branch: {} leaves, values of {} held at most, {} of {} surface points",
           s.candidateLeaves, s.heldLeaves, s.heldSurfacePoints, s.surfacePoints);
    EXPECT_GT(s.heldLeaves, 0u);
    EXPECT_LT(double(s.heldLeaves), 0.25 * double(s.candidateLeaves));
    EXPECT_GT(s.heldSurfacePoints, 0u);
    EXPECT_LT(double(s.heldSurfacePoints), 0.25 * double(s.surfacePoints));
    const Errors e = c.errors(*g.surface, h);
    expectAccurate(e, "long branch");
    EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
}

TEST(BakeStreaming, ValuesAreHeldOnlyForTheLayersBeingSurfaced)
{
    // A layer's values serve the surface voxels of its own and the
    // neighbouring layers; the propagation of its slab (eight layers) reads
    // the inside bits. So the values of three layers at a time are held
    // (the layer being surfaced, the one before and the one after), not of
    // a slab and its neighbours (ten). (Reads of freed values would go
    // unseen here: the sanitized build, whose blocks come from the
    // allocator, is what catches them.)
    const Capsule c{{0.003, 0.002, -0.001}, {12.0, 0.05, 0.02}, 0.1};
    const double h = 0.01;
    BakeOptions opt;
    opt.voxelSize = h;
    opt.layerGroupLeaves = 1;  // every layer alone
    auto sampler = makeCpuSampler();
    const BakedGrids g = bakeLevelSet(FieldProgram::compile(c.tree()), *sampler, opt);
    const BakeStats& s = g.stats;
    const double perLayer = double(s.candidateLeaves) / (12.0 / (8 * h));  // about 16
    report("values of {} of {} leaves held at most: {:.1f} layers", s.heldLeaves, s.candidateLeaves,
           double(s.heldLeaves) / perLayer);
    EXPECT_GT(s.heldLeaves, 0u);
    EXPECT_LT(double(s.heldLeaves), 6.0 * perLayer);
    expectAccurate(c.errors(*g.surface, h), "long branch, a layer at a time");
}

/// Exact signed distance to cambium's cone: in the (axial s, radial rho) half
/// plane the surface is the segment from (0, r0) to (L, r1) and the cap arcs of
/// radius r0 around (0, 0) for s <= 0 and r1 around (L, 0) for s >= L.
double coneDistance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, double r0,
                    double r1, bool inside)
{
    const glm::dvec3 u = glm::normalize(b - a);
    const double L = glm::length(b - a);
    const double s = glm::dot(p - a, u), rho = glm::length((p - a) - s * u);
    auto segDist = [](double px, double py, double ax, double ay, double bx, double by) {
        const double t = std::clamp(((px - ax) * (bx - ax) + (py - ay) * (by - ay)) /
                                        ((bx - ax) * (bx - ax) + (by - ay) * (by - ay)),
                                    0.0, 1.0);
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
        *g.surface,
        [&](const glm::dvec3& p) { return coneDistance(p, a, b, r0, r1, ref.value(p) > 0.5); },
        box.padded(r0), h, 3.0);
    report("cone: near max {:.4f}, far max {:.4f}, mean {:.4f} voxels, {} active", e.nearMax,
           e.farMax, e.mean, e.active);
    expectAccurate(e, "cone");
    EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface), "");
}

// --- completeness on blends, PCM, CSG and GBB --------------------------------

/// Scenes of every kind of operator, about 40 voxels across at h = 0.04.
BlobTree completenessScene(int which)
{
    BlobTree t;
    switch (which) {
        case 0: {  // blend with a scar
            const int a = t.sphere({0, 0, 0}, 0.4),
                      b = t.cone({0.1, 0.1, 0}, {0.5, 0.6, 0.1}, 0.2, 0.08);
            const int scar = t.sphere({0.3, 0.0, 0.2}, 0.12, {-0.8, std::nullopt});
            t.setRoot(t.op({NodeType::BLEND}, {a, b, scar}));
            break;
        }
        case 1: {  // a PCM junction of three branches summed with the base
            const int base = t.cone({0, -0.6, 0}, {0, 0.0, 0}, 0.18, 0.15);
            Combiner pcm{NodeType::PCM};
            pcm.width = 0.2;
            const int j = t.op(pcm, {t.cone({0, 0.02, 0}, {0.05, 0.6, 0}, 0.13, 0.1),
                                     t.cone({0.03, 0.05, 0}, {0.45, 0.4, 0.1}, 0.09, 0.06),
                                     t.cone({-0.03, 0.05, 0.02}, {-0.35, 0.45, -0.2}, 0.08, 0.05)});
            t.setRoot(t.op({NodeType::BLEND}, {base, j}));
            break;
        }
        case 2: {  // CSG: a sphere minus a sphere, unioned with a capsule
            const int d = t.op({NodeType::DIFFERENCE},
                               {t.sphere({0, 0, 0}, 0.45), t.sphere({0.3, 0.2, 0}, 0.3)});
            t.setRoot(
                t.op({NodeType::UNION}, {d, t.segment({-0.5, -0.3, 0}, {0.4, -0.4, 0.2}, 0.1)}));
            break;
        }
        default: {  // GBB of PCM and blend, bounded by a sphere, inside a bend
            const int a = t.cone({0, -0.5, 0}, {0, 0.2, 0}, 0.2, 0.15),
                      b = t.cone({0, 0.0, 0}, {0.5, 0.4, 0}, 0.12, 0.08);
            const int bound = t.sphere({0.05, 0.05, 0}, 0.15, {1.5, 0.5});
            const int g = t.gbb(bound, {a, b});
            t.setRoot(t.bend({0, -0.5, 0}, {0, 0.5, 0}, {1, 0, 0}, 0.6, g));
            break;
        }
    }
    t.finalize();
    return t;
}

TEST(BakeCompleteness, NoBandVoxelMissingAndNoneOutside)
{
    const double h = 0.04, W = 3.0;
    for (int which = 0; which < 4; ++which) {
        SCOPED_TRACE(which);
        const BlobTree tree = completenessScene(which);
        const FieldProgram prog = FieldProgram::compile(tree);
        const BakedGrids g = bakeTree(tree, h, W, /*cpu=*/std::getenv("CAMBIUM_CPU") != nullptr);
        // The surface by brute force: F on every point of a grid four times
        // finer than the voxels, over the whole box; a point where F - T
        // changes sign between neighbours, found by linear interpolation.
        const double f = h / 4.0, T = tree.threshold();
        const Box box = prog.positiveBounds().padded(W * h + 2 * h);
        const glm::ivec3 n = glm::ivec3(glm::ceil(box.size() / f)) + 1;
        std::vector<float> F(size_t(n.x) * size_t(n.y) * size_t(n.z));
        auto at = [&](int x, int y, int z) {
            return (size_t(z) * size_t(n.y) + size_t(y)) * size_t(n.x) + size_t(x);
        };
        tbb::parallel_for(0, n.z, [&](int z) {
            for (int y = 0; y < n.y; ++y)
                for (int x = 0; x < n.x; ++x)
                    F[at(x, y, z)] = float(
                        prog.evaluate(prog.code(), box.lo + f * glm::dvec3(x, y, z)).value - T);
        });
        // Surface points binned into voxel-sized cells.
        const glm::ivec3 lo(glm::floor(box.lo / h)), hi(glm::ceil(box.hi / h));
        const glm::ivec3 nc = hi - lo + 1;
        std::vector<std::vector<glm::dvec3>> cells(size_t(nc.x) * size_t(nc.y) * size_t(nc.z));
        auto cellOf = [&](int x, int y, int z) {
            return (size_t(z - lo.z) * size_t(nc.y) + size_t(y - lo.y)) * size_t(nc.x) +
                   size_t(x - lo.x);
        };
        size_t surfacePoints = 0;
        for (int z = 0; z < n.z; ++z)
            for (int y = 0; y < n.y; ++y)
                for (int x = 0; x < n.x; ++x)
                    for (int k = 0; k < 3; ++k) {
                        const int x1 = x + (k == 0), y1 = y + (k == 1), z1 = z + (k == 2);
                        if (x1 >= n.x || y1 >= n.y || z1 >= n.z)
                            continue;
                        const float a = F[at(x, y, z)], b = F[at(x1, y1, z1)];
                        if ((a > 0) == (b > 0))
                            continue;
                        const double t = a / (a - b);
                        const glm::dvec3 p = box.lo + f * (glm::dvec3(x, y, z) +
                                                           t * glm::dvec3(x1 - x, y1 - y, z1 - z));
                        const glm::ivec3 c = glm::clamp(glm::ivec3(glm::floor(p / h)), lo, hi);
                        cells[cellOf(c.x, c.y, c.z)].push_back(p);
                        ++surfacePoints;
                    }
        ASSERT_GT(surfacePoints, 1000u);
        auto acc = g.surface->getConstAccessor();
        const int reach = int(W) + 2;
        // The nearest surface point to a voxel, within `reach` cells, found
        // ring by ring (cells at Chebyshev distance r from the voxel's own):
        // a point in ring r + 1 is farther than r * h, so once the nearest
        // found is within that, no farther ring can hold a nearer one.  (The
        // brute force over all 11^3 cells took 150 s of the sanitized tests.)
        // Each cell's Chebyshev distance to the nearest cell holding a point
        // (reach + 1 where none is within reach): the rings before it are empty.
        std::vector<int> empty(cells.size(), reach + 1);
        for (int x = lo.x; x <= hi.x; ++x)
            for (int y = lo.y; y <= hi.y; ++y)
                for (int z = lo.z; z <= hi.z; ++z)
                    if (!cells[cellOf(x, y, z)].empty())
                        empty[cellOf(x, y, z)] = 0;
        for (int k = 1; k <= reach; ++k) {
            std::vector<int> next = empty;
            for (int x = lo.x; x <= hi.x; ++x)
                for (int y = lo.y; y <= hi.y; ++y)
                    for (int z = lo.z; z <= hi.z; ++z)
                        for (int dz = std::max(lo.z, z - 1); dz <= std::min(hi.z, z + 1); ++dz)
                            for (int dy = std::max(lo.y, y - 1); dy <= std::min(hi.y, y + 1); ++dy)
                                for (int dx = std::max(lo.x, x - 1); dx <= std::min(hi.x, x + 1);
                                     ++dx)
                                    if (empty[cellOf(dx, dy, dz)] == k - 1)
                                        next[cellOf(x, y, z)] = std::min(next[cellOf(x, y, z)], k);
            empty = std::move(next);
        }
        auto nearest = [&](int x, int y, int z) {
            const glm::dvec3 v = h * glm::dvec3(x, y, z);
            double best = INFINITY;
            for (int r = empty[cellOf(x, y, z)];
                 r <= reach && !(r > 0 && best <= ((r - 1) * h) * ((r - 1) * h)); ++r)
                for (int dz = -r; dz <= r; ++dz)
                    for (int dy = -r; dy <= r; ++dy) {
                        // The shell only: all of a row on its faces, else its ends.
                        const int step =
                            std::abs(dz) == r || std::abs(dy) == r ? 1 : std::max(2 * r, 1);
                        for (int dx = -r; dx <= r; dx += step) {
                            const int cx = x + dx, cy = y + dy, cz = z + dz;
                            if (cx < lo.x || cy < lo.y || cz < lo.z || cx > hi.x || cy > hi.y ||
                                cz > hi.z)
                                continue;
                            // Nor a cell whose box is farther than the nearest yet.
                            auto gap = [h](double u, int c) {
                                return std::max({c * h - u, u - (c + 1) * h, 0.0});
                            };
                            const double gx = gap(v.x, cx), gy = gap(v.y, cy), gz = gap(v.z, cz);
                            if (gx * gx + gy * gy + gz * gz >= best)
                                continue;
                            for (const auto& p : cells[cellOf(cx, cy, cz)])
                                best = std::min(best, glm::dot(p - v, p - v));
                        }
                    }
            return std::sqrt(best) / h;  // voxels to the surface
        };
        size_t band = 0, missing = 0, outside = 0;
        for (int x = lo.x; x <= hi.x; ++x)
            for (int y = lo.y; y <= hi.y; ++y)
                for (int z = lo.z; z <= hi.z; ++z) {
                    const double d = nearest(x, y, z);
                    const bool active = acc.isValueOn(openvdb::Coord(x, y, z));
                    band += d < W;
                    // Band membership is decided by the baked distance, exact
                    // to 0.15 voxel on smooth surfaces and to 0.75 voxel next
                    // to creases and saddles (docs/baking.md).
                    if (d < W - 0.75 && !active)
                        ++missing;
                    if (active && d > W + 0.75) {
                        ++outside;
                        if (std::getenv("CAMBIUM_DEBUG") && outside < 6)
                            report("outside: voxel {} {} {} true {:.3f} baked {:.3f} voxels", x, y,
                                   z, d, acc.getValue(openvdb::Coord(x, y, z)) / h);
                    }
                }
        EXPECT_GT(band, 2000u);
        EXPECT_EQ(missing, 0u) << "band voxels left inactive";
        EXPECT_EQ(outside, 0u) << "active voxels outside the band";
        // All of OpenVDB's checks but the Eikonal one: next to a crease or a
        // medial axis inside the band (CSG edges, PCM ridges) a true distance
        // function's finite-difference gradient is not of unit length.
        EXPECT_EQ(openvdb::tools::checkLevelSet(*g.surface, 8), "");
    }
}

// --- colour ------------------------------------------------------------------------

TEST(BakeColour, TwoColoursGiveCdOnEveryBandVoxel)
{
    // A red and a blue sphere blended: Cd is defined on exactly the band's
    // voxels, red at the red sphere's far side, blue at the blue one's, and a
    // field-weighted mix (r + b = 1, g = 0) everywhere.
    const BlobTree t = redAndBlueSpheres();
    ASSERT_FALSE(FieldProgram::compile(t).uniformColor());
    const double h = 0.02;
    for (bool cpu : {true, false}) {
        const BakedGrids g = bakeTree(t, h, 3.0, cpu, false, ColourExtent::Band);
        EXPECT_TRUE(g.color->tree().hasSameTopology(g.surface->tree()));
        EXPECT_GT(g.color->activeVoxelCount(), 1000u);
        for (auto it = g.color->cbeginValueOn(); it; ++it) {
            const openvdb::Vec3f c = *it;
            ASSERT_NEAR(c.x() + c.z(), 1.0, 0.01) << it.getCoord();
            ASSERT_NEAR(c.y(), 0.0, 1e-6) << it.getCoord();
        }
        auto acc = g.color->getConstAccessor();
        // The spheres' far poles: where the x axis first enters the surface.
        ReferenceEvaluator ref(t);
        for (int side : {-1, 1}) {
            int x = side * 60;
            while (ref.value(glm::dvec3(x * h, 0, 0)) < 0.5)
                x -= side;
            openvdb::Coord c(x, 0, 0);
            ASSERT_TRUE(acc.isValueOn(c)) << c;
            const openvdb::Vec3f v = acc.getValue(c);
            EXPECT_NEAR(side < 0 ? v.x() : v.z(), 1.0, 0.02) << c;
        }
    }
}

namespace {

/// Whether voxel c is a corner of a cell whose corners lie on both sides of
/// the level set (value < 0 inside, as volumeToMesh takes it).
bool cornerOfACrossedCell(openvdb::FloatGrid::ConstAccessor& acc, const openvdb::Coord& c)
{
    for (int cx = -1; cx <= 0; ++cx)
        for (int cy = -1; cy <= 0; ++cy)
            for (int cz = -1; cz <= 0; ++cz) {
                int inside = 0;
                for (int k = 0; k < 8; ++k)
                    inside += acc.getValue(c.offsetBy(cx + (k & 1), cy + ((k >> 1) & 1),
                                                      cz + (k >> 2))) < 0.0f;
                if (inside > 0 && inside < 8)
                    return true;
            }
    return false;
}

/// Shell Cd against band Cd of the same bake: on every corner of every
/// crossed cell shell Cd is on (a voxel or a tile) and within a step of 8-bit
/// colour of the band's (equal off the tiles); off them no voxel is on.
void expectShellHoldsTheBandsColours(const BakedGrids& shell, const BakedGrids& band,
                                     const std::string& what)
{
    auto s = shell.surface->getConstAccessor();
    auto cs = shell.color->getConstAccessor();
    auto cb = band.color->getConstAccessor();
    size_t corners = 0, tiled = 0, missing = 0, differ = 0, outside = 0;
    for (auto it = band.color->cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        const bool corner = cornerOfACrossedCell(s, c);
        if (!corner) {
            outside += cs.isValueOn(c) && cs.getValueDepth(c) == 3;  // a voxel, not a tile
            continue;
        }
        ++corners;
        if (!cs.isValueOn(c)) {
            ++missing;
            continue;
        }
        const bool tile = cs.getValueDepth(c) != 3;
        tiled += tile;
        const openvdb::Vec3f d = cs.getValue(c) - cb.getValue(c);
        const float most = std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])});
        differ += tile ? most > 1.0f / 255.0f + 1e-6f : most != 0.0f;
    }
    EXPECT_GT(corners, 1000u) << what;
    EXPECT_EQ(missing, 0u) << what << ": crossed cells' corners without colour";
    EXPECT_EQ(differ, 0u) << what << ": colours that differ from the band's";
    EXPECT_EQ(outside, 0u) << what << ": colour voxels off the shell";
    EXPECT_GT(tiled, 0u) << what;
    // Less than the band holds.
    EXPECT_LT(shell.color->tree().leafCount(), band.color->tree().leafCount()) << what;
}

}  // namespace

TEST(BakeColour, TheShellHoldsTheBandsColoursWhereTheSurfaceReadsThem)
{
    // Cd where a trilinear lookup on the surface reads it (the corners of
    // the cells the surface crosses), the band's values there, leaves of one
    // colour as tiles: on the CPU and OpenCL, packed for the file or not, at
    // the default half-width and a wide band; and what the file holds of it.
    openvdb::initialize();
    const BlobTree t = redAndBlueSpheres();
    for (bool cpu : {true, false})
        for (double W : {3.0, 6.0}) {
            const std::string what = fmt::format("{}, half-width {}", cpu ? "cpu" : "opencl", W);
            const BakedGrids band = bakeTree(t, 0.01, W, cpu, false, ColourExtent::Band);
            const BakedGrids shell = bakeTree(t, 0.01, W, cpu, false, ColourExtent::Shell);
            expectIdentical(*shell.surface, *band.surface, what + ": the level set");
            expectShellHoldsTheBandsColours(shell, band, what);
            // Packed, its file holds the same grids.
            const BakedGrids packed = bakeTree(t, 0.01, W, cpu, false, ColourExtent::Shell, true);
            const std::string path =
                (freshDir("cambium_shell") / (cpu ? "cpu.vdb" : "cl.vdb")).string();
            VdbFileInfo info;
            writeVdb(packed, path, info);
            const LevelSetGrids read = readLevelSet(path);
            expectIdentical(*read.color, *shell.color, what + ": Cd in the file");
            EXPECT_EQ(read.color->tree().activeTileCount(), shell.color->tree().activeTileCount());
        }
    // --colour none: no Cd.
    EXPECT_FALSE(bakeTree(t, 0.02, 3.0, true, false, ColourExtent::None).color);
}

TEST(BakeColour, ColourMadeWholeIsKeptOnTheShellToo)
{
    // A photo's colours and a mesh's are made on the whole band, then kept on
    // the shell (keepColourShell): the same rule as the bake's own.
    openvdb::initialize();
    const BlobTree t = redAndBlueSpheres();
    const BakedGrids band = bakeTree(t, 0.01, 3.0, true, false, ColourExtent::Band);
    BakedGrids kept = bakeTree(t, 0.01, 3.0, true, false, ColourExtent::Band);
    keepColourShell(kept);
    expectShellHoldsTheBandsColours(kept, band, "keepColourShell");
    const BakedGrids shell = bakeTree(t, 0.01, 3.0, true, false, ColourExtent::Shell);
    expectIdentical(*kept.color, *shell.color, "keepColourShell against the bake's shell");
}

TEST(BakeColour, OneColourIsTheBackgroundOfAnEmptyCdGrid)
{
    // Every primitive the same colour: the evaluator's colour is that colour
    // wherever the field is defined (blends normalise their weights, CSG picks
    // a child's), so Cd holds it as its background and no voxels.
    for (int which = 0; which < 4; ++which) {
        BlobTree t = completenessScene(which);
        const glm::dvec3 colour(0.25, 0.5, 0.125);
        t.setColor(t.root(), colour);
        t.finalize();
        const FieldProgram prog = FieldProgram::compile(t);
        ASSERT_TRUE(prog.uniformColor()) << which;
        EXPECT_EQ(*prog.uniformColor(), colour);
        ReferenceEvaluator ref(t);
        std::mt19937 rng(which);
        std::uniform_real_distribution<double> u(-0.8, 0.8);
        int checked = 0;
        for (int k = 0; k < 20000; ++k) {
            const glm::dvec3 p(u(rng), u(rng), u(rng));
            const FieldSample s = ref.sample(p);
            if (s.value > 0.2) {
                ++checked;
                ASSERT_NEAR(glm::length(s.color - colour), 0.0, 1e-9) << which;
            }
        }
        EXPECT_GT(checked, 100);
        auto sampler = makeCpuSampler();
        BakeOptions o;
        o.voxelSize = 0.04;
        const BakedGrids g = bakeLevelSet(prog, *sampler, o);
        EXPECT_EQ(g.color->activeVoxelCount(), 0u);
        EXPECT_EQ(g.color->tree().leafCount(), 0u);
        EXPECT_EQ(g.color->background(), openvdb::Vec3f(0.25f, 0.5f, 0.125f));
        EXPECT_GT(g.surface->activeVoxelCount(), 1000u);
    }
}

// --- round trip ------------------------------------------------------------------

TEST(BakeRoundTrip, AFileEncodedShortOfMemoryEndsInBadAllocNotInCutBytes)
{
    // A stream swallows its buffer's exceptions: short of memory, the
    // serial writer returned a file cut short, and the parallel packing cut
    // leaves short ("a packed leaf shorter than its header": a tile merge,
    // sweep 26).  Both must end in bad_alloc.  4,000 leaves of values that
    // do not compress (8 MB) are encoded with 3 MB of room (in a child, on
    // one thread: TBB's workers do not survive a fork).
    openvdb::initialize();
    for (bool parallel : {false, true}) {
        const int status = test::statusUnderAddressSpaceLimit(5e8, [parallel] {
            LevelSetGrids g;
            g.surface = openvdb::FloatGrid::create(0.3f);
            g.surface->setGridClass(openvdb::GRID_LEVEL_SET);
            g.surface->setName("surface");
            std::mt19937 rng(7);
            std::uniform_real_distribution<float> value(-0.3f, 0.3f);
            auto acc = g.surface->getAccessor();
            for (int leaf = 0; leaf < 4000; ++leaf)
                for (int v = 0; v < 512; ++v)
                    acc.setValue(openvdb::Coord(leaf * 8 + (v & 7), (v >> 3) & 7, v >> 6),
                                 value(rng));
            const MemoryLimits now = memoryLimits();
            const rlimit limit{rlim_t(now.addressSpaceUsed + 3e6),
                               rlim_t(now.addressSpaceUsed + 3e6)};
            if (::setrlimit(RLIMIT_AS, &limit) != 0)
                return 6;
            // Room the limit cannot take away is taken first: the heaps of
            // other threads' malloc arenas, mapped already (run after the
            // reader's tests in one process, the 8 MB fitted in a worker's),
            // and a reserve an earlier test may have installed
            // (installMemoryReserve); then 3 MB is given back.
            std::set_new_handler(nullptr);
            std::vector<void*> taken;
            while (void* p = ::malloc(size_t(1) << 20))
                taken.push_back(p);
            for (int k = 0; k < 3 && !taken.empty(); ++k) {
                ::free(taken.back());
                taken.pop_back();
            }
            tbb::task_arena one(1);
            return one.execute([&] {
                try {
                    VdbFileInfo info;
                    const std::vector<char> bytes = encodeVdb(g, info, parallel);
                    return bytes.size() < 4000u * 2048u ? 3 : 1;
                } catch (const std::bad_alloc&) {
                    return 0;
                } catch (const std::logic_error&) {
                    return 2;
                }
            });
        });
        if (status == -1)
            GTEST_SKIP() << "no address-space limit to try (ASan, or a limit set already)";
        EXPECT_EQ(status, 0) << "parallel " << parallel
                             << ": 1 it fitted, 2 leaves cut short, 3 a file cut short, "
                                "6 no limit, 128 a signal";
    }
}

TEST(BakeRoundTrip, TheParallelWriterWritesOpenVDBsOwnBytes)
{
    // Two coloured spheres (surface, Cd with many colours, density), with
    // and without halves: the leaves compressed on all cores give the bytes
    // of OpenVDB's serial writer past the header's random UUID (byte 57).
    openvdb::initialize();
    const BakedGrids g = bakeTree(redAndBlueSpheres(), 0.007, 3.0, true, /*fog=*/true);
    ASSERT_GT(g.surface->tree().leafCount(), 4 * 256u);  // several blocks of leaves
    ASSERT_GT(g.color->activeVoxelCount(), 1000u);
    for (bool half : {false, true}) {
        VdbFileInfo info;
        info.scene = "two spheres";
        info.half = half;
        const std::vector<char> ours = encodeVdb(g, info, true), theirs = encodeVdb(g, info, false);
        ASSERT_EQ(ours.size(), theirs.size()) << "half " << half;
        constexpr size_t kUuidEnd = 57;
        EXPECT_FALSE(std::equal(ours.begin(), ours.begin() + kUuidEnd, theirs.begin()));
        EXPECT_TRUE(std::equal(ours.begin() + kUuidEnd, ours.end(), theirs.begin() + kUuidEnd))
            << "half " << half;
        // writeVdb streams the same bytes into its file, checksum patched in.
        const std::string path = (std::filesystem::temp_directory_path() /
                                  ("cambium_pw_" + std::to_string(::getpid()) + ".vdb"))
                                     .string();
        writeVdb(g, path, info);
        std::ifstream in(path, std::ios::binary);
        const std::vector<char> file((std::istreambuf_iterator<char>(in)),
                                     std::istreambuf_iterator<char>());
        ASSERT_EQ(file.size(), theirs.size());
        EXPECT_TRUE(std::equal(file.begin() + kUuidEnd, file.end(), theirs.begin() + kUuidEnd));
        EXPECT_TRUE(verifyVdbChecksum(path, inspectVdb(path)));
        std::filesystem::remove(path);
    }
}

TEST(BakeRoundTrip, APackedBakeWritesTheBytesItsValuesWould)
{
    // A bake that serialises its leaves as it finishes them (the command's
    // way: the grid never holds its values) writes the file the values would
    // give OpenVDB's own writer, past the UUID: the buffers, the delayed-load
    // metadata read from them, the statistics counting the absent values, and
    // the flood fill above the leaves from their first and last signs.  A
    // coloured model (Cd packed too) and one of a single colour.
    openvdb::initialize();
    struct Case {
        const char* name;
        BlobTree tree;
        double h;
    };
    const Case cases[] = {{"two spheres", redAndBlueSpheres(), 0.007},
                          {"junction", completenessScene(1), 0.01}};
    for (const Case& c : cases)
        for (bool half : {false, true}) {
            SCOPED_TRACE(std::string(c.name) + (half ? ", half" : ""));
            const BakedGrids values = bakeTree(c.tree, c.h);
            const FieldProgram prog = FieldProgram::compile(c.tree);
            auto sampler = makeCpuSampler();
            BakeOptions o;
            o.voxelSize = c.h;
            o.pack = true;
            o.half = half;
            const BakedGrids packed = bakeLevelSet(prog, *sampler, o);
            ASSERT_TRUE(packed.surfacePacked);
            EXPECT_EQ(bool(packed.colorPacked), values.color->tree().leafCount() > 0);
            EXPECT_EQ(packed.stats.activeVoxels, values.stats.activeVoxels);
            EXPECT_GT(packed.surfacePacked->size(), 0u);
            // The leaves hold no values; the tiles inside were filled.
            for (auto it = packed.surface->tree().cbeginLeaf(); it; ++it)
                ASSERT_EQ(it->buffer().memUsage(), sizeof(it->buffer()));
            size_t insideTiles = 0;
            for (auto it = packed.surface->tree().cbeginValueAll(); it; ++it)
                insideTiles += !it.isVoxelValue() && *it < 0.0f;
            EXPECT_GT(insideTiles, 0u);
            VdbFileInfo info;
            info.scene = c.name;
            info.half = half;
            const std::vector<char> ours = encodeVdb(packed, info),
                                    theirs = encodeVdb(values, info, false);
            ASSERT_EQ(ours.size(), theirs.size());
            constexpr size_t kUuidEnd = 57;
            EXPECT_TRUE(std::equal(ours.begin() + kUuidEnd, ours.end(), theirs.begin() + kUuidEnd));
            // A packed grid is refused where its halves differ from the file's.
            info.half = !half;
            EXPECT_THROW(encodeVdb(packed, info), std::logic_error);
        }
}

TEST(BakeRoundTrip, GridsNamesClassesAndMetadataSurviveTheFile)
{
    openvdb::initialize();
    const BakedGrids g = bakeTree(completenessScene(1), 0.04, 3.0, true, /*fog=*/true);
    for (bool half : {false, true}) {
        const std::string path = (std::filesystem::temp_directory_path() /
                                  (std::string(half ? "cambium_rt_half_" : "cambium_rt_") +
                                   std::to_string(::getpid()) + ".vdb"))
                                     .string();
        VdbFileInfo info;
        info.scene = "junction";
        info.frame = 7;
        info.time = 0.7;
        info.half = half;
        writeVdb(g, path, info);
        EXPECT_FALSE(std::filesystem::exists(temporaryPathFor(path)));
        // The structure check walks the file as OpenVDB wrote it: three
        // grids, the last ending where the file ends.
        const VdbSummary summary = inspectVdb(path);
        ASSERT_EQ(summary.grids.size(), 3u);
        EXPECT_EQ(summary.grids[0].name, "surface");
        EXPECT_EQ(uint64_t(summary.grids.back().end), std::filesystem::file_size(path));
        EXPECT_EQ(summary.strings.at("creator").rfind("cambium", 0), 0u);
        // Its checksum holds, and any byte changed after it is found before
        // OpenVDB decodes a tree.
        EXPECT_TRUE(verifyVdbChecksum(path, summary));
        {
            const std::string flipped = path + ".flipped.vdb";
            std::filesystem::copy_file(path, flipped,
                                       std::filesystem::copy_options::overwrite_existing);
            std::fstream f(flipped, std::ios::in | std::ios::out | std::ios::binary);
            const auto at = std::streamoff(std::filesystem::file_size(path) * 2 / 3);
            f.seekg(at);
            const char c = char(f.get());
            f.seekp(at);
            f.put(char(c ^ 0x10));
            f.close();
            EXPECT_NO_THROW(inspectVdb(flipped));  // the structure is whole
            EXPECT_THROW(verifyVdbChecksum(flipped, inspectVdb(flipped)), InputError);
            EXPECT_THROW(readLevelSet(flipped), InputError);
            std::filesystem::remove(flipped);
        }
        {
            // The digest is 16 hex digits; any other text in its place
            // verifies nothing.
            const std::string bad = path + ".digest.vdb";
            std::filesystem::copy_file(path, bad,
                                       std::filesystem::copy_options::overwrite_existing);
            std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
            f.seekp(std::streamoff(summary.checksumEnd - 16));
            f.write("-000000000000001", 16);
            f.close();
            EXPECT_THROW(verifyVdbChecksum(bad, inspectVdb(bad)), InputError);
            std::filesystem::remove(bad);
        }
        openvdb::io::File file(path);
        file.open();
        auto names = file.getGrids();
        auto surface = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("surface"));
        auto cd = openvdb::gridPtrCast<openvdb::Vec3fGrid>(file.readGrid("Cd"));
        auto density = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("density"));
        file.close();
        ASSERT_EQ(names->size(), 3u);
        ASSERT_TRUE(surface && cd && density);
        EXPECT_EQ(cd->getName(), "Cd");
        EXPECT_EQ(density->getName(), "density");
        EXPECT_EQ(surface->getGridClass(), openvdb::GRID_LEVEL_SET);
        EXPECT_EQ(density->getGridClass(), openvdb::GRID_FOG_VOLUME);
        EXPECT_DOUBLE_EQ(surface->voxelSize()[0], 0.04);
        EXPECT_EQ(surface->activeVoxelCount(), g.surface->activeVoxelCount());
        EXPECT_EQ(cd->activeVoxelCount(), g.color->activeVoxelCount());
        EXPECT_EQ(surface->metaValue<std::string>("cambium_scene"), "junction");
        EXPECT_EQ(surface->metaValue<int64_t>("cambium_frame"), 7);
        EXPECT_DOUBLE_EQ(surface->metaValue<double>("cambium_time"), 0.7);
        EXPECT_DOUBLE_EQ(surface->metaValue<double>("cambium_threshold"), 0.5);
        EXPECT_NO_THROW(surface->metaValue<openvdb::Vec3i>("file_bbox_min"));  // statistics
        auto a = g.surface->getConstAccessor();
        for (auto it = surface->cbeginValueOn(); it; ++it)
            EXPECT_NEAR(*it, a.getValue(it.getCoord()), half ? 1e-3 * 0.12 : 0.0);
        std::filesystem::remove(path);
    }
}

}  // namespace

TEST(Topology, LeafProgramsPastMemoryAreRefusedWhileTheyAreMade)
{
    // PCM keeps every child whose field reaches a leaf in the leaf's program:
    // 2000 segments fanned out from one cone made programs of 3,900
    // instructions in 30,000 leaves, and the bake ran out of memory after
    // the estimate (from the primitives' areas) said 433 MB (sweep 11).  (The
    // fan now keeps only the segments that reach each leaf; a ball of 2000
    // segments that all overlap still needs them all everywhere.)  Under an
    // address-space limit 600 MB above what the process maps: the search
    // refuses by name, not out of memory.
    std::string scene = R"({"threshold": 0.5, "root": {"type": "pcm", "children": [)";
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.3, 0.3);
    for (int i = 0; i < 2000; ++i)
        scene += fmt::format(
            R"({}{{"type": "segment", "p0": [{:.6f}, {:.6f}, {:.6f}], "p1": [{:.6f}, {:.6f}, {:.6f}], "radius": 0.5}})",
            i ? ", " : "", u(rng), u(rng), u(rng), u(rng), u(rng), u(rng));
    scene += "]}}";
    const FieldProgram program = FieldProgram::compile(parseScene(scene, "fan.json"));
    expectRefusedUnderAddressSpaceLimit(
        600e6, [&] { findBandLeaves(program, 0.005, 3.0, {}, {}, "fan.json"); },
        [](const std::string& what) {
            return what.rfind("fan.json: the band's leaves' programs would take more than half the",
                              0) == 0;
        });
}
