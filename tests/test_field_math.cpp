// The Wyvill function and the skeletal falloff (kernels/cb_primitives.h), and
// the promise that the shared headers mean the same thing when compiled as C99.
#include "blobtree/blobtree.h"

#include "cb_operators.h"
#include "cb_primitives.h"

#include <gtest/gtest.h>

extern "C" {
double cb_c99_wyvill(double x);
double cb_c99_cone(const double p[3], const double a[3], const double b[3], double r0, double r1);
double cb_c99_pcm_deformation(double f_other, double T, double w, double k);
int cb_c99_opcode_pcm(void);
}

namespace {

double w(double x)
{
    double dw;
    return cb_wyvill(x, &dw);
}
double dw(double x)
{
    double d;
    cb_wyvill(x, &d);
    return d;
}

TEST(Wyvill, ValuesAtZeroHalfAndOne)
{
    EXPECT_DOUBLE_EQ(w(0.0), 1.0);
    EXPECT_NEAR(w(0.5), 0.5, 1e-15);
    EXPECT_DOUBLE_EQ(w(1.0), 0.0);
    EXPECT_DOUBLE_EQ(w(1.7), 0.0);
}

TEST(Wyvill, MatchesThePolynomialAndItsDerivative)
{
    for (double x = 0.01; x < 1.0; x += 0.01) {
        const double x2 = x * x;
        EXPECT_NEAR(w(x), 1 - 22.0 / 9 * x2 + 17.0 / 9 * x2 * x2 - 4.0 / 9 * x2 * x2 * x2, 1e-14);
        EXPECT_NEAR(dw(x), (w(x + 1e-6) - w(x - 1e-6)) / 2e-6, 1e-8) << "x = " << x;
    }
}

TEST(Wyvill, IsC1AtOneAndAtZero)
{
    // Value and slope go to zero from below at 1, and match the constant 0 beyond.
    EXPECT_NEAR(w(1.0 - 1e-6), 0.0, 1e-10);
    EXPECT_NEAR(dw(1.0 - 1e-6), 0.0, 1e-5);
    EXPECT_DOUBLE_EQ(dw(1.0 + 1e-6), 0.0);
    EXPECT_NEAR(dw(1e-6), 0.0, 1e-5);
    // One-sided difference quotients at 1 agree to O(h): the slope has no jump
    // (w''(1) = 40/9, so the left quotient is about 40/9 * h / 2).
    for (double h : {1e-3, 1e-4, 1e-5}) {
        const double left = (w(1.0) - w(1.0 - h)) / h, right = (w(1.0 + h) - w(1.0)) / h;
        EXPECT_NEAR(left, right, 2.5 * h) << h;
    }
}

TEST(Wyvill, DecreasesStrictlyOnTheSupport)
{
    for (double x = 0.001; x < 1.0; x += 0.001)
        ASSERT_LT(w(x), w(x - 0.001)) << x;
}

TEST(Wyvill, InverseFindsTheThresholdCrossing)
{
    EXPECT_NEAR(cb_wyvill_inverse(0.5), 0.5, 1e-15);
    for (double T : {0.05, 0.2, 0.35, 0.5, 0.61, 0.9})
        EXPECT_NEAR(w(cb_wyvill_inverse(T)), T, 1e-14) << T;
}

TEST(SkeletalFalloff, SurfaceStaysAtTheRadiusForAnySupport)
{
    for (double T : {0.3, 0.5, 0.7}) {
        const double xT = cb_wyvill_inverse(T);
        for (double sigma : {0.5, 1.0, 1.8}) {
            double fd, fr;
            EXPECT_NEAR(cb_skeletal_field(0.37, 0.37, sigma, xT, &fd, &fr), T, 1e-12);
            // Zero exactly from the reach on.
            const double reach = cb_skeletal_reach(0.37, sigma, xT);
            EXPECT_EQ(cb_skeletal_field(reach, 0.37, sigma, xT, &fd, &fr), 0.0);
            EXPECT_GT(cb_skeletal_field(reach * 0.999, 0.37, sigma, xT, &fd, &fr), 0.0);
        }
    }
}

TEST(SharedHeaders, CompileAsC99AndAgreeWithCpp)
{
    for (double x = -0.2; x < 1.2; x += 0.013)
        EXPECT_EQ(cb_c99_wyvill(x), w(x));
    const double p[3] = {0.3, 0.9, -0.1}, a[3] = {0, 0, 0}, b[3] = {0, 2, 0};
    cb_vec3 g;
    EXPECT_EQ(cb_c99_cone(p, a, b, 0.5, 0.2),
              cb_cone_field(cb_v3(0.3, 0.9, -0.1), cb_v3(0, 0, 0), cb_v3(0, 1, 0), 2.0, 0.5, 0.2,
                            1.0, 0.5, &g));
    double d;
    EXPECT_EQ(cb_c99_pcm_deformation(0.4, 0.5, 0.25, 2.0),
              cb_pcm_deformation(0.4, 0.5, 0.25, 2.0, &d));
    EXPECT_EQ(cb_c99_opcode_pcm(), int(cambium::NodeType::PCM));
}

}  // namespace
