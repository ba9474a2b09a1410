// cambium tests — one small scene per node type.
#pragma once

#include "blobtree/blobtree.h"

#include <glm/gtc/matrix_transform.hpp>

namespace cambium::test {

/// A red and a blue sphere blended: every colour between them on the band.
inline BlobTree redAndBlueSpheres()
{
    BlobTree t;
    const int a = t.sphere({-0.3, 0, 0}, 0.3), b = t.sphere({0.3, 0, 0}, 0.3);
    t.setColor(a, {1, 0, 0});
    t.setColor(b, {0, 0, 1});
    t.setRoot(t.op({NodeType::BLEND}, {a, b}));
    t.finalize();
    return t;
}

/// Children that overlap, with tapers and a scar, to combine under operators.
inline std::vector<int> someChildren(BlobTree& t)
{
    return {t.sphere({0, 0, 0}, 0.6), t.cone({0.3, 0.1, 0}, {1.2, 0.8, 0.2}, 0.35, 0.15),
            t.segment({-0.2, 0.4, 0.3}, {0.1, 1.3, -0.2}, 0.25),
            t.sphere({0.5, 0.5, 0.3}, 0.3, {-0.4, 0.8})};
}

/// A scene whose root is a node of the given type.
inline BlobTree sceneFor(NodeType type)
{
    BlobTree t;
    int root = -1;
    switch (type) {
        case NodeType::SPHERE:
            root = t.sphere({0.1, 0.2, 0.3}, 0.7, {1.0, 2.0});
            break;
        case NodeType::SEGMENT:
            root = t.segment({0, 0, 0}, {1, 0.5, 0.2}, 0.3);
            break;
        case NodeType::CONE:
            root = t.cone({0, 0, 0}, {0.4, 1.5, 0.2}, 0.5, 0.1);
            break;
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
            root = t.taper({0, 0, 0}, {0.2, 1, 0}, 1.0, 1.0, 0.4,
                           t.op({NodeType::BLEND}, someChildren(t)));
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

}  // namespace cambium::test
