// Operators: blend, Ricci, CSG, PCM (paper 003 eq. 3), GBB (paper 000
// eq. 2-4) and better blending (paper 002 eq. 6).
#include "test_util.h"

#include "cb_operators.h"

#include <gtest/gtest.h>

#include <algorithm>

namespace {

using namespace cambium;
using namespace cambium::test;

struct TwoSpheres {
    BlobTree tree;
    int a, b;
    explicit TwoSpheres(double ra = 1.0, double rb = 1.0, double gap = 1.0)
    {
        a = tree.sphere({-0.5 * gap, 0, 0}, ra);
        b = tree.sphere({0.5 * gap, 0, 0}, rb);
    }
    ReferenceEvaluator rooted(const Combiner& c)
    {
        tree.setRoot(tree.op(c, {a, b}));
        tree.finalize();
        return ReferenceEvaluator(tree);
    }
};

Combiner pcmOfWidth(double width)
{
    Combiner pcm{NodeType::PCM};
    pcm.width = width;
    return pcm;
}

TEST(Blend, IsCommutative)
{
    std::mt19937 rng(4);
    BlobTree tree;
    std::vector<int> kids = {tree.sphere({0, 0, 0}, 0.7),
                             tree.cone({0.2, 0, 0}, {1, 1, 0}, 0.3, 0.1),
                             tree.segment({0, -1, 0}, {0, 0, 1}, 0.25),
                             tree.sphere({0.4, 0.2, 0}, 0.3, {-0.6, std::nullopt})};
    const int first = tree.op({NodeType::BLEND}, kids);
    std::reverse(kids.begin(), kids.end());
    const int second = tree.op({NodeType::BLEND}, kids);
    std::swap(kids[0], kids[2]);
    const int third = tree.op({NodeType::BLEND}, kids);
    tree.setRoot(first);
    tree.finalize();
    ReferenceEvaluator eval(tree);
    for (int i = 0; i < 500; ++i) {
        const glm::dvec3 p = randomIn(rng, {-1.5, -1.5, -1.5}, {1.5, 1.5, 1.5});
        const double f = eval.sample(first, p).value;
        EXPECT_NEAR(eval.sample(second, p).value, f, 1e-14);
        EXPECT_NEAR(eval.sample(third, p).value, f, 1e-14);
    }
}

TEST(Csg, InsideOutsideAtChosenPoints)
{
    // Spheres of radius 1 centred at x = -0.5 and x = +0.5.
    const glm::dvec3 both(0, 0, 0), onlyA(-1.3, 0, 0), onlyB(1.3, 0, 0), neither(0, 1.5, 0);
    auto inside = [](NodeType op, const glm::dvec3& p) {
        TwoSpheres s;
        Combiner c;
        c.type = op;
        return s.rooted(c).value(p) > 0.5;
    };
    EXPECT_TRUE(inside(NodeType::UNION, both));
    EXPECT_TRUE(inside(NodeType::UNION, onlyA));
    EXPECT_TRUE(inside(NodeType::UNION, onlyB));
    EXPECT_FALSE(inside(NodeType::UNION, neither));
    EXPECT_TRUE(inside(NodeType::INTERSECTION, both));
    EXPECT_FALSE(inside(NodeType::INTERSECTION, onlyA));
    EXPECT_FALSE(inside(NodeType::INTERSECTION, onlyB));
    EXPECT_FALSE(inside(NodeType::INTERSECTION, neither));
    EXPECT_FALSE(inside(NodeType::DIFFERENCE, both));
    EXPECT_TRUE(inside(NodeType::DIFFERENCE, onlyA));
    EXPECT_FALSE(inside(NodeType::DIFFERENCE, onlyB));
    EXPECT_FALSE(inside(NodeType::DIFFERENCE, neither));
}

TEST(Csg, DifferenceSurfaceIsTheCutterSurface)
{
    // Inside A, the surface of A - B is exactly B's surface (2T - F_B = T iff F_B = T).
    TwoSpheres s;
    const ReferenceEvaluator eval = s.rooted({NodeType::DIFFERENCE});
    EXPECT_NEAR(eval.value({-0.5, 0, 0}), 0.5, 1e-12);  // on B's surface (B: centre 0.5, radius 1)
    EXPECT_NEAR(eval.value({0.5 - std::sqrt(0.5), std::sqrt(0.5), 0}), 0.5, 1e-12);
}

TEST(Ricci, ExponentOneIsTheSumAndLargeExponentIsTheMax)
{
    std::mt19937 rng(5);
    TwoSpheres s;
    const int sum = s.tree.op({NodeType::BLEND}, {s.a, s.b});
    Combiner r1{NodeType::RICCI};
    r1.n = 1.0;
    Combiner r64{NodeType::RICCI};
    r64.n = 64.0;
    const int ricci1 = s.tree.op(r1, {s.a, s.b});
    const int ricci64 = s.tree.op(r64, {s.b, s.a});
    s.tree.setRoot(sum);
    s.tree.finalize();
    ReferenceEvaluator eval(s.tree);
    for (int i = 0; i < 200; ++i) {
        const glm::dvec3 p = randomIn(rng, {-2, -1.5, -1.5}, {2, 1.5, 1.5});
        const double fa = eval.sample(s.a, p).value, fb = eval.sample(s.b, p).value;
        EXPECT_NEAR(eval.sample(ricci1, p).value, eval.sample(sum, p).value, 1e-12);
        const double mx = std::max(fa, fb);
        const double r = eval.sample(ricci64, p).value;
        EXPECT_GE(r, mx - 1e-12);
        EXPECT_LE(r, mx * std::pow(2.0, 1.0 / 64.0) + 1e-12);
    }
}

// --- PCM ----------------------------------------------------------------------

constexpr double kT = 0.5;

TEST(Pcm, DeformationProfile)
{
    const double w = 0.2, k = 2.0;
    double d;
    // Interpenetration: T - f_other.
    EXPECT_DOUBLE_EQ(cb_pcm_deformation(0.8, kT, w, k, &d), kT - 0.8);
    EXPECT_EQ(d, -1.0);
    // Propagation: s (1 - s/w)^k > 0 with s = T - f_other.
    for (double s = 0.01; s < w; s += 0.01) {
        const double D = cb_pcm_deformation(kT - s, kT, w, k, &d);
        EXPECT_NEAR(D, s * (1 - s / w) * (1 - s / w), 1e-15);
        EXPECT_GT(D, 0.0);
    }
    // Beyond: nothing.
    EXPECT_EQ(cb_pcm_deformation(kT - w, kT, w, k, &d), 0.0);
    EXPECT_EQ(cb_pcm_deformation(0.0, kT, w, k, &d), 0.0);
    // C1 at both borders (value and slope match from both sides).
    const double e = 1e-7;
    for (double border : {kT, kT - w}) {
        double dl, dr;
        const double vl = cb_pcm_deformation(border - e, kT, w, k, &dl);
        const double vr = cb_pcm_deformation(border + e, kT, w, k, &dr);
        EXPECT_NEAR(vl, vr, 3e-7) << border;
        EXPECT_NEAR(dl, dr, 1e-5) << border;
    }
}

TEST(Pcm, DeformedFieldsMeetOnTheContactSurfaceAndDoNotInterpenetrate)
{
    std::mt19937 rng(6);
    // Unequal spheres, so the contact surface f_a = f_b is curved.
    TwoSpheres s(1.0, 0.7, 1.2);
    const Combiner pcm = pcmOfWidth(0.2);
    const ReferenceEvaluator eval = s.rooted(pcm);
    auto fa = [&](const glm::dvec3& p) { return eval.sample(s.a, p).value; };
    auto fb = [&](const glm::dvec3& p) { return eval.sample(s.b, p).value; };
    auto deformedA = [&](const glm::dvec3& p) {
        double d;
        return fa(p) + cb_pcm_deformation(fb(p), kT, pcm.width, pcm.attenuation, &d);
    };
    auto deformedB = [&](const glm::dvec3& p) {
        double d;
        return fb(p) + cb_pcm_deformation(fa(p), kT, pcm.width, pcm.attenuation, &d);
    };
    int onContact = 0;
    for (int i = 0; i < 5000; ++i) {
        const glm::dvec3 p = randomIn(rng, {-1.6, -1.2, -1.2}, {1.4, 1.2, 1.2});
        // Never inside both deformed solids.
        EXPECT_FALSE(deformedA(p) > kT + 1e-12 && deformedB(p) > kT + 1e-12);
        // Walk along x to the contact surface f_a = f_b inside both objects.
        if (fa(p) > kT && fb(p) > kT) {
            const double x = bisect(
                [&](double t) {
                    const glm::dvec3 q(t, p.y, p.z);
                    return fa(q) - fb(q);
                },
                -1.0, 1.0);
            const glm::dvec3 c(x, p.y, p.z);
            if (fa(c) > kT && fb(c) > kT) {
                EXPECT_NEAR(deformedA(c), kT, 1e-9);
                EXPECT_NEAR(deformedB(c), kT, 1e-9);
                EXPECT_NEAR(eval.value(c), kT, 1e-9);
                ++onContact;
            }
        }
    }
    EXPECT_GT(onContact, 50);
}

TEST(Pcm, BulgeIsPositiveInThePropagationRegionAndVanishesBeyond)
{
    std::mt19937 rng(7);
    TwoSpheres s(1.0, 1.0, 1.5);
    const Combiner pcm = pcmOfWidth(0.2);
    const ReferenceEvaluator eval = s.rooted(pcm);
    int inRegion = 0, beyond = 0;
    for (int i = 0; i < 4000; ++i) {
        const glm::dvec3 p = randomIn(rng, {-2, -1.5, -1.5}, {2, 1.5, 1.5});
        const double fa = eval.sample(s.a, p).value, fb = eval.sample(s.b, p).value;
        const double strong = std::max(fa, fb), weak = std::min(fa, fb);
        const double F = eval.value(p);
        if (weak < kT && weak > kT - pcm.width) {
            EXPECT_GT(F, strong);
            ++inRegion;
        } else if (weak <= kT - pcm.width) {
            EXPECT_EQ(F, strong);
            ++beyond;
        }
    }
    EXPECT_GT(inRegion, 100);
    EXPECT_GT(beyond, 100);
}

TEST(Pcm, FieldAndGradientAreContinuousAcrossTheRegionBorders)
{
    // Walk from deep inside B (interpenetration) to far from it, staying where
    // A is clearly the stronger field, and look at each border crossing.
    TwoSpheres s(1.4, 0.6, 1.6);
    const Combiner pcm = pcmOfWidth(0.2);
    const ReferenceEvaluator eval = s.rooted(pcm);
    int crossings = 0;
    // Rays from B's centre (x = 0.8) towards A's centre: B's surface and its
    // propagation region lie inside A there, where A is the stronger field.
    const glm::dvec3 start(0.8, 0.0, 0.0);
    for (double angle = 0.0; angle < 0.8; angle += 0.1) {
        const glm::dvec3 dir = glm::normalize(glm::dvec3(-std::cos(angle), std::sin(angle), 0.2));
        auto fb = [&](double t) { return eval.sample(s.b, start + t * dir).value; };
        for (double level : {kT, kT - pcm.width}) {
            ASSERT_TRUE(fb(0.0) > level && fb(1.0) < level);
            const double t = bisect([&](double u) { return fb(u) - level; }, 0.0, 1.0);
            const glm::dvec3 c = start + t * dir;
            ASSERT_GT(eval.sample(s.a, c).value, fb(t) + 0.05);  // away from the ridge
            const double e = 1e-6;
            const FieldSample lo = eval.sample(c - e * dir), hi = eval.sample(c + e * dir);
            EXPECT_NEAR(lo.value, hi.value, 1e-5);
            EXPECT_LT(glm::length(lo.gradient - hi.gradient), 1e-3) << "level " << level;
            // And the analytic gradient matches finite differences across the border.
            auto f = [&](const glm::dvec3& p) { return eval.value(p); };
            EXPECT_EQ(checkGradient(f, c, eval.sample(c).gradient, 1e-5, 1e-4),
                      GradientCheck::Agrees);
            ++crossings;
        }
    }
    EXPECT_EQ(crossings, 18);
}

TEST(Pcm, ThreeChildrenFollowEquation3)
{
    std::mt19937 rng(8);
    BlobTree tree;
    std::vector<int> kids = {tree.sphere({0, 0, 0}, 0.8),
                             tree.cone({0.5, 0, 0}, {1.5, 0.5, 0}, 0.5, 0.3),
                             tree.segment({0, 0.6, 0.2}, {0.2, 1.4, 0}, 0.35)};
    Combiner pcm{NodeType::PCM};
    pcm.width = 0.3;
    pcm.attenuation = 3.0;
    const int root = tree.op(pcm, kids);
    std::vector<int> shuffled = {kids[2], kids[0], kids[1]};
    const int other = tree.op(pcm, shuffled);
    tree.setRoot(root);
    tree.finalize();
    ReferenceEvaluator eval(tree);
    for (int i = 0; i < 1000; ++i) {
        const glm::dvec3 p = randomIn(rng, {-1, -1, -1}, {2, 2, 1});
        std::vector<double> f;
        for (int k : kids)
            f.push_back(eval.sample(k, p).value);
        // Eq. 3: F_0 = f_lmax; F_i = F_{i-1} + d(F_{i-1}, f_i) for every other child.
        const size_t strongest = size_t(std::max_element(f.begin(), f.end()) - f.begin());
        double F = f[strongest];
        for (size_t j = 0; j < f.size(); ++j) {
            if (j == strongest)
                continue;
            const double sj = kT - f[j];
            const double d =
                sj <= 0 ? sj : (sj < pcm.width ? sj * std::pow(1 - sj / pcm.width, 3.0) : 0.0);
            F += d;
        }
        EXPECT_NEAR(eval.value(p), F, 1e-12);
        EXPECT_NEAR(eval.sample(other, p).value, F, 1e-12);
    }
}

// --- GBB ------------------------------------------------------------------------

TEST(Gbb, InterpolatesBetweenB1AndB2WithTheBoundingField)
{
    std::mt19937 rng(9);
    TwoSpheres s(1.0, 0.8, 1.4);
    // Bounding field: weight 2 -> clamps to 1 near its centre, 0 beyond its support.
    const int bound = s.tree.sphere({0, 0.3, 0}, 0.6, {2.0, 1.5});
    const int g = s.tree.gbb(bound, {s.a, s.b});
    Combiner pcm{NodeType::PCM};
    const int b1 = s.tree.op(pcm, {s.a, s.b});
    const int b2 = s.tree.op({NodeType::BLEND}, {s.a, s.b});
    s.tree.setRoot(g);
    s.tree.finalize();
    ReferenceEvaluator eval(s.tree);
    int ones = 0, zeros = 0, between = 0;
    for (int i = 0; i < 3000; ++i) {
        const glm::dvec3 p = randomIn(rng, {-2, -1.5, -1.5}, {2, 2, 1.5});
        const double fb = eval.sample(bound, p).value;
        const double v1 = eval.sample(b1, p).value, v2 = eval.sample(b2, p).value;
        const double F = eval.value(p);
        if (fb >= 1.0) {
            EXPECT_DOUBLE_EQ(F, v1);
            ++ones;
        } else if (fb <= 0.0) {
            EXPECT_DOUBLE_EQ(F, v2);
            ++zeros;
        } else {
            EXPECT_NEAR(F, fb * v1 + (1 - fb) * v2, 1e-14);
            const double lo = std::min(v1, v2), hi = std::max(v1, v2);
            EXPECT_GE(F, lo - 1e-14);
            EXPECT_LE(F, hi + 1e-14);
            ++between;
        }
    }
    EXPECT_GT(ones, 10);
    EXPECT_GT(zeros, 100);
    EXPECT_GT(between, 100);
}

TEST(Gbb, IsContinuousAcrossTheBoundingFieldEdges)
{
    TwoSpheres s(1.0, 1.0, 1.0);
    const int bound = s.tree.sphere({0, 0, 0}, 0.6, {2.0, 1.5});
    s.tree.setRoot(s.tree.gbb(bound, {s.a, s.b}));
    s.tree.finalize();
    ReferenceEvaluator eval(s.tree);
    // Along a line through the bound's centre: F(x) has no jumps.
    double prev = eval.value({0, -2.0, 0.1});
    for (double y = -2.0 + 1e-4; y < 2.0; y += 1e-4) {
        const double v = eval.value({0, y, 0.1});
        ASSERT_LT(std::abs(v - prev), 5e-3) << y;
        prev = v;
    }
}

// --- better blending -------------------------------------------------------------

TEST(BetterBlend, RemapIsC1AndKeepsTheThreshold)
{
    const double c = 0.5, k = 0.3;
    double d;
    EXPECT_DOUBLE_EQ(cb_better_blend_g(c, c, k, &d), c);
    EXPECT_EQ(cb_better_blend_g(0.2, c, k, &d), 0.0);
    EXPECT_EQ(cb_better_blend_g(0.9, c, k, &d), 2 * c);
    for (double t = -0.95; t < 1.0; t += 0.01) {
        double d1, d2;
        const double e = 1e-7;
        const double v1 = cb_better_blend_g(t - e, c, k, &d1),
                     v2 = cb_better_blend_g(t + e, c, k, &d2);
        EXPECT_NEAR(v1, v2, 12 * e);  // |g'| <= 2c / (c - k) = 5
        EXPECT_NEAR(d1, d2, 1e-5) << t;
        EXPECT_NEAR(cb_better_blend_g(t, c, k, &d), -cb_better_blend_g(-t, c, k, &d1), 1e-15);
    }
}

TEST(BetterBlend, BulgesLessThanASumAndKeepsIsolatedSurfaces)
{
    // Two spheres whose surfaces touch: the summed blend swells the waist, the
    // better blend much less; far from the junction both keep the radius.
    TwoSpheres sum(0.5, 0.5, 1.0), better(0.5, 0.5, 1.0);
    const ReferenceEvaluator es = sum.rooted({NodeType::BLEND});
    Combiner bb{NodeType::BETTER_BLEND};
    const ReferenceEvaluator eb = better.rooted(bb);
    const double waistSum = surfaceDistance(es, 0.5, {0, 0, 0}, {0, 1, 0}, 1.0);
    const double waistBetter = surfaceDistance(eb, 0.5, {0, 0, 0}, {0, 1, 0}, 1.0);
    EXPECT_LT(waistBetter, waistSum);
    EXPECT_NEAR(surfaceDistance(eb, 0.5, {-0.5, 0, 0}, {-1, 0, 0}, 1.0), 0.5, 1e-9);
}

}  // namespace
