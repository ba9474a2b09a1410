// Primitives against their closed forms: sphere, segment, cone and the
// convolution segment (paper 002), weights and colours.
#include "test_util.h"

#include "cb_primitives.h"

#include <gtest/gtest.h>

namespace {

using namespace cambium;
using namespace cambium::test;

TEST(Sphere, SurfaceAtTheRadiusInEveryDirection)
{
    std::mt19937 rng(1);
    for (double T : {0.5, 0.3}) {
        for (double r : {0.01, 1.0, 37.5}) {
            BlobTree tree(T);
            const glm::dvec3 c(1.0, -2.0, 0.5);
            tree.setRoot(tree.sphere(c, r));
            tree.finalize();
            ReferenceEvaluator eval(tree);
            for (int i = 0; i < 50; ++i) {
                const glm::dvec3 d = randomUnit(rng);
                EXPECT_NEAR(eval.value(c + r * d), T, 1e-6);
                EXPECT_GT(eval.value(c + 0.99 * r * d), T);
                EXPECT_LT(eval.value(c + 1.01 * r * d), T);
            }
        }
    }
}

TEST(Sphere, IsolatedWyvillSupportIsTwiceTheRadius)
{
    // The 0.5 iso-surface of one Wyvill primitive of support R has radius R/2.
    for (double R : {1.0, 0.02, 7.0}) {
        BlobTree tree;
        tree.setRoot(tree.sphere({0, 0, 0}, R / 2, {1.0, R}));
        tree.finalize();
        ReferenceEvaluator eval(tree);
        EXPECT_NEAR(eval.value({R / 2, 0, 0}), 0.5, 1e-12);
        EXPECT_EQ(eval.value({0, R, 0}), 0.0);
        EXPECT_GT(eval.value({0, 0, 0.999 * R}), 0.0);
        // Without an explicit support the default is the same: R = 2 r.
        BlobTree plain;
        plain.setRoot(plain.sphere({0, 0, 0}, R / 2));
        plain.finalize();
        ReferenceEvaluator e2(plain);
        EXPECT_EQ(e2.value({0, R, 0}), 0.0);
        EXPECT_EQ(e2.value({0, 0.7 * R, 0}), eval.value({0, 0.7 * R, 0}));
    }
}

TEST(Sphere, ExplicitSupportKeepsTheSurfaceRadius)
{
    for (double R : {0.6, 1.0, 3.0}) {
        BlobTree tree;
        tree.setRoot(tree.sphere({0, 0, 0}, 0.5, {1.0, R}));
        tree.finalize();
        ReferenceEvaluator eval(tree);
        EXPECT_NEAR(eval.value({0, 0, 0.5}), 0.5, 1e-12) << R;
        EXPECT_EQ(eval.value({0, 0, std::max(R, 0.5 + 0.5 * R) + 1e-9}), 0.0) << R;
    }
}

TEST(Cone, SurfaceRadiusIsLinearFromBaseToTip)
{
    std::mt19937 rng(2);
    const glm::dvec3 a(0.2, 0.1, -0.3), b(0.9, 2.2, 0.4);
    const double r0 = 0.3, r1 = 0.1;
    BlobTree tree;
    tree.setRoot(tree.cone(a, b, r0, r1));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    const glm::dvec3 u = glm::normalize(b - a);
    for (int i = 0; i <= 40; ++i) {
        const double t = i / 40.0;
        const glm::dvec3 c = a + t * (b - a);
        glm::dvec3 side = glm::cross(u, randomUnit(rng));
        side = glm::normalize(side);
        const double radius = surfaceDistance(eval, 0.5, c, side, 2.0 * r0);
        EXPECT_NEAR(radius, r0 + (r1 - r0) * t, 1e-3 * r0) << "t = " << t;
    }
    // Hemispherical caps of radius r0 and r1 beyond the ends.
    EXPECT_NEAR(surfaceDistance(eval, 0.5, a, -u, 1.0), r0, 1e-9);
    EXPECT_NEAR(surfaceDistance(eval, 0.5, b, u, 1.0), r1, 1e-9);
}

TEST(Segment, IsACapsule)
{
    std::mt19937 rng(3);
    BlobTree tree;
    tree.setRoot(tree.segment({0, 0, 0}, {0, 0, 3}, 0.4));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    int checked = 0;
    for (int i = 0; i < 2000; ++i) {
        const glm::dvec3 p = randomIn(rng, {-0.8, -0.8, -0.8}, {0.8, 0.8, 3.8});
        // Exact distance to the capsule's skeleton decides inside / outside.
        const double d = glm::length(p - glm::dvec3(0, 0, std::clamp(p.z, 0.0, 3.0)));
        if (std::abs(d - 0.4) < 1e-9)
            continue;
        EXPECT_EQ(eval.value(p) > 0.5, d < 0.4) << d;
        ++checked;
    }
    EXPECT_GT(checked, 1900);
    for (double z : {-0.3, 0.0, 1.7, 3.0, 3.2}) {
        const glm::dvec3 c(0, 0, std::clamp(z, 0.0, 3.0));
        const glm::dvec3 dir = z < 0   ? glm::dvec3(0, 0, -1)
                               : z > 3 ? glm::dvec3(0, 0, 1)
                                       : glm::dvec3(0.6, 0.8, 0);
        EXPECT_NEAR(eval.value(c + 0.4 * dir), 0.5, 1e-12) << z;
    }
}

TEST(Primitive, NegativeWeightMakesAScarField)
{
    BlobTree tree;
    const int pos = tree.sphere({0, 0, 0}, 1.0);
    const int neg = tree.sphere({0, 0, 0}, 1.0, {-0.5, std::nullopt});
    tree.setRoot(tree.op({NodeType::BLEND}, {pos, neg}));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    for (double x : {0.0, 0.3, 0.8, 1.5}) {
        const glm::dvec3 p(x, 0, 0);
        EXPECT_NEAR(eval.sample(neg, p).value, -0.5 * eval.sample(pos, p).value, 1e-15);
        EXPECT_NEAR(eval.value(p), 0.5 * eval.sample(pos, p).value, 1e-15);
    }
}

// --- convolution segment ------------------------------------------------------

/// The convolution integral by composite Simpson's rule with n intervals.
double convolutionNumeric(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b, double q0,
                          double q1, double s, int n)
{
    const double len = glm::length(b - a);
    auto f = [&](double t) {
        const glm::dvec3 c = a + (t / len) * (b - a);
        const double r2 = glm::dot(p - c, p - c);
        const double q = q0 + (q1 - q0) * t / len;
        return q / ((1.0 + s * s * r2) * (1.0 + s * s * r2));
    };
    const double h = len / n;
    double sum = f(0.0) + f(len);
    for (int i = 1; i < n; ++i)
        sum += (i % 2 ? 4.0 : 2.0) * f(i * h);
    return sum * h / 3.0;
}

TEST(ConvolutionSegment, ClosedFormMatchesNumericalIntegration)
{
    const glm::dvec3 a(0.1, -0.2, 0.3), b(1.3, 1.5, -0.4);
    const glm::dvec3 u = glm::normalize(b - a);
    const glm::dvec3 side = glm::normalize(glm::cross(u, glm::dvec3(0, 0, 1)));
    const double len = glm::length(b - a);
    for (double s : {0.5, 4.0, 12.0}) {
        for (auto [q0, q1] : {std::pair{1.0, 1.0}, {2.5, 0.4}, {0.2, 3.0}}) {
            std::vector<glm::dvec3> points = {
                a + 0.5 * (b - a),                // on the skeleton
                a + 0.3 * (b - a) + 0.05 * side,  // near
                a + 0.7 * (b - a) + 0.6 * side,   // beside
                a - 0.2 * u + 0.1 * side,         // beyond the start
                b + 0.4 * u,                      // beyond the end, on the axis
                b + 1.5 * u - 0.9 * side,         // far beyond the end
                a + 0.5 * (b - a) + 3.0 * side,   // far to the side
            };
            for (const auto& p : points) {
                cb_vec3 g;
                const double closed = cb_convolution_raw(cb_v3(p.x, p.y, p.z), cb_v3(a.x, a.y, a.z),
                                                         cb_v3(u.x, u.y, u.z), len, q0, q1, s, &g);
                const double numeric = convolutionNumeric(p, a, b, q0, q1, s, 40000);
                EXPECT_NEAR(closed, numeric, 1e-4 * std::abs(numeric))
                    << "s " << s << " q " << q0 << "," << q1 << " p " << p.x << "," << p.y << ","
                    << p.z;
            }
        }
    }
}

TEST(ConvolutionSegment, DensityRuleGivesTheRadiusAlongALongSegment)
{
    for (double T : {0.5, 0.4}) {
        BlobTree tree(T);
        const double r = 0.2;
        tree.setRoot(tree.convolutionSegment({0, -40, 0}, {0, 40, 0}, r, r));
        tree.finalize();
        ReferenceEvaluator eval(tree);
        EXPECT_NEAR(surfaceDistance(eval, T, {0, 0, 0}, {1, 0, 0}, 0.5), r, 1e-6);
    }
    // Linear density: in the interior of a long tapered segment the radius
    // follows the density rule at each point.
    BlobTree tree;
    tree.setRoot(tree.convolutionSegment({0, -40, 0}, {0, 40, 0}, 0.3, 0.1, {1.0, 1.0 / 0.3, 0.9}));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    const double rMid = surfaceDistance(eval, 0.5, {0, 0, 0}, {0, 0, 1}, 0.9);
    // The radius where the density is halfway between the end densities.
    const double s = 1.0 / 0.3;
    const double qMid =
        0.5 * (cb_convolution_density(0.3, s, 0.5) + cb_convolution_density(0.1, s, 0.5));
    const double rExpected =
        bisect([&](double r) { return cb_convolution_density(r, s, 0.5) - qMid; }, 0.0, 1.0);
    EXPECT_NEAR(rMid, rExpected, 2e-3 * rExpected);
}

TEST(ConvolutionSegment, WindowEndsTheFieldAtTheSupport)
{
    BlobTree tree;
    tree.setRoot(tree.convolutionSegment({0, 0, 0}, {0, 1, 0}, 0.2, 0.1, {1.0, std::nullopt, 0.7}));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    EXPECT_EQ(eval.value({0.7, 0.5, 0}), 0.0);
    EXPECT_GT(eval.value({0.69, 0.5, 0}), 0.0);
    // Inside R/2 the window is 1: the field is the closed form itself.
    cb_vec3 g;
    const Primitive& p = tree.node(tree.root()).prim();
    EXPECT_DOUBLE_EQ(eval.value({0.3, 0.5, 0}),
                     cb_convolution_raw(cb_v3(0.3, 0.5, 0), cb_v3(0, 0, 0), cb_v3(0, 1, 0), 1.0,
                                        p.q0, p.q1, p.kernelWidth, &g));
}

TEST(Colour, IsTheFieldWeightedMixOfThePrimitives)
{
    BlobTree tree;
    const int a = tree.sphere({-0.5, 0, 0}, 1.0);
    const int b = tree.sphere({0.5, 0, 0}, 1.0);
    tree.setColor(a, {1, 0, 0});
    tree.setColor(b, {0, 0, 1});
    const int blend = tree.op({NodeType::BLEND}, {a, b});
    tree.setRoot(blend);
    tree.finalize();
    ReferenceEvaluator eval(tree);
    for (double x : {-1.2, -0.4, 0.0, 0.3, 1.1}) {
        const glm::dvec3 p(x, 0.2, 0);
        const double fa = eval.sample(a, p).value, fb = eval.sample(b, p).value;
        const glm::dvec3 c = eval.sample(p).color;
        EXPECT_NEAR(c.r, fa / (fa + fb), 1e-12);
        EXPECT_NEAR(c.b, fb / (fa + fb), 1e-12);
        EXPECT_EQ(c.g, 0.0);
    }
    // Colours are inherited: a primitive without its own colour takes its parent's.
    BlobTree t2;
    const int c1 = t2.sphere({0, 0, 0}, 1.0);
    const int top = t2.op({NodeType::BLEND}, {c1});
    t2.setColor(top, {0.2, 0.7, 0.1});
    t2.setRoot(top);
    t2.finalize();
    EXPECT_EQ(ReferenceEvaluator(t2).sample({0, 0, 0}).color, glm::dvec3(0.2, 0.7, 0.1));
}

}  // namespace
