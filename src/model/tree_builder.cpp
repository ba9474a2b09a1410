// cambium — the tree builder.
#include "model/tree_builder.h"

#include "core/error.h"
#include "core/math.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace cambium {

double basalShortening(const TreeBuildOptions& o, double rA, const std::vector<double>& childBaseRadii,
                       const std::vector<double>& childTipRadii)
{
    if (childBaseRadii.empty())
        return 0.0;
    if (childBaseRadii.size() == 1 || o.junction == TreeBuildOptions::Junction::Smooth)
        return 1.75 * *std::max_element(childTipRadii.begin(), childTipRadii.end());  // eq. 3
    return 2.75 * *std::max_element(childBaseRadii.begin(), childBaseRadii.end()) - rA;  // eq. 7
}

void checkTreeBuildOptions(const TreeBuildOptions& o)
{
    if (!(o.regrowth >= 0.0 && o.regrowth <= 1.0))
        throw InputError(fmt::format("--regrowth must be between 0 and 1 (got {})", o.regrowth));
}

BlobTree buildTree(const Skeleton& sk, const TreeBuildOptions& o)
{
    const size_t n = sk.internodes.size();
    if (n == 0)
        throw InputError("the skeleton has no internodes");
    checkTreeBuildOptions(o);
    std::unordered_map<long long, size_t> index;
    for (size_t i = 0; i < n; ++i)
        index[sk.internodes[i].id] = i;
    std::vector<std::vector<size_t>> children(n);
    std::vector<long long> parent(n, -1);
    for (size_t i = 0; i < n; ++i)
        if (const auto it = index.find(sk.internodes[i].parent); it != index.end()) {
            children[it->second].push_back(i);
            parent[i] = (long long)it->second;
        }

    // Each internode's thickest child (the first of equals), -1 for none.
    std::vector<long long> thickest(n, -1);
    for (size_t i = 0; i < n; ++i)
        for (size_t k : children[i])
            if (thickest[i] < 0 || sk.internodes[k].r0 > sk.internodes[size_t(thickest[i])].r0)
                thickest[i] = (long long)k;
    // The main axis: a root, and the thickest child of each internode on it;
    // the rest are laterals.
    std::vector<bool> onAxis(n, false);
    for (size_t i = 0; i < n; ++i) {
        if (parent[i] < 0)
            onAxis[i] = true;
        if (onAxis[i] && thickest[i] >= 0)
            onAxis[size_t(thickest[i])] = true;
    }
    using P = TreeBuildOptions::Primitives;
    // Internodes that are cones (with the rules) and the children that count
    // at their junctions (in mixed mode, only cones).
    auto isCone = [&](size_t i) { return o.primitives == P::Cone || (o.primitives == P::Mixed && onAxis[i]); };

    // Each internode's skeleton after the junction rules: its tip pulled back
    // by delta_A, its base moved off a shared branching point by delta_Bi.
    std::vector<glm::dvec3> p0(n), p1(n);
    std::vector<double> r0(n), r1(n);
    for (size_t i = 0; i < n; ++i) {
        const Internode& a = sk.internodes[i];
        const double len = glm::length(a.p1 - a.p0);
        if (!(len > 0.0))
            throw InputError(fmt::format("internode {}: its two ends coincide", a.id));
        p0[i] = a.p0;
        p1[i] = a.p1;
        r0[i] = a.r0;
        r1[i] = a.r1;
    }
    std::vector<double> baseShift(n, 0.0);  // how far each internode's base moves along its axis
    auto moveTip = [&](size_t i, double by) {
        // Along the internode's own axis, the radius following its taper.
        const Internode& a = sk.internodes[i];
        const glm::dvec3 axis = a.p1 - a.p0;
        // An internode short for its radii loses at most half its length.
        const double t = std::max(1.0 - by / glm::length(axis), 0.5);
        p1[i] = a.p0 + t * axis;
        r1[i] = a.r0 + t * (a.r1 - a.r0);
    };
    for (size_t i = 0; i < n; ++i) {
        if (!isCone(i))
            continue;  // convolution segments join without the rules
        std::vector<size_t> c;
        for (size_t k : children[i])
            if (isCone(k))
                c.push_back(k);
        if (c.empty())
            continue;
        std::vector<double> base, tip;
        for (size_t k : c) {
            base.push_back(sk.internodes[k].r0);
            tip.push_back(sk.internodes[k].r1);
        }
        const double rA = sk.internodes[i].r1;
        const double deltaA = basalShortening(o, rA, base, tip);  // negative: lengthened (eq. 7)
        moveTip(i, deltaA);
        if (c.size() > 1 && o.junction == TreeBuildOptions::Junction::Pcm)
            for (size_t k : c)
                if (const double d = rA - sk.internodes[k].r0; d > 0.0)
                    baseShift[k] += d;  // eq. 6
        // A basal internode shorter than twice delta_A gives only half its
        // length; the continuation (the thickest child, a cone whenever this
        // one is) gives the rest from its base, so that the gap between them
        // is still delta_A and their joint stays flat (short thick internodes
        // of old wood).
        const double half = 0.5 * glm::length(sk.internodes[i].p1 - sk.internodes[i].p0);
        if (deltaA > half)
            baseShift[size_t(thickest[i])] += deltaA - half;
    }
    for (size_t k = 0; k < n; ++k)
        if (baseShift[k] > 0.0) {
            // At most half its length, and a tenth must stay after its own tip moved.
            const Internode& a = sk.internodes[k];
            const glm::dvec3 axis = a.p1 - a.p0;
            const double tipAt = glm::dot(p1[k] - a.p0, axis) / glm::dot(axis, axis);
            const double t = std::min({baseShift[k] / glm::length(axis), 0.5, tipAt - 0.1});
            p0[k] = a.p0 + t * axis;
            r0[k] = a.r0 + t * (a.r1 - a.r0);
        }

    BlobTree tree;
    std::vector<int> top, convolution;
    std::vector<std::vector<int>> groups(n);  // junction -> its branches' nodes
    for (size_t i = 0; i < n; ++i) {
        int node = isCone(i) ? tree.cone(p0[i], p1[i], r0[i], r1[i])
                             : tree.convolutionSegment(p0[i], p1[i], r0[i], r1[i]);
        if (sk.internodes[i].colour)
            tree.setColor(node, *sk.internodes[i].colour);
        if (sk.internodes[i].cut) {
            // A saw cut through the skeleton's end, across the axis: the
            // difference with a sphere so large that over the cut face (radius
            // r) it departs from the plane by r^2 / 2R = r / 2000.  Its field
            // rises from 0 to 1 within 4 r of its surface (a narrow support),
            // so that elsewhere it leaves the branch's field as it is.
            const Internode& a = sk.internodes[i];
            const double r = std::max(a.r0, a.r1), R = 1000.0 * r;
            PrimitiveOptions cutter;
            cutter.support = 4.0 * r / tree.xT();
            const glm::dvec3 axis = glm::normalize(a.p1 - a.p0);
            node = tree.op({NodeType::DIFFERENCE}, {node, tree.sphere(a.p1 + R * axis, R, cutter)});
            if (o.regrowth > 0.0) {
                // The callus: from 1.5 radii below the cut to a little beyond
                // it, thicker than the branch at its base, closing at its tip.
                const double g = o.regrowth, rc = a.r1;
                top.push_back(tree.convolutionSegment(a.p1 - 1.5 * rc * axis, a.p1 + 0.6 * g * rc * axis,
                                                      rc * (0.6 + 0.3 * g), rc * (0.3 + 0.5 * g)));
            }
        }
        if (o.bend != 0.0 && parent[i] >= 0) {
            const Internode& b = sk.internodes[size_t(parent[i])];
            const glm::dvec3 hA = glm::normalize(b.p1 - b.p0), h = glm::normalize(p1[i] - p0[i]);
            const glm::dvec3 away = h - glm::dot(h, hA) * hA;  // off the basal axis, in the plane of both
            if (glm::length(away) > 1e-3)
                node = tree.bend(p0[i], p1[i], glm::normalize(away), o.bend, node);
        }
        if (!isCone(i)) {
            convolution.push_back(node);
            continue;
        }
        const bool branch = o.primitives == P::Cone && parent[i] >= 0 &&
                            children[size_t(parent[i])].size() > 1 && o.junction == TreeBuildOptions::Junction::Pcm;
        (branch ? groups[size_t(parent[i])] : top).push_back(node);
    }
    for (const Scar& scar : sk.scars) {
        // The shortened stub, and the negative field that presses the scar in;
        // both the colour of the wood under the bark.
        std::vector<int> nodes{tree.cone(scar.base, scar.tip, scar.radius, scar.radius)};
        PrimitiveOptions negative;
        negative.weight = o.scarWeight * scar.weight;
        if (std::abs(negative.weight) > 1e-6)
            nodes.push_back(tree.sphere(scar.tip, o.scarRadius * scar.radius, negative));
        for (int node : nodes) {
            tree.setColor(node, 0.5 * o.bark);
            top.push_back(node);
        }
    }
    for (const Organ& organ : sk.organs) {
        int node = -1;
        switch (organ.kind) {
        case Organ::Kind::Bud:
            node = tree.sphere(organ.p0, organ.radius);
            break;
        case Organ::Kind::Ring: {
            PrimitiveOptions ring;
            ring.weight = organ.weight;
            node = tree.cone(organ.p0, organ.p1, organ.radius, organ.radius, ring);
            break;
        }
        case Organ::Kind::Leaf: {
            // The unit sphere mapped onto the blade's ellipsoid.
            const glm::dvec3 a = 0.5 * (organ.p1 - organ.p0);
            const glm::dvec3 along = glm::normalize(a);
            const glm::dvec3 normal = glm::normalize(organ.normal - along * glm::dot(organ.normal, along));
            const glm::dvec3 wide = glm::cross(normal, along);
            glm::dmat4 m(1.0);
            m[0] = glm::dvec4(a, 0.0);
            m[1] = glm::dvec4(organ.radius * wide, 0.0);
            m[2] = glm::dvec4(organ.thickness * normal, 0.0);
            m[3] = glm::dvec4(organ.p0 + a, 1.0);
            node = tree.transform(m, tree.sphere(glm::dvec3(0.0), 1.0));
            break;
        }
        }
        tree.setColor(node, organ.colour);
        top.push_back(node);
    }
    Combiner pcm{NodeType::PCM};
    pcm.width = o.pcmWidth;
    pcm.attenuation = o.pcmAttenuation;
    pcm.darken = o.ridgeDarken;
    for (size_t i = 0; i < n; ++i) {  // in skeleton order: the same tree every time
        const std::vector<int>& group = groups[i];
        if (group.empty())
            continue;
        // The junction's age and thinnest branch (ridges over time).
        double age = 1e300, thinnest = 1e300;
        glm::dvec3 lateral{0.0};
        for (size_t k : children[i])
            if (isCone(k)) {
                age = std::min(age, sk.internodes[k].age);
                if (sk.internodes[k].r0 < thinnest) {
                    thinnest = sk.internodes[k].r0;
                    lateral = glm::normalize(sk.internodes[k].p1 - sk.internodes[k].p0);
                }
            }
        if (o.ridgeYears <= 0.0 || age < 0.0) {
            top.push_back(tree.op(pcm, group));
            continue;
        }
        const double support = smoothstep(0.0, o.ridgeYears, age) * o.ridgeRadius * thinnest;
        if (support < 1e-6 * thinnest) {
            top.insert(top.end(), group.begin(), group.end());  // a new junction: the summation alone
            continue;
        }
        // Fb = 1 along the thinnest branch's axis through the bark of its
        // parent, falling to 0 `support` away: the collar where the ridge forms.
        PrimitiveOptions bound;
        bound.support = support;
        const glm::dvec3 at = sk.internodes[i].p1;
        const int fb = tree.segment(at, at + (sk.internodes[i].r1 + 2.0 * thinnest) * lateral, 0.5 * support, bound);
        top.push_back(tree.gbb(fb, group, pcm, {NodeType::BLEND}));
    }
    auto sum = [&](const std::vector<int>& nodes) {
        return nodes.size() == 1 ? nodes[0] : tree.op({NodeType::BLEND}, nodes);
    };
    if (convolution.empty()) {
        tree.setRoot(sum(top));
    } else if (top.empty()) {
        tree.setRoot(sum(convolution));
    } else {
        Combiner better{NodeType::BETTER_BLEND};
        better.k = o.betterBlendK;
        tree.setRoot(tree.op(better, {sum(top), sum(convolution)}));
    }
    tree.setColor(tree.root(), o.bark);
    tree.finalize();
    return tree;
}

}  // namespace cambium
