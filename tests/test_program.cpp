// The FieldProgram: the host interpreter of the compiled program equals the
// reference evaluator; intervals bound the field; specialisation to a box
// changes nothing inside the box and removes what is irrelevant there.
#include "test_util.h"
#include "random_tree.h"

#include "blobtree/bounds.h"
#include "field/program.h"

#include "cb_program.h"

#include "cb_primitives.h"

#include <gtest/gtest.h>

#include <cstdlib>

namespace {

using namespace cambium;
using namespace cambium::test;

void expectSameSample(const FieldSample& a, const FieldSample& b, double tol, const char* what)
{
    EXPECT_NEAR(a.value, b.value, tol) << what;
    EXPECT_LT(glm::length(a.gradient - b.gradient), tol * std::max(1.0, glm::length(b.gradient)))
        << what;
    EXPECT_LT(glm::length(a.color - b.color), 1e-9) << what;
}

TEST(FieldProgram, InterpreterMatchesTheReferenceOnRandomTrees)
{
    const unsigned seeds = std::getenv("CAMBIUM_STRESS") ? 3000 : 300;
    for (unsigned seed = 0; seed < seeds; ++seed) {
        const BlobTree tree = RandomTreeBuilder(seed).build(1 + int(seed % 4));
        const FieldProgram prog = FieldProgram::compile(tree);
        ReferenceEvaluator ref(tree);
        std::mt19937 rng(seed);
        for (int i = 0; i < 200; ++i) {
            const glm::dvec3 p = randomIn(rng, glm::dvec3(-1.5), glm::dvec3(1.5));
            expectSameSample(prog.evaluate(prog.code(), p), ref.sample(p), 1e-10, "random tree");
            if (HasFailure())
                FAIL() << "seed " << seed << " point " << p.x << " " << p.y << " " << p.z;
        }
    }
}

TEST(FieldProgram, IntervalsBoundTheFieldOverBoxes)
{
    const unsigned seeds = std::getenv("CAMBIUM_STRESS") ? 2000 : 200;
    for (unsigned seed = 0; seed < seeds; ++seed) {
        const BlobTree tree = RandomTreeBuilder(100000 + seed).build(1 + int(seed % 4));
        const FieldProgram prog = FieldProgram::compile(tree);
        std::mt19937 rng(seed);
        for (int b = 0; b < 20; ++b) {
            const glm::dvec3 c = randomIn(rng, glm::dvec3(-1.2), glm::dvec3(1.2));
            const double h = std::uniform_real_distribution<double>(0.01, 0.6)(rng);
            const Box box(c - h, c + h);
            const Interval iv = prog.specialize(prog.code(), box, nullptr);
            for (int i = 0; i < 100; ++i) {
                const double v = prog.evaluate(prog.code(), randomIn(rng, box.lo, box.hi)).value;
                ASSERT_GE(v, iv.lo - 1e-12) << "seed " << seed;
                ASSERT_LE(v, iv.hi + 1e-12) << "seed " << seed;
            }
        }
    }
}

TEST(FieldProgram, SpecialisationIsExactInsideItsBox)
{
    int shrunk = 0, total = 0;
    const unsigned seeds = std::getenv("CAMBIUM_STRESS") ? 3000 : 300;
    for (unsigned seed = 0; seed < seeds; ++seed) {
        const BlobTree tree = RandomTreeBuilder(200000 + seed).build(1 + int(seed % 4));
        const FieldProgram prog = FieldProgram::compile(tree);
        std::mt19937 rng(seed);
        for (int b = 0; b < 15; ++b) {
            const glm::dvec3 c = randomIn(rng, glm::dvec3(-1.2), glm::dvec3(1.2));
            const double h = std::uniform_real_distribution<double>(0.02, 0.5)(rng);
            const Box box(c - h, c + h);
            std::vector<Instr> spec;
            prog.specialize(prog.code(), box, &spec);
            int stack, warps;
            FieldProgram::depths(spec, stack, warps);
            ASSERT_LE(stack, FieldProgram::maxStackDepth());
            ++total;
            shrunk += spec.size() < prog.code().size();
            for (int i = 0; i < 60; ++i) {
                const glm::dvec3 p = randomIn(rng, box.lo, box.hi);
                expectSameSample(prog.evaluate(spec, p), prog.evaluate(prog.code(), p), 1e-12,
                                 "specialised");
                if (HasFailure())
                    FAIL() << "seed " << seed << " box " << b;
            }
        }
    }
    EXPECT_GT(shrunk, total / 3);
}

TEST(FieldProgram, ALeafNearOneTwigEvaluatesOnlyThatTwig)
{
    // A blend of 200 separated cones: near one of them only it remains.
    BlobTree tree;
    std::vector<int> cones;
    for (int i = 0; i < 200; ++i) {
        const glm::dvec3 a(0.5 * (i % 20), 0.0, 0.5 * (i / 20));
        cones.push_back(tree.cone(a, a + glm::dvec3(0, 1, 0), 0.05, 0.03));
    }
    tree.setRoot(tree.op({NodeType::BLEND}, cones));
    tree.finalize();
    const FieldProgram prog = FieldProgram::compile(tree);
    EXPECT_EQ(prog.primitiveCount(), 200u);
    std::vector<Instr> spec;
    const Interval iv =
        prog.specialize(prog.code(), Box({1.45, 0.4, 0.95}, {1.55, 0.5, 1.05}), &spec);
    ASSERT_EQ(spec.size(), 1u);
    EXPECT_EQ(spec[0].op, CB_CONE);
    EXPECT_TRUE(iv.contains(0.5));
    // Far from all of them: the constant 0.
    spec.clear();
    EXPECT_TRUE(prog.specialize(prog.code(), Box({0.2, 5, 0.2}, {0.3, 6, 0.3}), &spec).isZero());
    ASSERT_EQ(spec.size(), 1u);
    EXPECT_EQ(spec[0].op, CB_I_CONST);
}

TEST(FieldProgram, ALeafBesideOneWarpedTwigEvaluatesOnlyThatTwig)
{
    // Two twigs 0.6 apart under a twist or a taper, or one after the other
    // along a bend: a leaf on one's surface keeps only it.  (The twist's and
    // taper's child boxes were whole cylinders about the axis, the bend's
    // arc the internode's whole length: a nested warp sampled 265 times the
    // leaves it kept, 17 s for a bake of 0.5 s.)
    const double deg = M_PI / 180.0;
    auto pair = [](BlobTree& t, glm::dvec3 a0, glm::dvec3 a1, glm::dvec3 b0, glm::dvec3 b1) {
        return t.op({NodeType::BLEND}, {t.cone(a0, a1, 0.05, 0.05), t.cone(b0, b1, 0.05, 0.05)});
    };
    NamedTrees named;
    named.add("twist", [&](BlobTree& t) {
        return t.twist({0, 0, 0}, {0, 1, 0}, 0.8,
                       pair(t, {0.3, 0, 0}, {0.3, 1, 0}, {-0.3, 0, 0}, {-0.3, 1, 0}));
    });
    named.add("taper", [&](BlobTree& t) {
        return t.taper({0, 0, 0}, {0, 1, 0}, 1.0, 1.5, 0.7,
                       pair(t, {0.3, 0, 0}, {0.3, 1, 0}, {-0.3, 0, 0}, {-0.3, 1, 0}));
    });
    named.add("bend", [&](BlobTree& t) {
        return t.bend({0, 0, 0}, {0, 1, 0}, {1, 0, 0}, 60 * deg,
                      pair(t, {0, 0.05, 0}, {0, 0.35, 0}, {0, 0.65, 0}, {0, 0.95, 0}));
    });
    for (const auto& [name, tree] : named.trees) {
        SCOPED_TRACE(name);
        const FieldProgram prog = FieldProgram::compile(tree);
        std::mt19937 rng(5);
        int leaves = 0;
        for (int i = 0; i < 200000 && leaves < 50; ++i) {
            const glm::dvec3 p = randomIn(rng, glm::dvec3(-1.0, -0.2, -1.0), glm::dvec3(1.0));
            if (std::abs(prog.evaluate(prog.code(), p).value - 0.5) > 0.05)
                continue;
            ++leaves;
            std::vector<Instr> spec;
            prog.specialize(prog.code(), Box(p - 0.01, p + 0.01), &spec);
            EXPECT_EQ(std::count_if(spec.begin(), spec.end(),
                                    [](const Instr& in) { return in.op == CB_CONE; }),
                      1)
                << "at " << p.x << " " << p.y << " " << p.z;
        }
        EXPECT_EQ(leaves, 50);
    }
}

TEST(FieldProgram, APcmLeafKeepsNoChildWhoseFieldIsZeroThere)
{
    // Twelve laterals fanned out from one node under PCM.  A leaf at the edge
    // of one's support (its lower bound 0 there) kept every other, zero as
    // they are: 300 laterals left 516 instructions in every leaf of the
    // tree (14 s for a bake of 0.8 s).
    BlobTree tree;
    std::vector<int> laterals;
    for (int i = 0; i < 12; ++i) {
        const double a = 2.0 * M_PI * i / 12.0;
        laterals.push_back(tree.cone({0, 0, 0}, {std::cos(a), 0.5, std::sin(a)}, 0.02, 0.01));
    }
    Combiner pcm{NodeType::PCM};
    tree.setRoot(tree.op(pcm, laterals));
    tree.finalize();
    const FieldProgram prog = FieldProgram::compile(tree);
    // Half way along lateral 0, across it to the edge of its support.
    const glm::dvec3 mid(0.5, 0.25, 0.0);
    const double reach = cb_skeletal_reach(0.015, tree.node(laterals[0]).prim().sigma, tree.xT());
    const glm::dvec3 edge = mid + glm::dvec3(0, 0, reach);
    std::vector<Instr> spec;
    const Interval iv = prog.specialize(prog.code(), Box(edge - 0.01, edge + 0.01), &spec);
    EXPECT_EQ(iv.lo, 0.0);
    // The other laterals' boxes hold the leaf, their fields are zero on it:
    // PCM collapses to the one lateral.
    ASSERT_EQ(spec.size(), 1u);
    EXPECT_EQ(spec[0].op, CB_CONE);
}

TEST(FieldProgram, CanonicalFormsAreEqualExactlyForTheSameLocalField)
{
    // Two trees: the second has an extra cone first (every parameter offset
    // moves) and one cone moved.  Near an unchanged cone the specialised
    // programs' canonical forms are equal; near the moved one they differ.
    auto build = [](bool extra, double shift) {
        BlobTree tree;
        std::vector<int> cones;
        if (extra)
            cones.push_back(tree.cone({9, 9, 9}, {9, 10, 9}, 0.05, 0.03));
        for (int i = 0; i < 10; ++i) {
            const glm::dvec3 a(0.5 * i + (i == 3 ? shift : 0.0), 0.0, 0.0);
            cones.push_back(tree.cone(a, a + glm::dvec3(0, 1, 0), 0.05, 0.03));
        }
        tree.setRoot(tree.op({NodeType::BLEND}, cones));
        tree.finalize();
        return FieldProgram::compile(tree);
    };
    const FieldProgram a = build(false, 0.0), b = build(true, 0.001);
    auto canonicalNear = [](const FieldProgram& p, double x) {
        std::vector<Instr> spec;
        p.specialize(p.code(), Box({x - 0.05, 0.4, -0.05}, {x + 0.05, 0.5, 0.05}), &spec);
        std::vector<double> out;
        p.canonical(spec, out);
        return out;
    };
    EXPECT_NE(a.params().size(), b.params().size());
    EXPECT_EQ(canonicalNear(a, 1.0), canonicalNear(b, 1.0));  // cone 2: unchanged
    EXPECT_NE(canonicalNear(a, 1.5), canonicalNear(b, 1.5));  // cone 3: moved by 0.001
    EXPECT_NE(canonicalNear(a, 1.0), canonicalNear(a, 2.0));  // other cones
}

TEST(FieldProgram, FoldsEveryOperatorCorrectly)
{
    // Per operator: two children, one far away.  The far child's field is 0
    // in the box, and each operator folds it the right way.
    auto specialised = [](NodeType type, bool farIsScar) {
        BlobTree t;
        const int nearChild = t.sphere({0, 0, 0}, 0.5);
        const int farChild = t.sphere({10, 0, 0}, 0.5, {farIsScar ? -1.0 : 1.0, std::nullopt});
        Combiner c;
        c.type = type;
        t.setRoot(t.op(c, {nearChild, farChild}));
        t.finalize();
        const FieldProgram prog = FieldProgram::compile(t);
        std::vector<Instr> spec;
        prog.specialize(prog.code(), Box(glm::dvec3(-0.1), glm::dvec3(0.1)), &spec);
        return spec;
    };
    // The far child is zero on the box: a sum drops it and collapses to the near sphere.
    for (NodeType t : {NodeType::BLEND, NodeType::RICCI, NodeType::BETTER_BLEND, NodeType::UNION,
                       NodeType::PCM, NodeType::DIFFERENCE}) {
        const auto spec = specialised(t, false);
        if (t == NodeType::BETTER_BLEND) {  // remaps its one child: stays an operator
            EXPECT_EQ(spec.size(), 4u) << typeName(t);
        } else {
            EXPECT_EQ(spec.size(), 1u) << typeName(t);
            EXPECT_EQ(spec[0].op, CB_SPHERE) << typeName(t);
        }
    }
    // min(near, 0) = 0 on the box where near > 0: the intersection keeps the zero
    // (the near sphere is never the minimum there).
    const auto inter = specialised(NodeType::INTERSECTION, false);
    ASSERT_EQ(inter.size(), 1u);
    EXPECT_EQ(inter[0].op, CB_I_CONST);
}

TEST(SegmentBoxDistance, MatchesBruteForce)
{
    std::mt19937 rng(7);
    for (int i = 0; i < 2000; ++i) {
        const glm::dvec3 a = randomIn(rng, glm::dvec3(-2), glm::dvec3(2));
        const glm::dvec3 b = randomIn(rng, glm::dvec3(-2), glm::dvec3(2));
        const glm::dvec3 c = randomIn(rng, glm::dvec3(-1), glm::dvec3(1));
        const Box box(c - 0.3, c + glm::dvec3(0.5, 0.2, 0.4));
        double brute = 1e30;
        for (int k = 0; k <= 4000; ++k) {
            const glm::dvec3 p = a + (k / 4000.0) * (b - a);
            const glm::dvec3 d = glm::max(glm::max(box.lo - p, p - box.hi), glm::dvec3(0.0));
            brute = std::min(brute, glm::dot(d, d));
        }
        const double exact = segmentBoxDistance2(a, b, box);
        EXPECT_LE(exact, brute + 1e-12);
        EXPECT_NEAR(std::sqrt(exact), std::sqrt(brute), 2e-3);
    }
    // Adversarial: a point, axis-parallel segments, one inside, one along a
    // face, one through a corner, one whose closest point is interior.
    const Box unit(glm::dvec3(0.0), glm::dvec3(1.0));
    EXPECT_DOUBLE_EQ(segmentBoxDistance2({2, 0.5, 0.5}, {2, 0.5, 0.5}, unit), 1.0);
    EXPECT_DOUBLE_EQ(segmentBoxDistance2({2, 0.5, 0.5}, {3, 0.5, 0.5}, unit), 1.0);
    EXPECT_DOUBLE_EQ(segmentBoxDistance2({3, 0.5, 0.5}, {2, 0.5, 0.5}, unit), 1.0);
    EXPECT_DOUBLE_EQ(segmentBoxDistance2({0.2, 0.3, 0.4}, {0.7, 0.6, 0.5}, unit), 0.0);
    EXPECT_DOUBLE_EQ(segmentBoxDistance2({0, 1, -1}, {1, 1, -1}, unit), 1.0);
    EXPECT_DOUBLE_EQ(segmentBoxDistance2({-1, -1, -1}, {2, 2, 2}, unit), 0.0);
    EXPECT_NEAR(segmentBoxDistance2({-1, 2, 0.5}, {2, 2, 0.5}, unit), 1.0, 1e-15);
    EXPECT_NEAR(segmentBoxDistance2({-1, 3, 0.5}, {3, -1, 2.5}, unit), 0.2, 1e-15);  // at t = 0.45
    EXPECT_NEAR(segmentBoxDistance2({-1, 2, 2}, {2, 2, -1}, unit), 1.0, 1e-12);
}

}  // namespace
