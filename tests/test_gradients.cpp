// The analytic gradient of every node type against finite differences.
#include "test_util.h"
#include "scenes.h"

#include "blobtree/bounds.h"

#include <gtest/gtest.h>

#include <map>

namespace {

using namespace cambium;
using namespace cambium::test;

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
                case GradientCheck::Agrees:
                    ++agree;
                    break;
                case GradientCheck::NotSmooth:
                    ++creased;
                    break;
                case GradientCheck::Disagrees:
                    ADD_FAILURE() << "gradient (" << s.gradient.x << ", " << s.gradient.y << ", "
                                  << s.gradient.z << ") disagrees with finite differences at ("
                                  << p.x << ", " << p.y << ", " << p.z << ")";
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
