// cambium — thin parts thickened to a bake's smallest radius.
#include "bake/thicken.h"

#include "cb_primitives.h"
#include "cb_warps.h"
#include "core/error.h"

#include <fmt/format.h>

#include <openvdb/math/Mat3.h>

#include <algorithm>
#include <cmath>
#include <variant>
#include <vector>

namespace cambium {

namespace {

/// The eigenvalues (ascending) and unit eigenvectors of the symmetric
/// 3x3 matrix s.
struct Eigen3 {
    double value[3];
    glm::dvec3 vector[3];
};

Eigen3 symmetricEigen(const glm::dmat3& s)
{
    openvdb::math::Mat3d m;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            m(r, c) = s[c][r];
    openvdb::math::Mat3d q;
    openvdb::math::Vec3d d;
    openvdb::math::diagonalizeSymmetricMatrix(m, q, d);
    int order[3] = {0, 1, 2};
    std::sort(order, order + 3, [&](int a, int b) { return d[a] < d[b]; });
    Eigen3 e;
    for (int k = 0; k < 3; ++k) {
        e.value[k] = std::max(d[order[k]], 0.0);
        // (the eigenvectors are q's columns: m = q diag(d) q^T)
        e.vector[k] = glm::normalize(glm::dvec3(q(0, order[k]), q(1, order[k]), q(2, order[k])));
    }
    return e;
}

/// The least a linear map `a` stretches a direction across `axis` (a unit
/// vector; zero: any direction): the smallest half-width, over the radius,
/// of the world cross-section of a cylinder along `axis`, i.e. across the
/// axis's image w.  That cross-section is the disc across the axis mapped
/// by `a` and projected across w (under shear or uneven scaling the disc's
/// image is a slanted slice, wider than the cross-section): the smaller
/// singular value of (I - w w^T) a on the disc's plane.  On all of space:
/// the smallest singular value of `a`.
double leastStretch(const glm::dmat3& a, const glm::dvec3& axis)
{
    if (axis == glm::dvec3(0.0))
        return std::sqrt(symmetricEigen(glm::transpose(a) * a).value[0]);
    const glm::dvec3 w = glm::normalize(a * axis);
    const glm::dmat3 across = (glm::dmat3(1.0) - glm::outerProduct(w, w)) * a;
    const glm::dmat3 ata = glm::transpose(across) * across;
    // A basis (u, v) of the plane across the axis, and the 2x2 Gram matrix
    // of their images: its smaller eigenvalue in closed form.
    const glm::dvec3 helper =
        std::abs(axis.x) < 0.9 ? glm::dvec3(1.0, 0.0, 0.0) : glm::dvec3(0.0, 1.0, 0.0);
    const glm::dvec3 u = glm::normalize(glm::cross(axis, helper));
    const glm::dvec3 v = glm::cross(axis, u);
    const double p = glm::dot(u, ata * u), q = glm::dot(u, ata * v), r = glm::dot(v, ata * v);
    const double mean = 0.5 * (p + r), spread = std::hypot(0.5 * (p - r), q);
    return std::sqrt(std::max(mean - spread, 0.0));
}

/// The warps above a node: the linear part of the transforms (and of the
/// tapers not met directly), and the nearest taper when no transform lies
/// between it and the node (its scale then taken where each end is).
struct Frame {
    glm::dmat3 a{1.0};
    const cb_taper* taper = nullptr;
    /// The linear part with the taper, if any, at its smallest scale.
    glm::dmat3 folded() const
    {
        return taper ? a * std::min(double(taper->scale0), double(taper->scale1)) : a;
    }
    /// The taper's scale at point p of the node's frame (1 without one).
    double scaleAt(const glm::dvec3& p) const
    {
        if (!taper)
            return 1.0;
        const glm::dvec3 o(taper->o.x, taper->o.y, taper->o.z),
            ax(taper->a.x, taper->a.y, taper->a.z);
        return cb_taper_scale(taper->scale0, taper->scale1, taper->len, taper->start,
                              glm::dot(p - o, ax));
    }
};

struct Thickener {
    BlobTree& tree;
    double minRadius;
    Thickened result;
    std::vector<char> seen;

    /// Whether a radius is below the smallest (rounding aside: a leaf
    /// thickened to it is not thickened again as its sphere is met).
    bool thinner(double radius) const { return radius < minRadius * (1.0 - 1e-9); }
    /// What a world radius below the smallest becomes: the smallest, or
    /// kMaxThickening times itself where that is less.
    double grown(double radius) const
    {
        return std::max(radius, std::min(minRadius, kMaxThickening * radius));
    }

    /// A primitive's own surface radius over its radius; 0 where it has no
    /// surface of its own (a weight below the threshold: a bud scale scar's
    /// ring, which only shapes the bark it is summed with).  An R-type
    /// primitive's surface lies where W w(u) = T (kernels/cb_primitives.h),
    /// inside r for T <= W < 1, outside for W > 1; a convolution segment's
    /// radius is its surface's at weight 1, and is taken as it is.
    double surfaceScale(int i) const
    {
        const Primitive& p = tree.node(i).prim();
        const double T = tree.threshold();
        if (!(p.weight >= T))
            return 0.0;
        if (tree.node(i).type == NodeType::CONVOLUTION_SEGMENT || p.weight == 1.0)
            return 1.0;
        return 1.0 + p.sigma * (cb_wyvill_inverse(T / p.weight) / tree.xT() - 1.0);
    }

    /// Node i, under the warps `f`.
    void visit(int i, const Frame& f)
    {
        if (seen[size_t(i)])
            return;  // (a node under two parents: thickened under the first)
        seen[size_t(i)] = 1;
        const Node& n = tree.node(i);
        switch (kindOf(n.type)) {
            case NodeKind::Primitive:
                primitive(i, f);
                return;
            case NodeKind::Operator: {
                // What a difference takes away is no surface of material
                // (a thickened cutter would cut more), nor is a bounded
                // blend's bounding field (n.gbb().bound, not a child).
                const size_t kept = n.type == NodeType::DIFFERENCE ? 1 : n.children.size();
                for (size_t k = 0; k < kept && k < n.children.size(); ++k)
                    visit(n.children[k], f);
                return;
            }
            case NodeKind::Warp:
                break;
        }
        Frame below = f;
        if (n.type == NodeType::TRANSFORM) {
            // (a taper above is taken at its smallest scale from here down)
            const glm::dmat3 above = f.folded();
            glm::dmat4 m = tree.matrix(i);
            const int child = n.children.front();
            if (tree.node(child).type == NodeType::SPHERE && !seen[size_t(child)]) {
                // (its sphere is the transform's to thicken: met again as a
                // primitive, a leaf the cap left thinner than the smallest
                // would grow along its length and width too)
                m = squashedSphere(i, m, above, child);
                seen[size_t(child)] = 1;
                result.positive += surfaceScale(child) > 0.0;
            }
            below.a = above * glm::dmat3(m);
            below.taper = nullptr;
        } else if (n.type == NodeType::TAPER) {
            below.a = f.folded();
            below.taper = &std::get<cb_taper>(n.params);
        }  // (a bend or a twist moves a cross-section without squashing it)
        for (int c : n.children)
            visit(c, below);
    }

    /// A transform `m` of a sphere of its own, under `a`: its sphere is an
    /// ellipsoid in the world (a polygon leaf), thickened along its thin
    /// axes only, about its centre.
    glm::dmat4 squashedSphere(int i, const glm::dmat4& m, const glm::dmat3& a, int child)
    {
        const Primitive& sphere = tree.node(child).prim();
        const double r = sphere.r0 * surfaceScale(child);
        if (!(r > 0.0))
            return m;
        const glm::dmat3 lin(m);
        const glm::dmat3 world = a * lin;
        // world = U S V^T: the ellipsoid's semi-axes are r s_k along U e_k,
        // the images of V's columns; stretching by f_k along V e_k first
        // makes them r s_k f_k.
        const Eigen3 e = symmetricEigen(glm::transpose(world) * world);
        glm::dmat3 stretch(1.0);
        bool thin = false;
        for (int k = 0; k < 3; ++k) {
            const double semi = r * std::sqrt(e.value[k]);
            if (!thinner(semi))
                continue;
            thin = true;
            result.thinnest = std::min(result.thinnest, semi);
            const double f = semi > 0.0 ? grown(semi) / semi : 1.0;
            stretch += (f - 1.0) * glm::outerProduct(e.vector[k], e.vector[k]);
        }
        if (!thin)
            return m;
        // x' = M S (p - c) + M c + t: the centre c stays where it was.
        const glm::dmat3 grown = lin * stretch;
        glm::dmat4 out(grown);
        const glm::dvec3 t = glm::dvec3(m[3]) + lin * sphere.p0 - grown * sphere.p0;
        out[3] = glm::dvec4(t, 1.0);
        tree.setMatrix(i, out);
        ++result.parts;
        return out;
    }

    void primitive(int i, const Frame& f)
    {
        const Primitive& p = tree.node(i).prim();
        const double own = surfaceScale(i);
        if (!(own > 0.0))
            return;
        ++result.positive;
        const glm::dvec3 axis = tree.node(i).type == NodeType::SPHERE || p.p0 == p.p1
                                    ? glm::dvec3(0.0)
                                    : glm::normalize(p.p1 - p.p0);
        // World radius over radius at each end (a taper's scale where it is).
        const double across = leastStretch(f.a, axis) * own;
        const double s0 = across * f.scaleAt(p.p0), s1 = across * f.scaleAt(p.p1);
        if (!(s0 > 0.0 && s1 > 0.0))
            return;
        const double r0 = p.r0 * s0, r1 = p.r1 * s1;
        if (!thinner(std::min(r0, r1)))
            return;
        result.thinnest = std::min({result.thinnest, r0, r1});
        ++result.parts;
        tree.setRadii(i, std::max(p.r0, grown(r0) / s0), std::max(p.r1, grown(r1) / s1));
    }
};

}  // namespace

void checkMinRadius(double voxels)
{
    if (!(voxels >= 0.0 && voxels <= kMaxMinRadiusVoxels))
        throw InputError(fmt::format(
            "--min-radius must be from 0 (thin parts baked as they are) to {:g} voxels (got {:g}): "
            "to resolve thin parts, use a smaller --voxel-size",
            kMaxMinRadiusVoxels, voxels));
}

Thickened thickenThinParts(BlobTree& tree, double minRadius)
{
    Thickener t{tree, minRadius, {}, std::vector<char>(tree.nodes().size(), 0)};
    if (minRadius > 0.0 && tree.root() >= 0)
        t.visit(tree.root(), Frame{});
    return t.result;
}

}  // namespace cambium
