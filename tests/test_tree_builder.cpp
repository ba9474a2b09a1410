// The tree builder's junction rules (papers 001/003): no bulge where a
// shortened basal internode meets its continuation, PCM ridges between
// branches without interpenetration, endpoint-preserving bends, and a
// bounded tree depth however large the skeleton.
#include "model/tree_builder.h"

#include "bake_util.h"
#include "core/math.h"
#include "test_util.h"
#include "model/turtle.h"
#include "io/vdb.h"
#include "use/world_sampler.h"

#include "blobtree/evaluator.h"
#include "core/error.h"
#include "temp_dir.h"
#include "core/files.h"
#include "model/load_model.h"
#include "field/program.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <filesystem>
#include <cstdio>

namespace {

using namespace cambium;

using test::internode;
using test::report;

/// Largest and smallest radius of the surface around the y axis for y in
/// [y0, y1] (two collinear internodes along y).
std::pair<double, double> radiusRange(const BlobTree& tree, double y0, double y1)
{
    const ReferenceEvaluator ev(tree);
    double lo = 1e9, hi = 0.0;
    for (double y = y0; y <= y1 + 1e-12; y += 0.002) {
        const double r = test::surfaceDistance(ev, tree.threshold(), {0, y, 0}, {1, 0, 0}, 1.0);
        lo = std::min(lo, r);
        hi = std::max(hi, r);
    }
    return {lo, hi};
}

TEST(TreeBuilder, ShorteningTheBasalInternodeRemovesTheBulge)
{
    // Two collinear internodes of equal radius r meeting at y = 1 (paper 001, 3.1).
    const double r = 0.1;
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 1, 0}, r, r),
                     internode(1, 0, {0, 1, 0}, {0, 2, 0}, r, r)};
    const auto [minWith, maxWith] = radiusRange(buildTree(sk), 0.5, 1.5);
    const auto [minWithout, maxWithout] = radiusRange(skeletonToBlend(sk), 0.5, 1.5);
    report(
        "joint of two cones of radius {:.2f}: with delta_A = 1.75 r the radius stays in [{:.4f}, "
        "{:.4f}] "
        "({:+.1f} % / {:+.1f} %); without, up to {:.4f} ({:+.1f} %)",
        r, minWith, maxWith, 100.0 * (minWith / r - 1.0), 100.0 * (maxWith / r - 1.0), maxWithout,
        100.0 * (maxWithout / r - 1.0));
    EXPECT_LT(maxWith / r - 1.0, 0.05);     // the bulge the papers call practically unnoticeable
    EXPECT_GT(minWith / r - 1.0, -0.05);    // and no waist in its place
    EXPECT_GT(maxWithout / r - 1.0, 0.15);  // the plain sum bulges visibly
}

TEST(TreeBuilder, AChainOfShortThickInternodesStaysFlat)
{
    // Old wood: internodes two radii long, shorter than twice delta_A. The
    // basal one gives half its length and its continuation the rest of delta_A
    // from its base: the chain's radius stays within a few percent (with the
    // basal shortening alone it bulged at every joint).
    const double r = 0.1, len = 0.2;
    Skeleton sk;
    for (int i = 0; i < 8; ++i)
        sk.internodes.push_back(internode(i, i - 1, {0, len * i, 0}, {0, len * (i + 1), 0}, r, r));
    const auto [lo, hi] = radiusRange(buildTree(sk), 2 * len, 6 * len);
    report("chain of internodes two radii long: radius in [{:.4f}, {:.4f}] ({:+.1f} % / {:+.1f} %)",
           lo, hi, 100.0 * (lo / r - 1.0), 100.0 * (hi / r - 1.0));
    EXPECT_LT(hi / r - 1.0, 0.05);
    EXPECT_GT(lo / r - 1.0, -0.05);
}

TEST(TreeBuilder, ConvolutionSegmentsJoinWithoutABulge)
{
    // Paper 002: connected convolution segments are a polyline: no rules needed.
    const double r = 0.1;
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 1, 0}, r, r),
                     internode(1, 0, {0, 1, 0}, {0, 2, 0}, r, r)};
    TreeBuildOptions o;
    o.primitives = TreeBuildOptions::Primitives::Convolution;
    const BlobTree t = buildTree(sk, o);
    for (const Node& nd : t.nodes())
        EXPECT_NE(nd.type, NodeType::CONE);
    // No bulge, and a waist under 2 %: the segments' windowed fields add up
    // almost to the one long segment's (the window is per segment).
    BlobTree one;
    one.setRoot(one.convolutionSegment({0, 0, 0}, {0, 2, 0}, r, r));
    one.finalize();
    const ReferenceEvaluator a(t), b(one);
    double worst = 0.0, lo = 1e9, hi = 0.0;
    for (double y = 0.6; y <= 1.4; y += 0.002) {
        const double ra = test::surfaceDistance(a, 0.5, {0, y, 0}, {1, 0, 0}, 1.0);
        const double rb = test::surfaceDistance(b, 0.5, {0, y, 0}, {1, 0, 0}, 1.0);
        worst = std::max(worst, std::abs(ra - rb) / r);
        lo = std::min(lo, ra);
        hi = std::max(hi, ra);
    }
    report(
        "joint of two convolution segments of radius {:.2f}: the radius stays in [{:.4f}, {:.4f}], "
        "at "
        "most {:.2f} % "
        "from one long segment's",
        r, lo, hi, 100.0 * worst);
    EXPECT_LT(worst, 0.02);
    EXPECT_LT(hi / r - 1.0, 0.01);   // no bulge
    EXPECT_GT(lo / r - 1.0, -0.02);  // a waist of under 2 %
}

TEST(TreeBuilder, BetterBlendingJoinsConeTrunksAndConvolutionLateralsWithLessBulge)
{
    // A cone trunk and a convolution lateral at 60 degrees (mixed primitives):
    // on the side of the trunk away from the lateral, summation swells the
    // trunk with the lateral's far field; better blending (eq. 6) keeps it.
    const double a = 60.0 * 3.14159265358979323846 / 180.0;
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 1, 0}, 0.1, 0.1),
                     internode(1, 0, {0, 1, 0}, {0, 2, 0}, 0.1, 0.1),
                     internode(2, 0, {0, 1, 0}, {std::sin(a), 1 + std::cos(a), 0}, 0.07, 0.05)};
    TreeBuildOptions o;
    o.primitives = TreeBuildOptions::Primitives::Mixed;
    const BlobTree mixed = buildTree(sk, o);
    int better = 0, conv = 0, cones = 0;
    for (const Node& nd : mixed.nodes()) {
        better += nd.type == NodeType::BETTER_BLEND;
        conv += nd.type == NodeType::CONVOLUTION_SEGMENT;
        cones += nd.type == NodeType::CONE;
    }
    EXPECT_EQ(better, 1);
    EXPECT_EQ(conv, 1);
    EXPECT_EQ(cones, 2);
    // The same primitives summed.
    BlobTree summed;
    std::vector<int> kids;
    for (const Node& nd : mixed.nodes())
        if (nd.type == NodeType::CONE)
            kids.push_back(summed.cone(nd.prim().p0, nd.prim().p1, nd.prim().r0, nd.prim().r1));
    kids.push_back(summed.convolutionSegment(sk.internodes[2].p0, sk.internodes[2].p1, 0.07, 0.05));
    summed.setRoot(summed.op({NodeType::BLEND}, kids));
    summed.finalize();
    auto swelling = [](const BlobTree& t) {
        const ReferenceEvaluator ev(t);
        double hi = 0.0;
        for (double y = 0.8; y <= 1.2; y += 0.005)
            hi = std::max(hi, test::surfaceDistance(ev, t.threshold(), {0, y, 0}, {-1, 0, 0}, 1.0));
        return hi / 0.1 - 1.0;
    };
    const double b = swelling(mixed), s = swelling(summed);
    report("trunk opposite a convolution lateral: {:+.1f} % with better blending, {:+.1f} % summed",
           100.0 * b, 100.0 * s);
    EXPECT_LT(b, s);
    EXPECT_LT(b, 0.03);
}

TEST(TreeBuilder, JunctionRulesFollowEquationsThreeSixAndSeven)
{
    TreeBuildOptions pcm, smooth;
    smooth.junction = TreeBuildOptions::Junction::Smooth;
    EXPECT_DOUBLE_EQ(basalShortening(pcm, 0.1, {0.08}, {0.06}), 1.75 * 0.06);  // eq. 3
    EXPECT_DOUBLE_EQ(basalShortening(pcm, 0.1, {0.08, 0.05}, {0.07, 0.04}),
                     2.75 * 0.08 - 0.1);  // eq. 7
    EXPECT_DOUBLE_EQ(basalShortening(smooth, 0.1, {0.08, 0.05}, {0.07, 0.04}), 1.75 * 0.07);
    // In the PCM tree the branches start delta_Bi = r_A - r_i from the branching point (eq. 6).
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 1, 0}, 0.12, 0.1),
                     internode(1, 0, {0, 1, 0}, {0, 2, 0}, 0.08, 0.06),
                     internode(2, 0, {0, 1, 0}, {0.6, 1.8, 0}, 0.05, 0.035)};
    const BlobTree t = buildTree(sk);
    int cones = 0, pcms = 0;
    for (const Node& nd : t.nodes()) {
        pcms += nd.type == NodeType::PCM;
        if (nd.type != NodeType::CONE)
            continue;
        ++cones;
        const Primitive& p = nd.prim();
        if (p.p0 == glm::dvec3(0.0)) {  // A: tip pulled back by 2.75 * 0.08 - 0.1 = 0.12
            EXPECT_NEAR(p.p1.y, 1.0 - 0.12, 1e-12);
        } else {
            const double d = glm::length(p.p0 - glm::dvec3(0, 1, 0));
            EXPECT_NEAR(d, p.r0 > 0.07 ? 0.1 - 0.08 : 0.1 - 0.05, 1e-3) << "branch base offset";
        }
    }
    EXPECT_EQ(cones, 3);
    EXPECT_EQ(pcms, 1);
}

/// A Y junction in the xy plane: a vertical basal internode and two
/// branches 35 degrees either side of it, built by the rules in `mode`.
BlobTree yJunction(TreeBuildOptions::Junction mode)
{
    const double a = 35.0 * 3.14159265358979323846 / 180.0;
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 1, 0}, 0.1, 0.09),
                     internode(1, 0, {0, 1, 0}, {std::sin(a), 1 + std::cos(a), 0}, 0.07, 0.06),
                     internode(2, 0, {0, 1, 0}, {-std::sin(a), 1 + std::cos(a), 0}, 0.07, 0.06)};
    TreeBuildOptions o;
    o.junction = mode;
    return buildTree(sk, o);
}

/// Where the vertical line at x (z = 0), going up from the branching point
/// (inside the junction), leaves the surface into the gap between the
/// branches (the crotch), and the unit outward normal there.
std::pair<double, glm::dvec3> crotchPoint(const BlobTree& t, double x)
{
    const ReferenceEvaluator ev(t);
    const double T = t.threshold();
    EXPECT_GE(ev.value({x, 1.0, 0}), T) << "the branching point is inside";
    double hi = 1.0;
    while (ev.value({x, hi, 0}) >= T && hi < 2.0)
        hi += 0.001;
    double in = hi - 0.001, out = hi;
    for (int i = 0; i < 50; ++i) {
        const double m = 0.5 * (in + out);
        (ev.value({x, m, 0}) >= T ? in : out) = m;
    }
    const FieldSample s = ev.sample({x, in, 0});
    return {in, -glm::normalize(s.gradient)};  // the field grows inwards
}

TEST(TreeBuilder, PcmMakesARidgeBetweenBranchesWhereSummationFillsTheCrotch)
{
    // Across the crotch line (x = 0), the surface's normals on either side
    // (x = +-e) turn sharply with PCM (a ridge) and gently with summation
    // (a fillet); the summation also fills the crotch higher up.
    const double e = 0.01;
    double angle[2], height[2];
    int k = 0;
    for (const auto mode : {TreeBuildOptions::Junction::Pcm, TreeBuildOptions::Junction::Smooth}) {
        const BlobTree t = yJunction(mode);
        const auto [yl, nl] = crotchPoint(t, -e);
        const auto [yr, nr] = crotchPoint(t, e);
        angle[k] =
            std::acos(std::clamp(glm::dot(nl, nr), -1.0, 1.0)) * 180.0 / 3.14159265358979323846;
        height[k] = crotchPoint(t, 0.0).first - 1.0;
        ++k;
    }
    report(
        "crotch between two branches: normals 2x{:.2f} apart turn {:.1f} deg with PCM, {:.1f} deg "
        "with "
        "summation; "
        "the crotch is {:.3f} (PCM) and {:.3f} (summation) above the branching point",
        e, angle[0], angle[1], height[0], height[1]);
    // The ridge is darker than the bark (PCM's darken, paper 000 section 3.2).
    {
        const BlobTree t = yJunction(TreeBuildOptions::Junction::Pcm);
        const ReferenceEvaluator ev(t);
        const double ridge = ev.sample({0.0, 1.0 + height[0] - 0.002, 0}).color.x;
        const double bark = ev.sample({0.1, 0.5, 0}).color.x;
        report("ridge colour {:.3f} against the bark's {:.3f}", ridge, bark);
        EXPECT_LT(ridge, 0.9 * bark);
    }
    EXPECT_GT(angle[0], 3.0 * angle[1]);
    EXPECT_GT(angle[0], 20.0);
    EXPECT_GT(height[1], height[0]);  // summation fills the crotch: material reaches higher up
    // No interpenetration: the branches meet at a contact, as the plain union
    // of the same (offset) cones does, where summation fuses them higher up.
    {
        const BlobTree pcm = yJunction(TreeBuildOptions::Junction::Pcm);
        BlobTree uni;
        std::vector<int> branches;
        int basal = -1;
        for (const Node& nd : pcm.nodes())
            if (nd.type == NodeType::CONE) {
                const int c = uni.cone(nd.prim().p0, nd.prim().p1, nd.prim().r0, nd.prim().r1);
                if (nd.prim().p0 == glm::dvec3(0.0))
                    basal = c;
                else
                    branches.push_back(c);
            }
        uni.setRoot(uni.op({NodeType::BLEND}, {basal, uni.op({NodeType::UNION}, branches)}));
        uni.finalize();
        const double contact = crotchPoint(uni, 0.0).first - 1.0;
        report("the union of the same cones meets at {:.3f} above the branching point", contact);
        EXPECT_LT(std::abs(height[0] - contact), 0.25 * std::abs(height[1] - contact));
    }
}

/// Largest distance, in voxels, of the baked surface from the plane y = 1
/// along lines parallel to y through the disc x^2 + z^2 < r^2.
double cutFaceDeviation(const std::string& lsystem, double r, double h)
{
    const LSystem sys = parseLSystem(lsystem, "cut.l");
    const BakedGrids g = test::bakeTree(buildTree(interpretTurtle(sys, derive(sys, 0, 1, 100))), h);
    const WorldSampler<openvdb::FloatGrid> at(*g.surface);
    double worst = 0.0;
    for (double x = -r; x <= r; x += 0.25 * h)
        for (double z = -r; z <= r; z += 0.25 * h) {
            if (x * x + z * z > r * r)
                continue;
            double in = 0.8, out = 1.3;  // inside the branch below, outside above
            EXPECT_LT(at(openvdb::Vec3d(x, in, z)), 0.0f);
            EXPECT_GT(at(openvdb::Vec3d(x, out, z)), 0.0f);
            for (int i = 0; i < 40; ++i) {
                const double m = 0.5 * (in + out);
                (at(openvdb::Vec3d(x, m, z)) < 0.0f ? in : out) = m;
            }
            worst = std::max(worst, std::abs(in - 1.0) / h);
        }
    return worst;
}

TEST(TreeBuilder, ASawCutIsPlanarAfterBaking)
{
    // A branch of radius 0.1 pruned at y = 1 (%): over 70 % of the cut face's
    // radius the baked surface is the plane; the uncut branch's cap is not.
    const double h = 0.01;
    const double cut = cutFaceDeviation("Axiom: !(0.2)F(1)%\n", 0.07, h);
    const double cap = cutFaceDeviation("Axiom: !(0.2)F(1)\n", 0.07, h);
    report(
        "saw cut: the baked face is within {:.3f} voxel of its plane (the uncut cap: {:.1f} "
        "voxels)",
        cut, cap);
    EXPECT_LT(cut, 0.1);
    EXPECT_GT(cap, 1.0);
}

TEST(TreeBuilder, RegrowthSwellsAndClosesOverASawCut)
{
    // A branch of radius 0.1 cut at y = 1: with regrowth the callus swells the
    // branch below the cut and rises over the cut face, more as it grows.
    const LSystem sys = parseLSystem("Axiom: !(0.2)F(1)%\n", "cut.l");
    const Skeleton sk = interpretTurtle(sys, derive(sys, 0, 1, 100));
    double lastRise = -1.0, lastSwell = -1.0;
    for (double g : {0.0, 0.5, 1.0}) {
        TreeBuildOptions o;
        o.regrowth = g;
        const BlobTree t = buildTree(sk, o);
        const ReferenceEvaluator ev(t);
        const double rise = test::surfaceDistance(ev, t.threshold(), {0, 0.9, 0}, {0, 1, 0}, 0.5) -
                            0.1;  // over y = 1
        double swell = 0.0;
        for (double y = 0.8; y <= 1.0; y += 0.002)
            swell = std::max(
                swell,
                test::surfaceDistance(ev, t.threshold(), {0, y, 0}, {1, 0, 0}, 0.5) / 0.1 - 1.0);
        report(
            "regrowth {:.1f}: the surface rises {:.4f} over the cut, the branch swells {:+.1f} % "
            "below "
            "it",
            g, rise, 100.0 * swell);
        if (g == 0.0) {
            EXPECT_NEAR(rise, 0.0, 1e-3);  // a bare, flat cut
            EXPECT_LT(swell, 0.005);
        } else {
            EXPECT_GT(rise, lastRise + 0.005);
            EXPECT_GT(swell, lastSwell);
            EXPECT_LT(swell, 0.3);
        }
        lastRise = rise;
        lastSwell = swell;
    }
    TreeBuildOptions bad;
    bad.regrowth = 2.0;
    EXPECT_THROW(buildTree(sk, bad), InputError);
}

TEST(TreeBuilder, AShedOrgansScarIsAsDeepAsItsNegativeFieldMakesIt)
{
    // A trunk of radius 0.1 that lost a lateral of radius 0.05 at y = 1,
    // heading -z: the bark there is pressed in.  The depth (from the trunk's
    // radius) follows the negative field's weight, and the baked grid has it
    // within 0.1 voxel of the reference evaluator.
    const double h = 0.005;
    const std::string text = "Axiom: !(0.2)F(1)[&(90)!(0.1)%]F(1)\n";
    const LSystem sys = parseLSystem(text, "scar.l");
    const Skeleton sk = interpretTurtle(sys, derive(sys, 0, 1, 100));
    ASSERT_EQ(sk.scars.size(), 1u);
    EXPECT_NEAR(sk.scars[0].tip.z, -0.1, 1e-12);  // the stub reaches the bark
    const glm::dvec3 c(0, 1, 0), u(0, 0, -1);
    double previous = -1.0;
    for (double w : {-0.5, -1.0, -1.5}) {
        TreeBuildOptions o;
        o.scarWeight = w;
        const BlobTree t = buildTree(sk, o);
        const double predicted =
            0.1 - test::surfaceDistance(ReferenceEvaluator(t), t.threshold(), c, u, 0.4);
        const BakedGrids g = test::bakeTree(t, h);
        const WorldSampler<openvdb::FloatGrid> at(*g.surface);
        double in = 0.0, out = 0.4;
        for (int i = 0; i < 40; ++i) {
            const double m = 0.5 * (in + out);
            const glm::dvec3 p = c + m * u;
            (at(openvdb::Vec3d(p.x, p.y, p.z)) < 0.0f ? in : out) = m;
        }
        const double baked = 0.1 - in;
        report(
            "scar with weight {:.1f}: {:.4f} deep (evaluator), {:.4f} (baked), {:.3f} voxel apart",
            w, predicted, baked, std::abs(baked - predicted) / h);
        EXPECT_NEAR(baked, predicted, 0.1 * h) << "weight " << w;
        EXPECT_GT(predicted, previous) << "a stronger negative field presses deeper";
        previous = predicted;
    }
    EXPECT_GT(previous, 0.01);  // a visible scar: over a tenth of the trunk's radius
    // Bark colour on the bark, darker in the scar.
    const BlobTree t = buildTree(sk);
    const ReferenceEvaluator ev(t);
    const glm::dvec3 bark = ev.sample({0.1, 0.5, 0}).color, scar = ev.sample(c + 0.09 * u).color;
    EXPECT_NEAR(bark.x, 0.36, 1e-9);
    EXPECT_LT(scar.x, 0.9 * bark.x);
}

/// An internode's inside across its chord at `mid`: the mean offset along
/// `normal` (within 0.3) of the points at or above the threshold 0.5 (1e9
/// where none is).
double offChord(const ReferenceEvaluator& ev, const glm::dvec3& mid, const glm::dvec3& normal)
{
    double sum = 0.0;
    int count = 0;
    for (double t = -0.3; t <= 0.3; t += 0.0005)
        if (ev.value(mid + t * normal) >= 0.5) {
            sum += t;
            ++count;
        }
    return count ? sum / count : 1e9;
}

TEST(TreeBuilder, ALateralAtRightAnglesBendsAsOneJustShortOfThem)
{
    // At 90 degrees (ABOP's default angle) the direction off the basal axis
    // was the lateral's own, which picks no bend plane: refused (sweep 12).
    // It bends as the limit from below does: its middle below the chord.
    auto middle = [](double degrees) {
        const double a = degrees * kDegree;
        Skeleton sk;
        sk.internodes = {
            internode(0, -1, {0, 0, 0}, {0, 1, 0}, 0.1, 0.08),
            internode(1, 0, {0, 1, 0}, {std::sin(a), 1.0 + std::cos(a), 0}, 0.05, 0.04)};
        TreeBuildOptions o;
        o.bend = 0.4;
        const BlobTree tree = buildTree(sk, o);
        const ReferenceEvaluator ev(tree);
        // The lateral's middle, across its chord in the plane.
        return offChord(ev, glm::dvec3(0.5 * std::sin(a), 1.0 + 0.5 * std::cos(a), 0),
                        glm::dvec3(std::cos(a), -std::sin(a), 0));
    };
    const double right = middle(90.0), below = middle(89.99);
    EXPECT_NEAR(right, below, 1e-3);
    EXPECT_GT(std::abs(right), 0.01);  // bent, not straight
}

TEST(TreeBuilder, BentInternodesKeepTheirEnds)
{
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 1, 0}, 0.1, 0.08),
                     internode(1, 0, {0, 1, 0}, {0.7, 1.7, 0}, 0.05, 0.04)};
    TreeBuildOptions o;
    o.bend = 0.4;
    const BlobTree bent = buildTree(sk, o), straight = buildTree(sk);
    int bends = 0;
    for (const Node& nd : bent.nodes())
        bends += nd.type == NodeType::BEND;
    EXPECT_EQ(bends, 1);  // the collinear trunk is not bent
    const ReferenceEvaluator eb(bent), es(straight);
    // The lateral's end cap is where it was: the surface beyond its tip.
    const glm::dvec3 tip(0.7, 1.7, 0), out = glm::normalize(glm::dvec3(0.7, 0.7, 0));
    const double a = test::surfaceDistance(eb, 0.5, tip, out, 0.5),
                 b = test::surfaceDistance(es, 0.5, tip, out, 0.5);
    EXPECT_NEAR(a, b, 0.004);
    // Its middle moved off the chord, away from the trunk's axis: it first
    // grows more directly away from the trunk (towards +x, below the chord).
    const glm::dvec3 mid(0.35, 1.35, 0), normal = glm::normalize(glm::dvec3(0.7, -0.7, 0));
    const double shifted = offChord(eb, mid, normal), centred = offChord(es, mid, normal);
    report("bend 0.4 rad: the internode's middle is {:.4f} off its chord (straight: {:.4f})",
           shifted, centred);
    EXPECT_NEAR(centred, 0.0, 0.002);
    // The configured amount: an arc turning by theta over the chord L departs
    // from it by (L / 2) tan(theta / 4) in the middle.
    const double L = glm::length(glm::dvec3(0.7, 0.7, 0.0));
    EXPECT_NEAR(shifted, 0.5 * L * std::tan(0.4 / 4.0), 1e-3);
}

TEST(TreeBuilder, DepthStaysSmallOnLargeSkeletons)
{
    // A trunk of 400 internodes with a lateral at each: every internode a junction.
    Skeleton sk;
    long long id = 0;
    for (int i = 0; i < 400; ++i) {
        const long long trunk = id++;
        sk.internodes.push_back(internode(trunk, i == 0 ? -1 : trunk - 2, {0, 0.1 * i, 0},
                                          {0, 0.1 * (i + 1), 0}, 0.03, 0.03));
        sk.internodes.push_back(internode(id++, trunk, {0, 0.1 * (i + 1), 0},
                                          {0.1 * std::cos(i), 0.1 * (i + 1.5), 0.1 * std::sin(i)},
                                          0.01, 0.01));
    }
    const BlobTree t = buildTree(sk);
    EXPECT_NO_THROW(FieldProgram::compile(t));  // within the kernels' stack depth
}

TEST(TreeBuilder, ShortInternodesLoseAtMostHalfAndDegenerateOnesAreNamed)
{
    // delta_A = 1.75 * 0.1 exceeds the first internode's length 0.1: half of it stays.
    Skeleton sk;
    sk.internodes = {internode(0, -1, {0, 0, 0}, {0, 0.1, 0}, 0.1, 0.1),
                     internode(7, 0, {0, 0.1, 0}, {0, 1, 0}, 0.1, 0.1)};
    const BlobTree t = buildTree(sk);
    for (const Node& nd : t.nodes()) {
        if (nd.type == NodeType::CONE && nd.prim().p0 == glm::dvec3(0.0)) {
            EXPECT_NEAR(nd.prim().p1.y, 0.05, 1e-12);
        }
    }
    sk.internodes = {internode(3, -1, {0, 0, 0}, {0, 0, 0}, 0.1, 0.1)};
    try {
        buildTree(sk);
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("internode 3: its two ends coincide"),
                  std::string::npos)
            << e.what();
    }
}

TEST(TreeBuilder, ModelFilesAreKnownByTheirExtensionInAnyCase)
{
    // A scene and an L-system named in capitals read as they do in lower case
    // (before, TREE.JSON was read as a skeleton and refused line by line).
    namespace fs = std::filesystem;
    const fs::path dir = test::freshDir("cambium_model_case");
    const fs::path examples = fs::path(CAMBIUM_SOURCE_DIR) / "examples";
    for (const auto& [from, to] :
         {std::pair{examples / "branch_junction.json", dir / "JUNCTION.JSON"},
          {examples / "lsystems" / "bush.l", dir / "Bush.L"}}) {
        fs::copy_file(from, to);
        const BlobTree lower = loadModel(from.string(), {}), upper = loadModel(to.string(), {});
        EXPECT_EQ(upper.size(), lower.size()) << to;
        EXPECT_GT(upper.size(), 1u) << to;
    }
    EXPECT_EQ(fileExtension("trees/Poplar.JSON"), "json");
    EXPECT_EQ(fileExtension("trees.d/poplar"), "");
    EXPECT_EQ(fileExtension("a.tar.GZ"), "gz");
}

}  // namespace
