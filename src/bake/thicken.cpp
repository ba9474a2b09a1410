// cambium — thin parts thickened to a bake's smallest radius.
#include "bake/thicken.h"

#include "bake/options.h"
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
        e.vector[k] = glm::normalize(
            glm::dvec3(q(0, order[k]), q(1, order[k]), q(2, order[k])));
    }
    return e;
}

/// The least a linear map `a` stretches a direction across `axis` (a unit
/// vector; zero: any direction): the smallest singular value of `a` on the
/// plane across the axis, or on all of space.
double leastStretch(const glm::dmat3& a, const glm::dvec3& axis)
{
    const glm::dmat3 ata = glm::transpose(a) * a;
    if (axis == glm::dvec3(0.0))
        return std::sqrt(symmetricEigen(ata).value[0]);
    // A basis (u, v) of the plane across the axis, and the 2x2 Gram matrix
    // of a u and a v: its smaller eigenvalue in closed form.
    const glm::dvec3 helper =
        std::abs(axis.x) < 0.9 ? glm::dvec3(1.0, 0.0, 0.0) : glm::dvec3(0.0, 1.0, 0.0);
    const glm::dvec3 u = glm::normalize(glm::cross(axis, helper));
    const glm::dvec3 v = glm::cross(axis, u);
    const double p = glm::dot(u, ata * u), q = glm::dot(u, ata * v), r = glm::dot(v, ata * v);
    const double mean = 0.5 * (p + r), spread = std::hypot(0.5 * (p - r), q);
    return std::sqrt(std::max(mean - spread, 0.0));
}

struct Thickener {
    BlobTree& tree;
    double minRadius;
    Thickened result;
    std::vector<char> seen;

    /// Whether a radius is below the smallest (rounding aside: a leaf
    /// thickened to it is not thickened again as its sphere is met).
    bool thinner(double radius) const { return radius < minRadius * (1.0 - 1e-9); }

    /// A positive primitive's surface radius over its radius.
    double surfaceScale(const Primitive& p) const
    {
        return surfaceRadiusScale(p.weight, p.sigma, tree.threshold(), tree.xT());
    }

    /// Node i, under transforms and tapers whose linear part is `a`.
    void visit(int i, const glm::dmat3& a)
    {
        if (seen[size_t(i)])
            return;  // (a node under two parents: thickened under the first)
        seen[size_t(i)] = 1;
        const Node& n = tree.node(i);
        switch (kindOf(n.type)) {
            case NodeKind::Primitive:
                primitive(i, a);
                return;
            case NodeKind::Operator: {
                // What a difference takes away is no surface of material
                // (a thickened cutter would cut more), nor is a bounded
                // blend's bounding field (n.gbb().bound, not a child).
                const size_t kept = n.type == NodeType::DIFFERENCE ? 1 : n.children.size();
                for (size_t k = 0; k < kept && k < n.children.size(); ++k)
                    visit(n.children[k], a);
                return;
            }
            case NodeKind::Warp:
                break;
        }
        glm::dmat3 below = a;
        if (n.type == NodeType::TRANSFORM) {
            glm::dmat4 m = tree.matrix(i);
            const int child = n.children.front();
            if (tree.node(child).type == NodeType::SPHERE && !seen[size_t(child)])
                m = squashedSphere(i, m, a, tree.node(child).prim());
            below = a * glm::dmat3(m);
        } else if (n.type == NodeType::TAPER) {
            const cb_taper& t = std::get<cb_taper>(n.params);
            below = a * std::min(double(t.scale0), double(t.scale1));
        }  // (a bend or a twist moves a cross-section without squashing it)
        for (int c : n.children)
            visit(c, below);
    }

    /// A transform `m` of a sphere of its own, under `a`: its sphere is an
    /// ellipsoid in the world (a polygon leaf), thickened along its thin
    /// axes only, about its centre.
    glm::dmat4 squashedSphere(int i, const glm::dmat4& m, const glm::dmat3& a,
                              const Primitive& sphere)
    {
        if (!(sphere.weight > 0.0))
            return m;
        const double r = sphere.r0 * surfaceScale(sphere);
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
            const double f = semi > 0.0 ? minRadius / semi : 1.0;
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

    void primitive(int i, const glm::dmat3& a)
    {
        const Primitive& p = tree.node(i).prim();
        if (!(p.weight > 0.0))
            return;
        ++result.positive;
        const glm::dvec3 axis = tree.node(i).type == NodeType::SPHERE || p.p0 == p.p1
                                    ? glm::dvec3(0.0)
                                    : glm::normalize(p.p1 - p.p0);
        const double across = leastStretch(a, axis) * surfaceScale(p);
        const double r0 = p.r0 * across, r1 = p.r1 * across;
        if (!thinner(std::min(r0, r1)) || !(across > 0.0))
            return;
        result.thinnest = std::min({result.thinnest, r0, r1});
        ++result.parts;
        tree.setRadii(i, std::max(p.r0, minRadius / across), std::max(p.r1, minRadius / across));
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
        t.visit(tree.root(), glm::dmat3(1.0));
    return t.result;
}

}  // namespace cambium
