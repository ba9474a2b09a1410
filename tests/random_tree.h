// cambium tests — random BlobTrees that mix every node type.
#pragma once

#include "blobtree/blobtree.h"

#include <glm/gtc/matrix_transform.hpp>

#include <random>

namespace cambium::test {

/// Builds a random BlobTree in roughly [-1, 1]^3: `depth` levels of random
/// operators and warps over random primitives (including scars), so that
/// supports overlap, PCM regions and CSG switches occur.
class RandomTreeBuilder {
public:
    explicit RandomTreeBuilder(unsigned seed) : rng_(seed) {}

    BlobTree build(int depth)
    {
        BlobTree tree;
        tree.setRoot(node(tree, depth));
        tree.finalize();
        return tree;
    }

private:
    double uni(double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng_); }
    int pick(int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng_); }
    glm::dvec3 point(double s = 0.8) { return {uni(-s, s), uni(-s, s), uni(-s, s)}; }
    glm::dvec3 colour() { return {uni(0, 1), uni(0, 1), uni(0, 1)}; }

    int primitive(BlobTree& t)
    {
        PrimitiveOptions o;
        if (pick(6) == 0)
            o.weight = -uni(0.3, 1.0);  // a scar
        if (pick(4) == 0)
            o.support = uni(0.4, 1.2);
        const glm::dvec3 a = point();
        const glm::dvec3 b = a + glm::dvec3(uni(-0.7, 0.7), uni(-0.7, 0.7), uni(-0.7, 0.7));
        int n;
        switch (pick(4)) {
            case 0:
                n = t.sphere(a, uni(0.15, 0.45), o);
                break;
            case 1:
                n = t.segment(a, b, uni(0.08, 0.3), o);
                break;
            case 2:
                n = t.cone(a, b, uni(0.1, 0.35), uni(0.05, 0.2), o);
                break;
            default: {
                ConvolutionOptions c;
                c.weight = o.weight;
                n = t.convolutionSegment(a, b, uni(0.1, 0.3), uni(0.05, 0.2), c);
                break;
            }
        }
        if (pick(2))
            t.setColor(n, colour());
        return n;
    }

    Combiner combiner(NodeType type)
    {
        Combiner c;
        c.type = type;
        c.n = uni(1.0, 6.0);
        c.width = uni(0.05, 0.5);
        c.attenuation = uni(1.5, 4.0);
        c.k = uni(0.0, 0.45);
        c.darken = uni(0.0, 1.0);
        return c;
    }

    int node(BlobTree& t, int depth)
    {
        if (depth == 0)
            return primitive(t);
        static const NodeType blending[] = {
            NodeType::BLEND,      NodeType::RICCI, NodeType::UNION,       NodeType::INTERSECTION,
            NodeType::DIFFERENCE, NodeType::PCM,   NodeType::BETTER_BLEND};
        const int choice = pick(12);
        if (choice < 7) {
            std::vector<int> kids;
            const int n = 2 + pick(3);
            for (int i = 0; i < n; ++i)
                kids.push_back(node(t, depth - 1 - pick(2) * (depth > 1)));
            return t.op(combiner(blending[choice]), kids);
        }
        if (choice == 7) {
            std::vector<int> kids = {node(t, depth - 1), node(t, depth - 1)};
            const int bound = t.sphere(point(0.5), uni(0.2, 0.5), {uni(0.8, 2.5), uni(0.5, 1.2)});
            return t.gbb(bound, kids, combiner(blending[pick(7)]), combiner(blending[pick(7)]));
        }
        const int child = node(t, depth - 1);
        switch (choice) {
            case 8: {
                glm::dmat4 m = glm::translate(glm::dmat4(1.0), point(0.3));
                m = glm::rotate(m, uni(-3, 3), point() + glm::dvec3(0.01, 0, 0));
                m = glm::scale(m, glm::dvec3(uni(0.6, 1.4), uni(0.6, 1.4), uni(0.6, 1.4)));
                return t.transform(m, child);
            }
            case 9: {
                const glm::dvec3 a = point(0.5);
                return t.bend(a, a + glm::dvec3(uni(-0.3, 0.3), uni(0.4, 0.9), uni(-0.3, 0.3)),
                              glm::dvec3(1, 0, 0.2), uni(-2.0, 2.0), child);
            }
            case 10:
                return t.twist(point(0.3), glm::dvec3(uni(-1, 1), 1, uni(-1, 1)), uni(-2, 2),
                               child);
            default:
                return t.taper(point(0.3), glm::dvec3(uni(-1, 1), 1, uni(-1, 1)), uni(0.5, 1.5),
                               uni(0.5, 1.5), uni(0.3, 1.5), child);
        }
    }

    std::mt19937 rng_;
};

}  // namespace cambium::test
