// The global-to-local growth model (paper 000 section 4): the equations'
// properties on the bundled Populus and on parameter sets made to show one
// thing each; the skeleton's geometry (phyllotaxis, headings); continuity in
// time; bud scale scars and bark ridges over time.
#include "bake/options.h"
#include "blobtree/evaluator.h"
#include "core/error.h"
#include "core/system.h"
#include "model/growth.h"
#include "test_util.h"

#include <gtest/gtest.h>

#include <cmath>
#include <new>
#include <set>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace {

using namespace cambium;
using cambium::test::expectInputError;

constexpr double kPi = 3.14159265358979323846;

GrowthParameters populus()
{
    return loadGrowthParameters(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json");
}

const GrowthModel& populusModel()
{
    static const GrowthModel model(populus());
    return model;
}

double angularDistance(double deg)
{
    const double a = std::fmod(std::abs(deg), 360.0);
    return std::min(a, 360.0 - a);
}

TEST(Growth, Eq5EveryBranchGrowsAtLeastLminEveryYearItLives)
{
    const GrowthModel& m = populusModel();
    const double lmin = m.params().minShootLength;
    ASSERT_GT(m.branches().size(), 1000u);
    for (const GrowthBranch& b : m.branches()) {
        ASSERT_GE(b.length.size(), 2u);  // at least one year's growth
        EXPECT_EQ(b.length[0], 0.0);
        for (size_t k = 1; k < b.length.size(); ++k)
            ASSERT_GE(b.length[k], b.length[k - 1] + lmin * (1.0 - 1e-12)) << "order " << b.order;
        // It grows every year from its birth until the year before it is lost.
        EXPECT_EQ(b.lastYear(), std::min(m.params().years, b.lost - 1));
    }
}

TEST(Growth, LengthsNeverShrinkAtAnyTime)
{
    const GrowthModel& m = populusModel();
    for (size_t b = 0; b < m.branches().size(); b += 7) {
        double last = 0.0;
        for (double t = 0.0; t <= m.params().years; t += 0.05) {
            const double l = m.grownLength(int(b), m.growthTime(t));
            ASSERT_GE(l, last) << "branch " << b << " at t = " << t;
            last = l;
        }
        EXPECT_DOUBLE_EQ(last, m.branches()[b].length.back());
    }
}

TEST(Growth, AtYearEndsTheDrawnLengthIsEq7s)
{
    // The internodes of the trunk at t = y add up to l_y, whatever the
    // growth curves and the offsets of the metamers within the year.
    // (Straight: with noise, runs of short thick metamers are drawn as chords.)
    GrowthParameters p = populus();
    p.orientationNoise = 0.0;
    const GrowthModel m(p);
    for (int y : {1, 2, 5, 13, 27}) {
        const Skeleton sk = m.skeleton(y, false);
        double trunk = 0.0;
        for (const Internode& in : sk.internodes)
            if (in.module == 0)
                trunk += glm::length(in.p1 - in.p0);
        EXPECT_NEAR(trunk, m.branches()[0].lengthAt(y), 1e-9 * trunk) << "year " << y;
    }
}

TEST(Growth, LostBranchesStayLostAndLeaveScars)
{
    const GrowthModel& m = populusModel();
    size_t lost = 0;
    for (const GrowthBranch& b : m.branches())
        lost += b.lost <= m.params().years;
    ASSERT_GT(lost, 100u);
    for (double t : {8.0, 12.5, 17.0, 22.0, 27.0}) {
        const Skeleton sk = m.skeleton(t, false);
        std::set<long long> present;
        for (const Internode& in : sk.internodes)
            present.insert(in.module);
        size_t gone = 0;
        for (size_t b = 0; b < m.branches().size(); ++b) {
            const GrowthBranch& br = m.branches()[b];
            if (m.growthTime(t) >= br.lost) {
                EXPECT_FALSE(present.count((long long)b))
                    << "branch " << b << " lost in " << br.lost << ", t " << t;
                ++gone;
            }
        }
        const GrowthStats st = m.stats(t, false);
        EXPECT_EQ(size_t(st.lostBranches), gone);
        if (t >= 12.0) {
            EXPECT_GT(sk.scars.size(), 0u);
        }
    }
}

TEST(Growth, SilhouettesAtTheStartAndTheEndFollowGs1AndGs2)
{
    // Order-1 lengths relative to the trunk, divided by s_b, are Gs1 when the
    // tree is young and Gs2 when it is old (eq. 6) wherever eq. 7's minimum
    // does not decide (a long shoot).  Parameters with Gs1 and Gs2 of
    // different shapes, and Gss = Gbs = 1 so that s_b = 1.
    GrowthParameters p = populus();
    p.Gss = Curve::constant(1.0);
    p.Gbs = Curve::constant(0.5);
    p.Gs1 = Curve({{0, 0.8}, {1, 0.1}}, Curve::Interpolation::Linear, "Gs1");
    p.Gs2 = Curve({{0, 0.1}, {0.5, 0.6}, {1, 0.2}}, Curve::Interpolation::Smooth, "Gs2");
    p.minScale = 0.45;  // order 1 only (order 2 would have s_b = 0.25)
    p.Ga = Curve::constant(100);
    p.minShootLength = 1e-4;
    const GrowthModel m(p);
    const GrowthBranch& trunk = m.branches()[0];
    size_t young = 0, mature = 0;
    const int Y = p.years;
    for (const GrowthBranch& b : m.branches()) {
        if (b.order != 1)
            continue;
        ASSERT_DOUBLE_EQ(b.scale, 0.5);
        for (int y = b.birth; y <= b.lastYear(); ++y) {
            const double lp = trunk.lengthAt(y), x = b.position / lp, ty = double(y) / Y;
            const double rel = b.lengthAt(y) / (lp * b.scale);
            if (b.lengthAt(y) <= b.lengthAt(y - 1) + p.minShootLength * 1.0001)
                continue;  // eq. 7's minimum
            if (y == 2) {
                EXPECT_NEAR(rel, (1 - ty) * p.Gs1(x) + ty * p.Gs2(x), 1e-12);
                EXPECT_NEAR(rel, p.Gs1(x), 0.1);  // t_y = 2/27: mostly the young silhouette
                ++young;
            }
            if (y == Y) {
                EXPECT_NEAR(rel, p.Gs2(x), 1e-12) << "x " << x;
                ++mature;
            }
        }
    }
    EXPECT_GT(young, 2u);
    EXPECT_GT(mature, 20u);
}

TEST(Growth, HigherOrdersFollowEq12And13AndStopBelowSmin)
{
    const GrowthModel& m = populusModel();
    const GrowthParameters& p = m.params();
    std::set<int> orders;
    for (const GrowthBranch& b : m.branches()) {
        orders.insert(b.order);
        if (b.parent < 0)
            continue;
        EXPECT_GE(b.scale, p.minScale);
        const GrowthBranch& parent = m.branches()[size_t(b.parent)];
        EXPECT_EQ(b.order, parent.order + 1);
        EXPECT_LE(b.scale,
                  parent.scale * 0.85 * 0.85 + 1e-12);  // max Gss * max Gbs of the bundled curves
        EXPECT_LE(b.lost, parent.lost);
        EXPECT_GT(b.birth, parent.birth);
    }
    EXPECT_GE(*orders.rbegin(), 3);
}

TEST(Growth, MetamersFollowGmAndTheFortyDegreeRuleHoldsForEveryShoot)
{
    const GrowthModel& m = populusModel();
    const GrowthParameters& p = m.params();
    size_t shoots = 0, adjusted = 0;
    for (const GrowthBranch& b : m.branches()) {
        for (size_t i = 0; i < b.shoots.size(); ++i) {
            const GrowthShoot& s = b.shoots[i];
            const int m0 = std::max(1, int(std::lround(p.Gm(s.length / p.maxShootLength))));
            EXPECT_LE(std::abs(s.metamers - m0), 3);
            adjusted += s.metamers != m0;
            if (i == 0)
                continue;
            ++shoots;
            const int previous = b.shoots[i - 1].firstMetamer + b.shoots[i - 1].metamers - 1;
            const int last = s.firstMetamer + s.metamers - 1;
            ASSERT_GE(angularDistance((last - previous) * p.phyllotaxis), 40.0 - 1e-9);
            if (s.metamers > 1) {
                ASSERT_GE(angularDistance((last - 1 - previous) * p.phyllotaxis), 40.0 - 1e-9);
            }
        }
    }
    EXPECT_GT(shoots, 5000u);
    EXPECT_GT(adjusted, 100u);  // the rule did change counts
}

TEST(Growth, LateralsAreOnA137Point5DegreeSpiral)
{
    // Measured on the skeleton: without noise the trunk is straight, and the
    // directions of its laterals' first internodes around it step by 137.5
    // degrees per node.
    GrowthParameters p = populus();
    p.orientationNoise = 0.0;
    const GrowthModel m(p);
    const Skeleton sk = m.skeleton(p.years, false);
    std::map<int, double> azimuthAtNode;  // trunk node -> degrees
    for (const Internode& in : sk.internodes) {
        const GrowthBranch& b = m.branches()[size_t(in.module)];
        if (b.order != 1 || in.p0 != sk.internodes[size_t(in.parent)].p1)
            continue;
        if (sk.internodes[size_t(in.parent)].module != 0)
            continue;
        const glm::dvec3 d = glm::normalize(in.p1 - in.p0);
        if (azimuthAtNode.count(b.node))
            continue;  // the first internode only
        azimuthAtNode[b.node] = std::atan2(d.x, d.z) * 180.0 / kPi;
    }
    ASSERT_GT(azimuthAtNode.size(), 10u);
    size_t pairs = 0;
    for (auto a = azimuthAtNode.begin(); std::next(a) != azimuthAtNode.end(); ++a) {
        const auto b = std::next(a);
        const double measured = b->second - a->second,
                     expected = (b->first - a->first) * p.phyllotaxis;
        EXPECT_NEAR(angularDistance(measured - expected), 0.0, 1e-6)
            << "nodes " << a->first << ", " << b->first;
        ++pairs;
    }
    EXPECT_GT(pairs, 10u);
}

TEST(Growth, LongBranchesBendDownNearTheBaseAndUpAtTheTip)
{
    // Go2 starts negative and ends positive: a long branch's first internode
    // turns away from the trunk (down), its last towards it (up), relative
    // to its initial heading at the branching angle.
    GrowthParameters p = populus();
    p.orientationNoise = 0.0;
    const GrowthModel m(p);
    const Skeleton sk = m.skeleton(p.years, false);
    std::map<long long, std::vector<const Internode*>> byBranch;
    for (const Internode& in : sk.internodes)
        byBranch[in.module].push_back(&in);
    size_t checked = 0;
    for (const auto& [b, ins] : byBranch) {
        const GrowthBranch& br = m.branches()[size_t(b)];
        if (br.order != 1 || br.length.back() < 0.6 * p.maxBranchLength || ins.size() < 6)
            continue;
        const glm::dvec3 first = glm::normalize(ins.front()->p1 - ins.front()->p0);
        const glm::dvec3 last = glm::normalize(ins.back()->p1 - ins.back()->p0);
        const double initial = p.branchingAngle;  // degrees from the vertical trunk
        const double a0 = std::acos(std::clamp(first.y, -1.0, 1.0)) * 180.0 / kPi;
        const double a1 = std::acos(std::clamp(last.y, -1.0, 1.0)) * 180.0 / kPi;
        EXPECT_GT(a0, initial) << "branch " << b;  // heading below its start: drooping base
        EXPECT_LT(a1, a0) << "branch " << b;       // and turning up towards the tip
        ++checked;
    }
    EXPECT_GT(checked, 3u);
}

TEST(Growth, SameSeedSameTreeOtherSeedOtherTree)
{
    const GrowthModel a(populus()), b(populus());
    GrowthParameters q = populus();
    q.seed = 2;
    const GrowthModel c(q);
    const Skeleton sa = a.skeleton(9.5, true), sb = b.skeleton(9.5, true),
                   sc = c.skeleton(9.5, true);
    ASSERT_EQ(sa.internodes.size(), sb.internodes.size());
    for (size_t i = 0; i < sa.internodes.size(); ++i) {
        ASSERT_EQ(sa.internodes[i].p1, sb.internodes[i].p1);
        ASSERT_EQ(sa.internodes[i].r0, sb.internodes[i].r0);
    }
    ASSERT_EQ(sa.organs.size(), sb.organs.size());
    // The seed varies orientation: the same structure, other positions.
    ASSERT_EQ(sa.internodes.size(), sc.internodes.size());
    double moved = 0.0;
    for (size_t i = 0; i < sa.internodes.size(); ++i)
        moved = std::max(moved, glm::length(sa.internodes[i].p1 - sc.internodes[i].p1));
    EXPECT_GT(moved, 0.05);
}

TEST(Growth, RadiiFollowTheSupportedLengthAndNeverThin)
{
    const GrowthModel& m = populusModel();
    const GrowthParameters& p = m.params();
    // The trunk's base at the last year is base_radius; shoot tips are tip_radius.
    const Skeleton end = m.skeleton(p.years, false);
    EXPECT_NEAR(end.internodes[0].r0, p.baseRadius, 1e-9);
    double thinnest = 1e300;
    for (const Internode& in : end.internodes) {
        thinnest = std::min({thinnest, in.r0, in.r1});
        EXPECT_GE(in.r0, in.r1 * (1 - 1e-12));  // taper towards the tips
    }
    EXPECT_NEAR(thinnest, p.tipRadius, 0.2 * p.tipRadius);
    // Secondary growth: the trunk's base thickens every year (losses do not
    // thin it: shed wood stays counted).
    double last = 0.0;
    for (double t = 1.0; t <= p.years; t += 0.25) {
        const double r = m.skeleton(t, false).internodes[0].r0;
        EXPECT_GE(r, last) << t;
        last = r;
    }
}

TEST(Growth, LeavesGrowAndFallWithinTheYear)
{
    const GrowthModel& m = populusModel();
    auto leaves = [&](double t) { return m.stats(t, true).leaves; };
    EXPECT_EQ(leaves(5.0), 0);    // winter: the year's leaves have fallen
    EXPECT_GT(leaves(5.3), 100);  // early summer
    EXPECT_GT(leaves(5.7), leaves(5.3));
    EXPECT_EQ(m.stats(5.5, false).leaves, 0);  // --no-leaves
    // Leaf size grows through the season.
    auto meanSize = [&](double t) {
        double s = 0.0;
        size_t n = 0;
        for (const Organ& o : m.skeleton(t, true).organs)
            if (o.kind == Organ::Kind::Leaf) {
                s += glm::length(o.p1 - o.p0);
                ++n;
            }
        return s / double(n);
    };
    EXPECT_LT(meanSize(5.15), meanSize(5.5));
}

TEST(Growth, TheMemoryEstimateCountsLeavesAsLeaves)
{
    // A leaf is a unit sphere under a transform: its area must be counted in
    // world space (counted as a unit sphere, mid-summer of year 10 needed
    // 43 GB at voxel size 0.01; it bakes in 0.33 GB).
    const FieldProgram program = FieldProgram::compile(populusModel().tree(9.5, true));
    const double estimate = estimateBakeBytes(program, 0.01, 3.0, true);
    EXPECT_LT(estimate, 2e9);
    EXPECT_GT(estimate, estimateBakeBytes(FieldProgram::compile(populusModel().tree(9.5, false)),
                                          0.01, 3.0, true));
}

TEST(Growth, DormantSeasonsChangeNothing)
{
    const GrowthModel& m = populusModel();
    const double season = m.params().growingSeason;
    for (int y : {3, 11}) {
        const Skeleton a = m.skeleton(y - 1 + season + 0.01, false), b = m.skeleton(y, false);
        ASSERT_EQ(a.internodes.size(), b.internodes.size());
        for (size_t i = 0; i < a.internodes.size(); ++i)
            ASSERT_EQ(a.internodes[i].p1, b.internodes[i].p1);
        const Skeleton c = m.skeleton(y - 1 + 0.5 * season, false);
        EXPECT_LT(c.internodes.size(), b.internodes.size());
    }
}

TEST(Growth, ScarRingsFadeWithAge)
{
    const GrowthModel& m = populusModel();
    const GrowthParameters& p = m.params();
    // Rings of every age below scar_years, weights falling linearly with age.
    const Skeleton sk = m.skeleton(15.0, false);
    size_t rings = 0;
    for (const Organ& o : sk.organs)
        if (o.kind == Organ::Kind::Ring) {
            EXPECT_GT(o.weight, 0.0);
            EXPECT_LE(o.weight, p.scarRing);
            ++rings;
        }
    EXPECT_GT(rings, 100u);
    // A shoot's base ring: scar_ring when new, gone after scar_years.
    auto ringsAt = [&](double t) { return m.stats(t, false).rings; };
    EXPECT_GT(ringsAt(3.0), 0);
    GrowthParameters q = p;
    q.scarRing = 0.0;
    EXPECT_EQ(GrowthModel(q).stats(10.0, false).rings, 0);
}

TEST(Growth, ALateralAtEveryBudIsRefusedForItsBranchesBeforeMemoryRunsOut)
{
    // Gss = Gbs = 10 puts a lateral at every bud: 10^7 branches of a few
    // internodes each held 4.9 GB while their internodes were counted at
    // 400 bytes each, and the growth ran out of memory, exit 1 (sweep 10).
    // Here under an address-space limit 400 MB above what the process
    // maps: refused by name, not out of memory.
    GrowthParameters p = populus();
    p.Gss = Curve::constant(10.0);
    p.Gbs = Curve::constant(10.0);
    p.maxInternodes = 1e9;
    cambium::test::expectRefusedUnderAddressSpaceLimit(
        400e6, [&] { GrowthModel m(p); },
        [](const std::string& what) {
            return what.find("internodes in") != std::string::npos &&
                   what.find("branches (reached at a branch of order") != std::string::npos;
        });
}

TEST(Growth, BadParametersAreNamedBeforeAnyWork)
{
    GrowthParameters p = populus();
    p.Gss = Curve::constant(1.0);
    p.Gbs = Curve::constant(1.0);
    p.minScale = 0.1;
    p.maxInternodes = 20000;
    // Named by the file read (it named the species), then the limit.
    expectInputError([&] { GrowthModel m(p); },
                     "populus/populus.json: the parameters grow more than 20000 internodes "
                     "(max_internodes)",
                     "exploding parameters");
    const std::string base =
        readTextFile(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json", "test");
    auto replaced = [&](const std::string& from, const std::string& to) {
        std::string s = base;
        const size_t at = s.find(from);
        EXPECT_NE(at, std::string::npos) << from;
        return s.replace(at, from.size(), to);
    };
    expectInputError(
        [&] {
            parseGrowthParameters(replaced("\"growing_season\": 0.6", "\"growing_season\": 0"),
                                  "p.json");
        },
        "growing_season", "season");
    expectInputError(
        [&] {
            parseGrowthParameters(replaced("\"internode_growth\": {\"points\": [[0, 0]",
                                           "\"internode_growth\": {\"points\": [[0, 0.2]"),
                                  "p.json");
        },
        "curves.internode_growth: must start at 0 and end at 1", "growth curve");
}

}  // namespace
