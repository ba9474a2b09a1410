// cambium — bounds of BlobTree fields.
#include "blobtree/bounds.h"

#include "cb_primitives.h"

#include <algorithm>
#include <cmath>

namespace cambium {

namespace {

glm::dvec3 toGlm(const cb_vec3& v)
{
    return {v.x, v.y, v.z};
}

Box segmentBox(const glm::dvec3& a, const glm::dvec3& b, double pad)
{
    Box box;
    box.expand(a);
    box.expand(b);
    return box.padded(pad);
}

Box bendImage(const cb_bend& b, const Box& box)
{
    if (b.theta <= 0.0)
        return box;  // a bend of angle 0 is the identity
    const glm::dvec3 p0 = toGlm(b.p0), u = toGlm(b.u), v = toGlm(b.v), w = toGlm(b.w);
    double amin = INFINITY, amax = -INFINITY, rperp = 0.0;
    for (const auto& c : box.corners()) {
        const glm::dvec3 d = c - p0;
        const double a = glm::dot(d, u);
        amin = std::min(amin, a);
        amax = std::max(amax, a);
        rperp = std::max(rperp, std::hypot(glm::dot(d, v), glm::dot(d, w)));
    }
    // Every image point lies within rperp of the bent axis: the arc from p0 to
    // p1 and its tangent extensions (cb_bend_apply).
    Box curve;
    const glm::dvec3 p1 = p0 + b.len * u;
    const glm::dvec3 t0 = b.ch * u + b.sh * v, t1 = b.ch * u - b.sh * v;
    curve.expand(p0);
    curve.expand(p1);
    if (amin < 0.0)
        curve.expand(p0 + (amin / b.lscale) * t0);
    if (amax > b.len)
        curve.expand(p1 + ((amax - b.len) / b.lscale) * t1);
    const double h = 0.5 * b.theta;
    const glm::dvec3 centre = p0 + 0.5 * b.len * u - b.rho * b.ch * v;
    for (int k = 0; k < 3; ++k) {
        const double phi = std::atan2(u[k], v[k]);
        for (double cand : {phi, phi - M_PI, phi + M_PI})
            if (cand > -h && cand < h)
                curve.expand(centre + b.rho * (std::sin(cand) * u + std::cos(cand) * v));
    }
    return curve.padded(rperp);
}

}  // namespace

Box warpImage(const Node& n, const Box& box)
{
    if (box.empty())
        return box;
    switch (n.type) {
        case NodeType::TRANSFORM:
            return affineImage(box, std::get<TransformParams>(n.params).forward);
        case NodeType::BEND:
            return bendImage(std::get<cb_bend>(n.params), box);
        case NodeType::TWIST: {
            // A twist turns points about its axis: height and distance are kept.
            const cb_twist& t = std::get<cb_twist>(n.params);
            const glm::dvec3 o = toGlm(t.o), a = toGlm(t.a);
            double hmin, hmax, rmax;
            axialExtent(box, o, a, hmin, hmax, rmax);
            return cylinderBox(o + hmin * a, o + hmax * a, a, rmax);
        }
        case NodeType::TAPER: {
            // A taper scales distances from its axis by at most max(scale0, scale1).
            const cb_taper& t = std::get<cb_taper>(n.params);
            const glm::dvec3 o = toGlm(t.o), a = toGlm(t.a);
            double hmin, hmax, rmax;
            axialExtent(box, o, a, hmin, hmax, rmax);
            return cylinderBox(o + hmin * a, o + hmax * a, a, rmax * std::max(t.scale0, t.scale1));
        }
        default:
            return box;
    }
}

std::vector<NodeBounds> computeBounds(const BlobTree& tree)
{
    std::vector<NodeBounds> out(tree.size());
    const double xT = tree.xT();
    // Children precede parents, so one forward sweep sees every child first.
    for (size_t i = 0; i < tree.size(); ++i) {
        const Node& n = tree.node(int(i));
        NodeBounds& b = out[i];
        switch (kindOf(n.type)) {
            case NodeKind::Primitive: {
                const Primitive& p = n.prim();
                const double reach = n.type == NodeType::CONVOLUTION_SEGMENT
                                         ? p.support
                                         : cb_skeletal_reach(std::max(p.r0, p.r1), p.sigma, xT);
                b.support = segmentBox(p.p0, p.p1, reach);
                if (p.weight > 0.0)
                    b.positive = b.support;
                break;
            }
            case NodeKind::Operator: {
                for (int c : n.children)
                    b.support.expand(out[size_t(c)].support);
                const NodeType how = n.type == NodeType::GBB ? NodeType::GBB : n.combiner().type;
                if (how == NodeType::INTERSECTION) {
                    b.positive = out[size_t(n.children[0])].positive;
                    for (int c : n.children)
                        b.positive = b.positive.intersected(out[size_t(c)].positive);
                } else if (how == NodeType::DIFFERENCE) {
                    b.positive = out[size_t(n.children[0])].positive;
                } else {
                    // Sums, Ricci, PCM, better blending and union are positive only
                    // where some child is (PCM's bulge needs f_other > T - width >= 0).
                    // A GBB is a convex mix of two such combinations; an intersection
                    // or difference inside it is bounded by the union too.
                    for (int c : n.children)
                        b.positive.expand(out[size_t(c)].positive);
                }
                break;
            }
            case NodeKind::Warp:
                b.support = warpImage(n, out[size_t(n.children[0])].support);
                b.positive = warpImage(n, out[size_t(n.children[0])].positive);
                break;
        }
    }
    return out;
}

Box surfaceBounds(const BlobTree& tree)
{
    return computeBounds(tree)[size_t(tree.root())].positive;
}

}  // namespace cambium
