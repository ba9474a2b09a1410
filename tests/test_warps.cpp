// Warps: transform, the endpoint-preserving bend (papers 001/003), twist and
// taper, and the bounds of warped supports.
#include "test_util.h"

#include "blobtree/bounds.h"

#include "cb_warps.h"

#include <gtest/gtest.h>

namespace {

using namespace cambium;
using namespace cambium::test;

TEST(Transform, MovesASphereSurfaceExactly)
{
    std::mt19937 rng(10);
    BlobTree tree;
    const double r = 0.4;
    const int s = tree.sphere({0, 0, 0}, r);
    glm::dmat4 m(1.0);
    m = glm::translate(m, glm::dvec3(1.5, -0.5, 2.0));
    m = glm::rotate(m, 0.7, glm::normalize(glm::dvec3(1, 2, 3)));
    m = glm::scale(m, glm::dvec3(2.0));
    tree.setRoot(tree.transform(m, s));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    for (int i = 0; i < 100; ++i) {
        const glm::dvec3 d = randomUnit(rng);
        EXPECT_NEAR(eval.value(glm::dvec3(1.5, -0.5, 2.0) + 2.0 * r * d), 0.5, 1e-9);
    }
    // A non-uniform scale makes an ellipsoid with semi-axes scale * r.
    BlobTree t2;
    const int s2 = t2.sphere({0, 0, 0}, r);
    t2.setRoot(t2.transform(glm::scale(glm::dmat4(1.0), glm::dvec3(1.0, 3.0, 0.5)), s2));
    t2.finalize();
    ReferenceEvaluator e2(t2);
    EXPECT_NEAR(e2.value({r, 0, 0}), 0.5, 1e-12);
    EXPECT_NEAR(e2.value({0, 3 * r, 0}), 0.5, 1e-12);
    EXPECT_NEAR(e2.value({0, 0, 0.5 * r}), 0.5, 1e-12);
}

struct BentSegment {
    BlobTree tree;
    glm::dvec3 p0{0.3, -0.2, 0.1}, p1{0.8, 1.9, 0.6}, dir{1, 0, 0};
    double angle = 1.1, r = 0.12;
    int seg = -1, bend = -1;
    BentSegment()
    {
        seg = tree.segment(p0, p1, r);
        bend = tree.bend(p0, p1, dir, angle, seg);
        tree.setRoot(bend);
        tree.finalize();
    }
    const cb_bend& params() const { return std::get<cb_bend>(tree.node(bend).params); }
    /// A point of the bent skeleton: the arc from p0 to p1, s in [0, 1].
    glm::dvec3 arcPoint(double s) const
    {
        const cb_bend& b = params();
        const glm::dvec3 u(b.u.x, b.u.y, b.u.z), v(b.v.x, b.v.y, b.v.z);
        const glm::dvec3 centre = p0 + 0.5 * b.len * u - b.rho * b.ch * v;
        const double phi = -0.5 * b.theta + s * b.theta;
        return centre + b.rho * (std::sin(phi) * u + std::cos(phi) * v);
    }
};

TEST(Bend, KeepsBothEndPointsOnTheSkeleton)
{
    BentSegment b;
    double J[9];
    const cb_vec3 q0 = cb_bend_apply(b.params(), cb_v3(b.p0.x, b.p0.y, b.p0.z), J);
    const cb_vec3 q1 = cb_bend_apply(b.params(), cb_v3(b.p1.x, b.p1.y, b.p1.z), J);
    EXPECT_LT(glm::length(glm::dvec3(q0.x, q0.y, q0.z) - b.p0), 1e-12);
    EXPECT_LT(glm::length(glm::dvec3(q1.x, q1.y, q1.z) - b.p1), 1e-12);
    ReferenceEvaluator eval(b.tree);
    // On the bent skeleton the field is the segment's maximum, 1, all along the arc.
    for (double s = 0.0; s <= 1.0; s += 0.05)
        EXPECT_NEAR(eval.value(b.arcPoint(s)), 1.0, 1e-12) << s;
    EXPECT_NEAR(glm::length(b.arcPoint(0.0) - b.p0), 0.0, 1e-12);
    EXPECT_NEAR(glm::length(b.arcPoint(1.0) - b.p1), 0.0, 1e-12);
}

TEST(Bend, BulgesTowardsTheBendDirectionAndKeepsTheRadius)
{
    BentSegment b;
    ReferenceEvaluator eval(b.tree);
    const cb_bend& p = b.params();
    const glm::dvec3 v(p.v.x, p.v.y, p.v.z), w(p.w.x, p.w.y, p.w.z);
    // The arc's midpoint lies the sagitta rho (1 - cos(theta/2)) off the chord, along v.
    const glm::dvec3 mid = b.arcPoint(0.5);
    const double sagitta = p.rho * (1.0 - std::cos(0.5 * b.angle));
    EXPECT_NEAR(glm::dot(mid - 0.5 * (b.p0 + b.p1), v), sagitta, 1e-12);
    EXPECT_GT(glm::dot(glm::dvec3(1, 0, 0), v),
              0.0);  // v is the given direction made perpendicular
    // Across the bent axis the surface stays at the radius.
    for (double s : {0.1, 0.5, 0.9}) {
        EXPECT_NEAR(surfaceDistance(eval, 0.5, b.arcPoint(s), w, 0.5), b.r, 1e-9);
        EXPECT_NEAR(
            surfaceDistance(eval, 0.5, b.arcPoint(s),
                            glm::normalize(b.arcPoint(s) -
                                           (b.p0 + 0.5 * p.len * glm::dvec3(p.u.x, p.u.y, p.u.z) -
                                            p.rho * p.ch * v)),
                            0.5),
            b.r, 1e-9);
    }
}

TEST(Bend, AngleZeroIsTheIdentity)
{
    BlobTree tree;
    const int seg = tree.segment({0, 0, 0}, {0, 1, 0}, 0.1);
    const int straight = tree.bend({0, 0, 0}, {0, 1, 0}, {1, 0, 0}, 0.0, seg);
    tree.setRoot(straight);
    tree.finalize();
    ReferenceEvaluator eval(tree);
    std::mt19937 rng(11);
    for (int i = 0; i < 100; ++i) {
        const glm::dvec3 p = randomIn(rng, {-0.3, -0.3, -0.3}, {0.3, 1.3, 0.3});
        EXPECT_DOUBLE_EQ(eval.value(p), eval.sample(seg, p).value);
    }
}

TEST(Twist, TurnsAnOffAxisSegmentIntoAHelix)
{
    BlobTree tree;
    const double rate = 0.8;  // radians per unit length
    const int seg = tree.segment({0.5, 0, 0}, {0.5, 0, 2}, 0.1);
    tree.setRoot(tree.twist({0, 0, 0}, {0, 0, 1}, rate, seg));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    for (double z = 0.0; z <= 2.0; z += 0.1) {
        const glm::dvec3 helix(0.5 * std::cos(rate * z), 0.5 * std::sin(rate * z), z);
        EXPECT_NEAR(eval.value(helix), 1.0, 1e-12) << z;
    }
}

TEST(Taper, ScalesTheCrossSectionLinearly)
{
    BlobTree tree;
    const int seg = tree.segment({0, 0, -1}, {0, 0, 3}, 0.2);
    tree.setRoot(tree.taper({0, 0, 0}, {0, 0, 1}, 2.0, 1.0, 0.5, seg));
    tree.finalize();
    ReferenceEvaluator eval(tree);
    for (double z : {-0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5}) {
        const double s = 1.0 + (0.5 - 1.0) * std::clamp(z / 2.0, 0.0, 1.0);
        EXPECT_NEAR(surfaceDistance(eval, 0.5, {0, 0, z}, {1, 0, 0}, 1.0), 0.2 * s, 1e-9) << z;
    }
}

TEST(WarpBounds, ContainEveryPointWhoseChildIsPositive)
{
    std::mt19937 rng(12);
    BlobTree tree;
    const int seg = tree.cone({0.1, 0, 0}, {0.2, 1.5, 0.1}, 0.2, 0.1);
    std::vector<int> warps = {
        tree.bend({0.1, 0, 0}, {0.2, 1.5, 0.1}, {1, 0, 1}, 2.5, seg),
        tree.bend({0.1, 0, 0}, {0.2, 1.5, 0.1}, {0, 0, 1}, -0.4, seg),
        tree.twist({0, 0, 0}, {0.2, 1, 0}, 1.3, seg),
        tree.taper({0, 0.5, 0}, {0, 1, 0}, 1.0, 2.0, 0.3, seg),
        tree.transform(glm::rotate(glm::scale(glm::dmat4(1.0), glm::dvec3(1, 2, 0.5)), 0.9,
                                   glm::dvec3(0, 0, 1)),
                       seg),
    };
    tree.setRoot(warps[0]);
    tree.finalize();
    ReferenceEvaluator eval(tree);
    const auto bounds = computeBounds(tree);
    for (int w : warps) {
        const Box box = bounds[size_t(w)].positive;
        const Box wide = box.padded(1.5);
        int positive = 0;
        for (int i = 0; i < 20000; ++i) {
            const glm::dvec3 p = randomIn(rng, wide.lo, wide.hi);
            if (eval.sample(w, p).value > 0.0) {
                ++positive;
                ASSERT_TRUE(box.contains(p))
                    << typeName(tree.node(w).type) << " at " << p.x << "," << p.y << "," << p.z;
            }
        }
        EXPECT_GT(positive, 20) << typeName(tree.node(w).type);
    }
}

}  // namespace
