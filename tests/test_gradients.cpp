// The analytic gradient of every node type against finite differences.
#include "test_util.h"

#include "blobtree/bounds.h"

#include <gtest/gtest.h>

#include <map>

namespace {

using namespace cambium;
using namespace cambium::test;

/// Children that overlap, with tapers and a scar, to combine under operators.
std::vector<int> someChildren(BlobTree& t)
{
    return {t.sphere({0, 0, 0}, 0.6), t.cone({0.3, 0.1, 0}, {1.2, 0.8, 0.2}, 0.35, 0.15),
            t.segment({-0.2, 0.4, 0.3}, {0.1, 1.3, -0.2}, 0.25),
            t.sphere({0.5, 0.5, 0.3}, 0.3, {-0.4, 0.8})};
}

/// A scene whose root is a node of the given type.
BlobTree sceneFor(NodeType type)
{
    BlobTree t;
    int root = -1;
    switch (type) {
    case NodeType::SPHERE: root = t.sphere({0.1, 0.2, 0.3}, 0.7, {1.0, 2.0}); break;
    case NodeType::SEGMENT: root = t.segment({0, 0, 0}, {1, 0.5, 0.2}, 0.3); break;
    case NodeType::CONE: root = t.cone({0, 0, 0}, {0.4, 1.5, 0.2}, 0.5, 0.1); break;
    case NodeType::CONVOLUTION_SEGMENT:
        root = t.convolutionSegment({0, 0, 0}, {0.4, 1.5, 0.2}, 0.4, 0.15);
        break;
    case NodeType::GBB: {
        auto kids = someChildren(t);
        const int bound = t.sphere({0.4, 0.3, 0.1}, 0.5, {1.6, std::nullopt});
        Combiner b1{NodeType::PCM};
        b1.width = 0.3;
        root = t.gbb(bound, kids, b1, {NodeType::BETTER_BLEND});
        break;
    }
    case NodeType::TRANSFORM: {
        glm::dmat4 m = glm::translate(glm::dmat4(1.0), glm::dvec3(0.3, -0.2, 0.5));
        m = glm::rotate(m, 0.8, glm::dvec3(0.3, 1, 0.2));
        m = glm::scale(m, glm::dvec3(1.5, 0.7, 1.1));
        root = t.transform(m, t.op({NodeType::BLEND}, someChildren(t)));
        break;
    }
    case NodeType::BEND:
        root = t.bend({0, 0, 0}, {0.4, 1.5, 0.2}, {1, 0, 0}, 1.2,
                      t.cone({0, 0, 0}, {0.4, 1.5, 0.2}, 0.3, 0.15));
        break;
    case NodeType::TWIST:
        root = t.twist({0, 0, 0}, {0, 1, 0}, 1.1, t.op({NodeType::BLEND}, someChildren(t)));
        break;
    case NodeType::TAPER:
        root = t.taper({0, 0, 0}, {0.2, 1, 0}, 1.0, 1.0, 0.4, t.op({NodeType::BLEND}, someChildren(t)));
        break;
    default: {
        Combiner c;
        c.type = type;
        c.n = 3.0;
        c.width = 0.3;
        c.k = 0.2;
        root = t.op(c, someChildren(t));
        break;
    }
    }
    t.setRoot(root);
    t.finalize();
    return t;
}

TEST(Gradient, MatchesFiniteDifferencesForEveryNodeType)
{
    for (NodeType type : allNodeTypes()) {
        SCOPED_TRACE(typeName(type));
        const BlobTree tree = sceneFor(type);
        ASSERT_EQ(tree.node(tree.root()).type, type);
        ReferenceEvaluator eval(tree);
        auto f = [&](const glm::dvec3& p) { return eval.value(p); };
        const Box box = computeBounds(tree)[size_t(tree.root())].support;
        std::mt19937 rng(13 + int(type));
        int agree = 0, nonzero = 0, creased = 0;
        for (int i = 0; i < 100000 && nonzero < 1000; ++i) {
            const glm::dvec3 p = randomIn(rng, box.lo, box.hi);
            const FieldSample s = eval.sample(p);
            if (s.value == 0.0 && glm::length(s.gradient) == 0.0)
                continue;  // outside every support
            ++nonzero;
            switch (checkGradient(f, p, s.gradient, 1e-5, 2e-4)) {
            case GradientCheck::Agrees: ++agree; break;
            case GradientCheck::NotSmooth: ++creased; break;
            case GradientCheck::Disagrees:
                ADD_FAILURE() << "gradient (" << s.gradient.x << ", " << s.gradient.y << ", "
                              << s.gradient.z << ") disagrees with finite differences at (" << p.x
                              << ", " << p.y << ", " << p.z << ")";
                break;
            }
        }
        EXPECT_EQ(nonzero, 1000);
        // Creases (CSG switches, PCM ridges, cone end planes) are rare: almost
        // every sampled point must have been checked.
        EXPECT_GE(agree, nonzero * 95 / 100) << creased << " creased of " << nonzero;
    }
}

}  // namespace
