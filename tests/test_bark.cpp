// Bark furrows on cones (kernels/cb_primitives.h, cb_bark_cone_field): the
// surface where the profile puts it, gradients against finite differences,
// the program interpreter against the reference evaluator, the detail limit,
// and the parameter checks.
#include "blobtree/bounds.h"
#include "field/program.h"
#include "test_util.h"

#include "cb_primitives.h"

#include <gtest/gtest.h>

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
