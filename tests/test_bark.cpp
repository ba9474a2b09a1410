// Bark furrows on cones (kernels/cb_primitives.h, cb_bark_cone_field): the
// surface where the profile puts it, gradients against finite differences,
// the program interpreter against the reference evaluator, the detail limit,
// and the parameter checks.
#include "bake/levelset.h"
#include "bake/sampler.h"
#include "blobtree/bounds.h"
#include "model/tree_builder.h"
#include "field/program.h"
#include "test_util.h"

#include "cb_primitives.h"

#include <gtest/gtest.h>
#include <openvdb/tools/Interpolation.h>

namespace {

using namespace cambium;
using namespace cambium::test;

BarkParams bark(double depth)
{
    BarkParams b;
    b.depth0 = b.depth1 = depth;
    b.reference = {0.0, 0.0, 1.0};
    b.s0 = 0.7;
    b.around = 6;
    b.along = 9.0;
    b.phase = 0.37;
    return b;
}

/// A cylinder along x of radius 0.2 from 0 to 1, with bark of `depth`.
BlobTree barkCylinder(double depth, double limit = 0.0)
{
    BlobTree t;
    const int c = t.cone({0, 0, 0}, {1, 0, 0}, 0.2, 0.2);
    if (depth > 0.0)
        t.setBark(c, bark(depth));
    t.setDetailLimit(limit);
    t.setRoot(c);
    t.finalize();
    return t;
}

}  // namespace

TEST(Bark, TheSurfaceLiesWhereTheProfilePutsIt)
{
    const double A = 0.02, r = 0.2;
    const BlobTree tree = barkCylinder(A);
    ReferenceEvaluator eval(tree);
    const BarkParams b = bark(A);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.1, 0.9), angle(-M_PI, M_PI);
    double deepest = 0.0;
    for (int i = 0; i < 200; ++i) {
        const double x = u(rng), theta = angle(rng);
        // theta from the reference (z) towards axis x reference = (1,0,0) x (0,0,1) = -y.
        const glm::dvec3 dir(0.0, -std::sin(theta), std::cos(theta));
        const double found = surfaceDistance(eval, 0.5, {x, 0, 0}, dir, 0.5);
        double ds, dt, dr;
        const double P =
            cb_bark_profile(b.s0 + x, theta, r, b.around, b.along, b.phase, 0.0, &ds, &dt, &dr);
        ASSERT_NEAR(found, r - A * P, 1e-9) << "x " << x << " theta " << theta;
        deepest = std::max(deepest, P);
    }
    EXPECT_GT(deepest, 0.8);  // furrows were met
}

TEST(Bark, GradientMatchesFiniteDifferencesAndTheProgramTheReference)
{
    for (double limit : {0.0, 0.15}) {
        const BlobTree tree = barkCylinder(0.02, limit);
        ReferenceEvaluator eval(tree);
        const FieldProgram prog = FieldProgram::compile(tree);
        ASSERT_EQ(prog.barkCount(), 1u);
        auto f = [&](const glm::dvec3& p) { return eval.value(p); };
        std::mt19937 rng(9);
        int agree = 0, checked = 0;
        for (int i = 0; i < 4000 && checked < 1000; ++i) {
            const glm::dvec3 p = randomIn(rng, {-0.3, -0.45, -0.45}, {1.3, 0.45, 0.45});
            const FieldSample s = eval.sample(p);
            const FieldSample q = prog.evaluate(prog.code(), p);
            ASSERT_EQ(q.value, s.value);  // the same formula in the same precision
            ASSERT_EQ(q.gradient, s.gradient);
            if (s.value == 0.0)
                continue;
            ++checked;
            const GradientCheck c = checkGradient(f, p, s.gradient, 1e-6, 2e-4);
            ASSERT_NE(c, GradientCheck::Disagrees)
                << "at " << p.x << " " << p.y << " " << p.z << " limit " << limit;
            agree += c == GradientCheck::Agrees;
        }
        EXPECT_GE(agree, checked * 95 / 100);
    }
}

TEST(Bark, OctavesShorterThanTheDetailLimitFadeOut)
{
    // 6 furrows around r = 0.2: wavelength 0.209 at the first octave.  A limit
    // above it leaves a plain cylinder; none keeps all three octaves.
    const BlobTree plain = barkCylinder(0.0), faded = barkCylinder(0.02, 0.25),
                   full = barkCylinder(0.02, 0.0);
    ReferenceEvaluator p(plain), f(faded), b(full);
    std::mt19937 rng(2);
    int differ = 0;
    for (int i = 0; i < 2000; ++i) {
        const glm::dvec3 x = randomIn(rng, {0.1, -0.3, -0.3}, {0.9, 0.3, 0.3});
        ASSERT_EQ(f.value(x), p.value(x));
        differ += b.value(x) != p.value(x);
    }
    EXPECT_GT(differ, 1000);
    // The interval bounds still hold the field (furrows only deepen).
    const FieldProgram prog = FieldProgram::compile(full);
    for (int i = 0; i < 200; ++i) {
        const glm::dvec3 c = randomIn(rng, {-0.2, -0.4, -0.4}, {1.2, 0.4, 0.4});
        const Box box{c - 0.03, c + 0.03};
        const Interval iv = prog.specialize(prog.code(), box, nullptr);
        for (int k = 0; k < 20; ++k) {
            const double v = b.value(randomIn(rng, box.lo, box.hi));
            ASSERT_LE(iv.lo, v + 1e-12);
            ASSERT_GE(iv.hi, v - 1e-12);
        }
    }
}

TEST(Bark, BadParametersAreRefused)
{
    BlobTree t;
    const int c = t.cone({0, 0, 0}, {1, 0, 0}, 0.2, 0.1);
    BarkParams b = bark(0.02);
    b.depth1 = 0.04;  // 1.75 x 0.04 > half of 0.1
    expectInputError([&] { t.setBark(c, b); }, "reaches past half the cone's radii", "deep");
    b = bark(-0.01);
    expectInputError([&] { t.setBark(c, b); }, "must not be negative", "negative");
    b = bark(0.01);
    b.reference = {1, 0, 0};
    expectInputError([&] { t.setBark(c, b); }, "across the axis", "reference");
    b = bark(0.01);
    b.around = 2.5;
    expectInputError([&] { t.setBark(c, b); }, "whole number", "around");
    const int s = t.sphere({0, 0, 0}, 1.0);
    expectInputError([&] { t.setBark(s, bark(0.01)); }, "is for cones", "sphere");
}

// ---- Bark on grown trees (model/tree_builder.cpp, BarkDetail).

namespace {

/// A trunk of three internodes growing thicker: at `year`, radii grow with
/// age (r = 0.03 sqrt(age)), the base internode oldest.
Skeleton growingTrunk(double year)
{
    Skeleton sk;
    const double ages[3] = {year, year - 1.0, year - 2.0};
    for (int i = 0; i < 3; ++i) {
        const double r0 = 0.03 * std::sqrt(ages[i]),
                     r1 = 0.03 * std::sqrt(std::max(ages[i] - 1.0, 0.5));
        Internode n = internode(i, i - 1, {0.0, 0.5 * i, 0.0}, {0.02 * i, 0.5 * (i + 1), 0.0}, r0,
                                r1, ages[i]);
        n.module = 0;
        sk.internodes.push_back(n);
    }
    return sk;
}

TreeBuildOptions barkOptions(double depth)
{
    TreeBuildOptions o;
    o.barkDetail.depth = depth;
    o.barkDetail.maxDepth = 0.02;
    o.barkDetail.startAge = 2.0;
    o.barkDetail.fullAge = 6.0;
    o.barkDetail.around = 10;
    o.barkDetail.along = 5.0;
    return o;
}

/// The surface's distance from (0, y, 0) in the direction of angle theta
/// in the xz plane, from a level set (the zero crossing along the ray).
double surfaceRadius(const openvdb::FloatGrid& g, double y, double theta, double from, double to)
{
    const auto acc = g.getConstAccessor();
    openvdb::tools::GridSampler<openvdb::FloatGrid::ConstAccessor, openvdb::tools::BoxSampler> s(
        acc, g.transform());
    auto phi = [&](double r) {
        return double(s.wsSample(openvdb::Vec3d(r * std::cos(theta), y, r * std::sin(theta))));
    };
    return bisect(phi, from, to, 60);
}

std::vector<double> standardised(std::vector<double> v)
{
    double mean = 0.0, var = 0.0;
    for (double x : v)
        mean += x;
    mean /= double(v.size());
    for (double x : v)
        var += (x - mean) * (x - mean);
    const double sd = std::sqrt(var / double(v.size()));
    for (double& x : v)
        x = (x - mean) / sd;
    return v;
}

double correlation(const std::vector<double>& a, const std::vector<double>& b, size_t shift = 0)
{
    double c = 0.0;
    for (size_t i = 0; i < a.size(); ++i)
        c += a[i] * b[(i + shift) % b.size()];
    return c / double(a.size());
}

}  // namespace

TEST(BarkOnTrees, DepthZeroIsTodaysTreeExactly)
{
    const Skeleton sk = growingTrunk(9.0);
    const FieldProgram plain = FieldProgram::compile(buildTree(sk, TreeBuildOptions{}));
    const FieldProgram none = FieldProgram::compile(buildTree(sk, barkOptions(0.0)));
    const FieldProgram bark = FieldProgram::compile(buildTree(sk, barkOptions(0.1)));
    EXPECT_TRUE(plain.identical(none));
    EXPECT_FALSE(plain.identical(bark));
    EXPECT_EQ(bark.barkCount(), 3u);
    // Young shoots (below start_age) stay smooth.
    // (Ages 3.5, 2.5 and 1.5: the youngest has none.)
    EXPECT_EQ(FieldProgram::compile(buildTree(growingTrunk(3.5), barkOptions(0.1))).barkCount(),
              2u);
}

TEST(BarkOnTrees, ThePatternStaysWithTheWoodAsTheTrunkThickens)
{
    // Two frames of a thickening trunk, baked: at each height the furrow
    // pattern around the trunk (surface radius by angle, standardised) is the
    // same pattern in both frames, at the same angles.
    openvdb::initialize();
    const double h = 0.003;
    auto sampler = makeCpuSampler();
    std::vector<openvdb::FloatGrid::Ptr> grids;
    std::vector<double> radius;
    for (double year : {8.0, 12.0}) {
        const FieldProgram prog =
            FieldProgram::compile(buildTree(growingTrunk(year), barkOptions(0.1)));
        BakeOptions opt;
        opt.voxelSize = h;
        grids.push_back(bakeLevelSet(prog, *sampler, opt).surface);
        radius.push_back(0.03 * std::sqrt(year));
    }
    const int n = 360;
    double worst = 1.0;
    for (double y : {0.2, 0.3, 0.4}) {
        std::vector<double> pattern[2];
        for (int f = 0; f < 2; ++f)
            for (int k = 0; k < n; ++k)
                pattern[f].push_back(surfaceRadius(*grids[size_t(f)], y, 2.0 * M_PI * k / n,
                                                   0.5 * radius[size_t(f)],
                                                   1.3 * radius[size_t(f)]));
        const auto a = standardised(pattern[0]), b = standardised(pattern[1]);
        const double same = correlation(a, b);
        // The best match is at no shift: the pattern did not turn.
        size_t best = 0;
        for (size_t s = 0; s < size_t(n); ++s)
            if (correlation(a, b, s) > correlation(a, b, best))
                best = s;
        report(
            "height {}: correlation {:.3f} between years 8 and 12, best at a shift of {} "
            "degrees; a shift of 9 degrees (a quarter furrow) gives {:.3f}",
            y, same, best > size_t(n / 2) ? int(best) - n : int(best), correlation(a, b, 9));
        EXPECT_TRUE(best <= 1 || best >= size_t(n - 1)) << "shift " << best;
        worst = std::min(worst, same);
    }
    EXPECT_GT(worst, 0.9);
}

TEST(BarkOnTrees, RidgesAndScarsStayMeasurable)
{
    // The ridge test's junction (test_sequence.cpp), old enough for the
    // ridge and for full-depth bark: the crotch moves from the blend's
    // surface to the ridge by about as much with bark as without.
    auto junction = [](double age) {
        Skeleton sk;
        sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 2, 0}, 0.3, 0.28, age),
                         internode(1, 0, {0, 2, 0}, {0, 4, 0}, 0.28, 0.25, age),
                         internode(2, 0, {0, 2, 0},
                                   glm::dvec3(0, 2, 0) + 2.0 * glm::normalize(glm::dvec3(1, 1, 0)),
                                   0.15, 0.12, age)};
        return sk;
    };
    auto crotch = [](const BlobTree& tree) {
        const ReferenceEvaluator e(tree);
        const glm::dvec3 from(0.1, 2.2, 0.0), dir = glm::normalize(glm::dvec3(0.52, 0.855, 0.0));
        return bisect([&](double s) { return e.sample(from + s * dir).value - 0.5; }, 0.0, 0.8);
    };
    TreeBuildOptions plain;
    plain.ridgeYears = 8.0;
    TreeBuildOptions bark = barkOptions(0.05);
    bark.ridgeYears = 8.0;
    const double ridgePlain =
        crotch(buildTree(junction(12.0), plain)) - crotch(buildTree(junction(0.0), plain));
    const double ridgeBark =
        crotch(buildTree(junction(12.0), bark)) - crotch(buildTree(junction(0.0), bark));
    const double furrow = 1.75 * 0.02;  // the deepest bark reaches
    report("ridge: {:.4f} without bark, {:.4f} with (furrows at most {:.4f})", ridgePlain,
           ridgeBark, furrow);
    EXPECT_GT(std::abs(ridgePlain), 2.0 * furrow);
    EXPECT_NEAR(ridgeBark, ridgePlain, furrow);

    // A scar pressed into furrowed bark: as deep, measured against the same
    // bark without it, as on smooth bark.
    auto trunkWithScar = [](const TreeBuildOptions& o, bool scar) {
        Skeleton sk;
        sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 2, 0}, 0.3, 0.28, 12.0)};
        if (scar) {
            Scar s;
            s.base = {0.0, 1.0, 0.0};
            s.tip = {0.30, 1.0, 0.0};
            s.radius = 0.06;
            s.parent = 0;
            sk.scars.push_back(s);
        }
        return buildTree(sk, o);
    };
    auto radiusAt = [](const BlobTree& t, const glm::dvec3& dir, double y) {
        const ReferenceEvaluator e(t);
        return bisect([&](double r) { return e.sample(glm::dvec3(0, y, 0) + r * dir).value - 0.5; },
                      0.1, 0.6);
    };
    const glm::dvec3 out(1, 0, 0);
    const TreeBuildOptions smooth;
    const double scarPlain = radiusAt(trunkWithScar(smooth, true), out, 1.0) -
                             radiusAt(trunkWithScar(smooth, false), out, 1.0);
    const TreeBuildOptions barked = barkOptions(0.05);
    const double scarBark = radiusAt(trunkWithScar(barked, true), out, 1.0) -
                            radiusAt(trunkWithScar(barked, false), out, 1.0);
    report("scar: {:.4f} on smooth bark, {:.4f} on furrowed bark", scarPlain, scarBark);
    // The scar presses in (its depth about the bark's furrows) and stays at
    // least half as deep on furrowed bark.
    EXPECT_LT(scarPlain, -0.02);
    EXPECT_LT(scarBark, 0.5 * scarPlain);
    EXPECT_NEAR(scarBark, scarPlain, furrow);
}
