// cambium — the tree builder.
#include "model/tree_builder.h"

#include "core/error.h"
#include "core/math.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <unordered_map>

namespace cambium {

double basalShortening(const TreeBuildOptions& o, double rA,
                       const std::vector<double>& childBaseRadii,
                       const std::vector<double>& childTipRadii)
{
    if (childBaseRadii.empty())
        return 0.0;
    if (childBaseRadii.size() == 1 || o.junction == TreeBuildOptions::Junction::Smooth)
        return 1.75 * *std::max_element(childTipRadii.begin(), childTipRadii.end());     // eq. 3
    return 2.75 * *std::max_element(childBaseRadii.begin(), childBaseRadii.end()) - rA;  // eq. 7
}

void checkTreeBuildOptions(const TreeBuildOptions& o)
{
    if (!(o.regrowth >= 0.0 && o.regrowth <= 1.0))
        throw InputError(fmt::format("--regrowth must be between 0 and 1 (got {})", o.regrowth));
    const BarkDetail& b = o.barkDetail;
    if (!(b.depth >= 0.0 && b.depth <= 0.28))
        throw InputError(fmt::format(
            "bark depth must be from 0 to 0.28 of the radius (got {}): deeper furrows would "
            "cut through the stem",
            b.depth));
    if (!(b.maxDepth >= 0.0 && std::isfinite(b.maxDepth)))
        throw InputError(fmt::format("bark max_depth must be a length >= 0 (got {})", b.maxDepth));
    if (!(b.startAge >= 0.0 && b.fullAge > b.startAge && std::isfinite(b.fullAge)))
        throw InputError(
            fmt::format("bark ages: start_age ({}) must be >= 0 and below full_age ({})",
                        b.startAge, b.fullAge));
    if (!(b.around >= 1.0 && b.around <= 512.0 && b.around == std::floor(b.around)))
        throw InputError(
            fmt::format("bark around must be a whole number from 1 to 512 (got {})", b.around));
    if (!(b.along >= 0.0 && b.along <= 1e4))
        throw InputError(fmt::format("bark along must be from 0 to 10000 (got {})", b.along));
}

double BarkDetail::depthAt(double r, double age) const
{
    if (depth <= 0.0 || !(age > startAge))
        return 0.0;
    const double u = std::min(1.0, (age - startAge) / (fullAge - startAge));
    return std::min({depth * r, maxDepth, 0.28 * r}) * u * u * (3.0 - 2.0 * u);
}

namespace {

using Primitives = TreeBuildOptions::Primitives;

/// The skeleton's links by internode index (its ids may be anything).
struct Topology {
    std::vector<std::vector<size_t>> children;
    std::vector<long long> parent;    ///< -1 for a root
    std::vector<long long> thickest;  ///< the thickest child (the first of equals), -1 for none
    /// The main axis: a root, and the thickest child of each internode on
    /// it; the rest are laterals.
    std::vector<bool> onAxis;
};

Topology indexSkeleton(const Skeleton& sk)
{
    const size_t n = sk.internodes.size();
    Topology g;
    std::unordered_map<long long, size_t> index;
    for (size_t i = 0; i < n; ++i)
        index[sk.internodes[i].id] = i;
    g.children.resize(n);
    g.parent.assign(n, -1);
    for (size_t i = 0; i < n; ++i)
        if (const auto it = index.find(sk.internodes[i].parent); it != index.end()) {
            g.children[it->second].push_back(i);
            g.parent[i] = (long long)it->second;
        }

    g.thickest.assign(n, -1);
    for (size_t i = 0; i < n; ++i)
        for (size_t k : g.children[i])
            if (g.thickest[i] < 0 || sk.internodes[k].r0 > sk.internodes[size_t(g.thickest[i])].r0)
                g.thickest[i] = (long long)k;
    g.onAxis.assign(n, false);
    for (size_t i = 0; i < n; ++i) {
        if (g.parent[i] < 0)
            g.onAxis[i] = true;
        if (g.onAxis[i] && g.thickest[i] >= 0)
            g.onAxis[size_t(g.thickest[i])] = true;
    }
    return g;
}

/// Whether internode i is a cone (with the rules) rather than a convolution
/// segment; the children that count at a junction are its cones (in mixed
/// mode, only the main axis is in cones).
bool isCone(const TreeBuildOptions& o, const Topology& g, size_t i)
{
    return o.primitives == Primitives::Cone || (o.primitives == Primitives::Mixed && g.onAxis[i]);
}

/// Each internode's skeleton after the junction rules: its tip pulled back
/// by delta_A, its base moved off a shared branching point by delta_Bi.
struct Segments {
    std::vector<glm::dvec3> p0, p1;
    std::vector<double> r0, r1;
};

/// The internodes as the skeleton has them; InputError for one whose ends coincide.
Segments skeletonSegments(const Skeleton& sk)
{
    const size_t n = sk.internodes.size();
    Segments s{std::vector<glm::dvec3>(n), std::vector<glm::dvec3>(n), std::vector<double>(n),
               std::vector<double>(n)};
    for (size_t i = 0; i < n; ++i) {
        const Internode& a = sk.internodes[i];
        const double len = glm::length(a.p1 - a.p0);
        if (!(len > 0.0))
            throw InputError(fmt::format("internode {}: its two ends coincide", a.id));
        s.p0[i] = a.p0;
        s.p1[i] = a.p1;
        s.r0[i] = a.r0;
        s.r1[i] = a.r1;
    }
    return s;
}

/// Pulls back the tip of each basal cone by delta_A (eq. 3, 7), and adds to
/// `baseShift` how far the bases of its branches move along their axes (eq. 6).
void shortenBasalInternodes(const Skeleton& sk, const TreeBuildOptions& o, const Topology& g,
                            Segments& s, std::vector<double>& baseShift)
{
    const size_t n = sk.internodes.size();
    auto moveTip = [&](size_t i, double by) {
        // Along the internode's own axis, the radius following its taper.
        const Internode& a = sk.internodes[i];
        const glm::dvec3 axis = a.p1 - a.p0;
        // An internode short for its radii loses at most half its length.
        const double t = std::max(1.0 - by / glm::length(axis), 0.5);
        s.p1[i] = a.p0 + t * axis;
        s.r1[i] = a.r0 + t * (a.r1 - a.r0);
    };
    for (size_t i = 0; i < n; ++i) {
        if (!isCone(o, g, i))
            continue;  // convolution segments join without the rules
        std::vector<size_t> c;
        for (size_t k : g.children[i])
            if (isCone(o, g, k))
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
            baseShift[size_t(g.thickest[i])] += deltaA - half;
    }
}

/// Moves each internode's base along its axis by its `baseShift`.
void moveBases(const Skeleton& sk, const std::vector<double>& baseShift, Segments& s)
{
    const size_t n = sk.internodes.size();
    for (size_t k = 0; k < n; ++k)
        if (baseShift[k] > 0.0) {
            // At most half its length, and a tenth must stay after its own tip moved.
            const Internode& a = sk.internodes[k];
            const glm::dvec3 axis = a.p1 - a.p0;
            const double tipAt = glm::dot(s.p1[k] - a.p0, axis) / glm::dot(axis, axis);
            const double t = std::min({baseShift[k] / glm::length(axis), 0.5, tipAt - 0.1});
            s.p0[k] = a.p0 + t * axis;
            s.r0[k] = a.r0 + t * (a.r1 - a.r0);
        }
}

/// The tree as it is assembled: the nodes of the top-level summation, the
/// convolution segments (summed on their own, then better-blended with the
/// rest), and each junction's branches (combined by PCM).
struct Assembly {
    BlobTree tree;
    std::vector<int> top, convolution;
    std::vector<std::vector<int>> groups;  // junction -> its branches' nodes
};

/// A saw cut through the skeleton's end, across the axis, of `node` (internode
/// `a`), and the callus over it when the options regrow one (into `top`).
int sawCut(const Internode& a, int node, const TreeBuildOptions& o, Assembly& out)
{
    BlobTree& tree = out.tree;
    // The difference with a sphere so large that over the cut face (radius
    // r) it departs from the plane by r^2 / 2R = r / 2000.  Its field
    // rises from 0 to 1 within 4 r of its surface (a narrow support),
    // so that elsewhere it leaves the branch's field as it is.
    const double r = std::max(a.r0, a.r1), R = 1000.0 * r;
    PrimitiveOptions cutter;
    cutter.support = 4.0 * r / tree.xT();
    const glm::dvec3 axis = glm::normalize(a.p1 - a.p0);
    node = tree.op({NodeType::DIFFERENCE}, {node, tree.sphere(a.p1 + R * axis, R, cutter)});
    if (o.regrowth > 0.0) {
        // The callus: from 1.5 radii below the cut to a little beyond
        // it, thicker than the branch at its base, closing at its tip.
        const double g = o.regrowth, rc = a.r1;
        out.top.push_back(tree.convolutionSegment(a.p1 - 1.5 * rc * axis,
                                                  a.p1 + 0.6 * g * rc * axis, rc * (0.6 + 0.3 * g),
                                                  rc * (0.3 + 0.5 * g)));
    }
    return node;
}

/// The bark's coordinates of every internode, from the skeleton alone (so
/// that they stay with the wood from frame to frame): the arc length of its
/// base along its branch, the reference direction (theta = 0) carried along
/// the branch by the rotation between successive axes, and the branch's phase.
struct BarkFrames {
    std::vector<double> s0;
    std::vector<glm::dvec3> reference;
    std::vector<double> phase;
    std::vector<long long> next;  ///< the internode continuing the branch, -1 for none
};

/// Whether internode i continues its parent's branch: the same branch (its
/// module) when the skeleton says, else its parent's thickest child.
bool continuesBranch(const Skeleton& sk, const Topology& g, size_t i)
{
    const long long p = g.parent[i];
    if (p < 0)
        return false;
    const Internode &a = sk.internodes[i], &b = sk.internodes[size_t(p)];
    if (a.module >= 0 && b.module >= 0)
        return a.module == b.module;
    return g.thickest[size_t(p)] == (long long)i;
}

BarkFrames barkFrames(const Skeleton& sk, const Topology& g, uint64_t seed)
{
    const size_t n = sk.internodes.size();
    BarkFrames f;
    f.s0.assign(n, 0.0);
    f.reference.assign(n, glm::dvec3(0.0));
    f.phase.assign(n, 0.0);
    f.next.assign(n, -1);
    std::vector<char> done(n, 0), visiting(n, 0);
    std::vector<size_t> chain;
    for (size_t start = 0; start < n; ++start) {
        // Up to the first internode whose frame is known or that begins a branch.
        // (A cycle of parents, which a malformed skeleton may hold, ends the
        // walk where it closes: that internode begins a branch.)
        chain.clear();
        for (size_t i = start; !done[i] && !visiting[i];) {
            chain.push_back(i);
            visiting[i] = 1;
            if (!continuesBranch(sk, g, i))
                break;
            i = size_t(g.parent[i]);
        }
        for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
            const size_t i = *it;
            const Internode& a = sk.internodes[i];
            const glm::dvec3 axis = glm::normalize(a.p1 - a.p0);
            if (continuesBranch(sk, g, i) && done[size_t(g.parent[i])]) {
                const size_t p = size_t(g.parent[i]);
                const Internode& b = sk.internodes[p];
                const glm::dvec3 from = glm::normalize(b.p1 - b.p0);
                // The minimal rotation from `from` to `axis` applied to the
                // parent's reference (Rodrigues), then made exactly across.
                const glm::dvec3 k = glm::cross(from, axis);
                const double c = glm::dot(from, axis), sn = glm::length(k);
                glm::dvec3 r = f.reference[p];
                if (sn > 1e-12) {
                    const glm::dvec3 u = k / sn;
                    r = r * c + glm::cross(u, r) * sn + u * glm::dot(u, r) * (1.0 - c);
                }
                f.reference[i] = unitAcross(r, axis);
                f.s0[i] = f.s0[p] + glm::length(b.p1 - b.p0);
                f.phase[i] = f.phase[p];
                f.next[p] = (long long)i;
            } else {
                // A branch begins: its reference points up its parent's axis
                // (or along the world's x for a root), its phase from its id.
                const long long p = g.parent[i];
                const glm::dvec3 up =
                    p >= 0 ? sk.internodes[size_t(p)].p1 - sk.internodes[size_t(p)].p0
                           : glm::dvec3(1.0, 0.0, 0.0);
                f.reference[i] = unitAcross(up, axis);
                f.s0[i] = 0.0;
                uint64_t h = seed * 0x9e3779b97f4a7c15ull ^ uint64_t(a.id) * 0xbf58476d1ce4e5b9ull;
                h ^= h >> 31;
                h *= 0x94d049bb133111ebull;
                h ^= h >> 29;
                f.phase[i] = double(h >> 11) * 0x1.0p-53 * 6.283185307179586;
            }
            done[i] = 1;
        }
    }
    return f;
}

/// Internode i's bark on its cone (from s.p0 to s.p1, which the junction
/// rules may have moved along the skeleton's axis).
void addBark(const Skeleton& sk, const TreeBuildOptions& o, const Segments& s, const BarkFrames& f,
             size_t i, int node, BlobTree& tree)
{
    const BarkDetail& b = o.barkDetail;
    const Internode& a = sk.internodes[i];
    // The tip's age is its continuation's (younger) so that depths meet.
    const double tipAge = f.next[i] >= 0 && sk.internodes[size_t(f.next[i])].age >= 0.0
                              ? sk.internodes[size_t(f.next[i])].age
                              : a.age;
    // Every cone gets its bark coordinates (the photo's coherent colours
    // read them); furrows only where the bark is old enough.
    BarkParams p;
    if (a.age >= 0.0) {
        p.depth0 = b.depthAt(s.r0[i], a.age);
        p.depth1 = b.depthAt(s.r1[i], tipAge);
    }
    const glm::dvec3 axis = glm::normalize(a.p1 - a.p0);
    const glm::dvec3 cone = s.p1[i] - s.p0[i];
    if (glm::dot(glm::normalize(cone), axis) < 1.0 - 1e-9)
        return;  // the rules turned it (cannot happen with cones today): leave it smooth
    p.reference = f.reference[i];
    p.s0 = f.s0[i] + glm::dot(s.p0[i] - a.p0, axis);
    p.around = b.around;
    p.along = b.along;
    p.phase = f.phase[i];
    tree.setBark(node, p);
}

/// Each internode's primitive (cut, bent), into its junction's group, the
/// convolution segments or the top-level summation.
void addInternodes(const Skeleton& sk, const TreeBuildOptions& o, const Topology& g,
                   const Segments& s, Assembly& out)
{
    const size_t n = sk.internodes.size();
    BlobTree& tree = out.tree;
    const BarkFrames frames = barkFrames(sk, g, o.barkDetail.seed);
    for (size_t i = 0; i < n; ++i) {
        int node = isCone(o, g, i) ? tree.cone(s.p0[i], s.p1[i], s.r0[i], s.r1[i])
                                   : tree.convolutionSegment(s.p0[i], s.p1[i], s.r0[i], s.r1[i]);
        if (isCone(o, g, i) && !frames.s0.empty())
            addBark(sk, o, s, frames, i, node, tree);
        if (sk.internodes[i].colour)
            tree.setColor(node, *sk.internodes[i].colour);
        if (sk.internodes[i].cut)
            node = sawCut(sk.internodes[i], node, o, out);
        if (o.bend != 0.0 && g.parent[i] >= 0) {
            const Internode& b = sk.internodes[size_t(g.parent[i])];
            const glm::dvec3 hA = glm::normalize(b.p1 - b.p0),
                             h = glm::normalize(s.p1[i] - s.p0[i]);
            glm::dvec3 away = h - glm::dot(h, hA) * hA;  // off the basal axis, in the plane of both
            // (at right angles that is the lateral's own axis, which picks no
            // plane, and ABOP's default 90 degrees was refused: the basal
            // axis reversed picks the side a lateral just short of it bends to)
            if (std::abs(glm::dot(h, hA)) < 1e-6)
                away = -hA;
            if (glm::length(away) > 1e-3)
                node = tree.bend(s.p0[i], s.p1[i], glm::normalize(away), o.bend, node);
        }
        if (!isCone(o, g, i)) {
            out.convolution.push_back(node);
            continue;
        }
        const bool branch = o.primitives == Primitives::Cone && g.parent[i] >= 0 &&
                            g.children[size_t(g.parent[i])].size() > 1 &&
                            o.junction == TreeBuildOptions::Junction::Pcm;
        (branch ? out.groups[size_t(g.parent[i])] : out.top).push_back(node);
    }
}

/// The scars of shed organs, into the top-level summation.
void addScars(const Skeleton& sk, const TreeBuildOptions& o, Assembly& out)
{
    BlobTree& tree = out.tree;
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
            out.top.push_back(node);
        }
    }
}

/// The primitive of a bud, a bud scale scar ring or a leaf.
int organNode(BlobTree& tree, const Organ& organ)
{
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
            const glm::dvec3 normal =
                glm::normalize(organ.normal - along * glm::dot(organ.normal, along));
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
    return node;
}

/// Each junction's group of branches: PCM, or, with ridges over time, the
/// summation blending into PCM as the junction ages.
void addJunctions(const Skeleton& sk, const TreeBuildOptions& o, const Topology& g, Assembly& out)
{
    const size_t n = sk.internodes.size();
    BlobTree& tree = out.tree;
    Combiner pcm{NodeType::PCM};
    pcm.width = o.pcmWidth;
    pcm.attenuation = o.pcmAttenuation;
    pcm.darken = o.ridgeDarken;
    for (size_t i = 0; i < n; ++i) {  // in skeleton order: the same tree every time
        const std::vector<int>& group = out.groups[i];
        if (group.empty())
            continue;
        // The junction's age and thinnest branch (ridges over time).
        double age = 1e300, thinnest = 1e300;
        glm::dvec3 lateral{0.0};
        for (size_t k : g.children[i])
            if (isCone(o, g, k)) {
                age = std::min(age, sk.internodes[k].age);
                if (sk.internodes[k].r0 < thinnest) {
                    thinnest = sk.internodes[k].r0;
                    lateral = glm::normalize(sk.internodes[k].p1 - sk.internodes[k].p0);
                }
            }
        if (o.ridgeYears <= 0.0 || age < 0.0) {
            out.top.push_back(tree.op(pcm, group));
            continue;
        }
        const double support = smoothstep(0.0, o.ridgeYears, age) * o.ridgeRadius * thinnest;
        if (support < 1e-6 * thinnest) {
            out.top.insert(out.top.end(), group.begin(),
                           group.end());  // a new junction: the summation alone
            continue;
        }
        // Fb = 1 along the thinnest branch's axis through the bark of its
        // parent, falling to 0 `support` away: the collar where the ridge forms.
        PrimitiveOptions bound;
        bound.support = support;
        const glm::dvec3 at = sk.internodes[i].p1;
        const int fb = tree.segment(at, at + (sk.internodes[i].r1 + 2.0 * thinnest) * lateral,
                                    0.5 * support, bound);
        out.top.push_back(tree.gbb(fb, group, pcm, {NodeType::BLEND}));
    }
}

/// The root: the top-level summation, the convolution segments' summation,
/// or the two better-blended; in the bark's colour.
void setRoot(const TreeBuildOptions& o, Assembly& out)
{
    BlobTree& tree = out.tree;
    auto sum = [&](const std::vector<int>& nodes) {
        return nodes.size() == 1 ? nodes[0] : tree.op({NodeType::BLEND}, nodes);
    };
    if (out.convolution.empty()) {
        tree.setRoot(sum(out.top));
    } else if (out.top.empty()) {
        tree.setRoot(sum(out.convolution));
    } else {
        Combiner better{NodeType::BETTER_BLEND};
        better.k = o.betterBlendK;
        tree.setRoot(tree.op(better, {sum(out.top), sum(out.convolution)}));
    }
    tree.setColor(tree.root(), o.bark);
}

}  // namespace

BlobTree buildTree(const Skeleton& sk, const TreeBuildOptions& o)
{
    const size_t n = sk.internodes.size();
    if (n == 0)
        throw InputError("the skeleton has no internodes");
    checkTreeBuildOptions(o);
    const Topology g = indexSkeleton(sk);

    Segments s = skeletonSegments(sk);
    std::vector<double> baseShift(n, 0.0);  // how far each internode's base moves along its axis
    shortenBasalInternodes(sk, o, g, s, baseShift);
    moveBases(sk, baseShift, s);

    Assembly out;
    out.groups.resize(n);
    // Most internodes are a cone, a parent's junction adds two, and a scar or
    // a leaf two: room for all of them, so that no node moves while building.
    out.tree.reserve(2 * (n + sk.scars.size() + sk.organs.size()) + 1);
    addInternodes(sk, o, g, s, out);
    addScars(sk, o, out);
    for (const Organ& organ : sk.organs) {
        const int node = organNode(out.tree, organ);
        out.tree.setColor(node, organ.colour);
        out.top.push_back(node);
    }
    addJunctions(sk, o, g, out);
    setRoot(o, out);
    out.tree.setBarkLook({o.barkPhoto, o.bark, o.barkCoherent});
    out.tree.finalize();
    return std::move(out.tree);
}

}  // namespace cambium
