// cambium — CPU reference evaluator.
#include "blobtree/evaluator.h"

#include "cb_operators.h"
#include "cb_primitives.h"
#include "cb_warps.h"

#include <cmath>

namespace cambium {

namespace {

cb_vec3 toCb(const glm::dvec3& v)
{
    return cb_v3(v.x, v.y, v.z);
}
glm::dvec3 toGlm(const cb_vec3& v)
{
    return {v.x, v.y, v.z};
}

FieldSample primitiveSample(const Node& n, const glm::dvec3& p, double xT, double detailLimit)
{
    const Primitive& pr = n.prim();
    cb_vec3 g = cb_v3(0, 0, 0);
    double f = 0.0;
    switch (n.type) {
        case NodeType::SPHERE:
            f = cb_sphere_field(toCb(p), toCb(pr.p0), pr.r0, pr.sigma, xT, &g);
            break;
        case NodeType::SEGMENT:
        case NodeType::CONE: {
            const glm::dvec3 axis = pr.p1 - pr.p0;
            const double len = glm::length(axis);
            const glm::dvec3 u = len > 0.0 ? axis / len : glm::dvec3(0.0);
            if (pr.bark.active()) {
                const BarkParams& b = pr.bark;
                f = cb_bark_cone_field(toCb(p), toCb(pr.p0), toCb(u), len, pr.r0, pr.r1, pr.sigma,
                                       xT, toCb(b.reference), b.s0, b.depth0, b.depth1, b.around,
                                       b.along, b.phase, detailLimit, &g);
            } else {
                f = cb_cone_field(toCb(p), toCb(pr.p0), toCb(u), len, pr.r0, pr.r1, pr.sigma, xT,
                                  &g);
            }
            break;
        }
        case NodeType::CONVOLUTION_SEGMENT: {
            const glm::dvec3 axis = pr.p1 - pr.p0;
            const double len = glm::length(axis);
            f = cb_convolution_field(toCb(p), toCb(pr.p0), toCb(axis / len), len, pr.q0, pr.q1,
                                     pr.kernelWidth, pr.support, &g);
            break;
        }
        default:
            break;
    }
    FieldSample s;
    s.value = pr.weight * f;
    s.gradient = pr.weight * toGlm(g);
    s.color = s.value != 0.0 ? n.shade : glm::dvec3(0.0);  // colour exists where the field does
    return s;
}

/// Colour as a weighted mean; black where every weight vanishes (outside
/// all supports): a colour that does not depend on children whose field is
/// zero, so a program specialised to a region keeps the same colours.
glm::dvec3 weightedColor(const std::vector<FieldSample>& kids, const std::vector<double>& w)
{
    glm::dvec3 c(0.0);
    double sum = 0.0;
    for (size_t i = 0; i < kids.size(); ++i) {
        c += w[i] * kids[i].color;
        sum += w[i];
    }
    return sum > 0.0 ? c / sum : glm::dvec3(0.0);
}

}  // namespace

FieldSample combine(const Combiner& c, const std::vector<FieldSample>& kids, double T)
{
    FieldSample out;
    std::vector<double> w(kids.size(), 0.0);
    double shade = 1.0;  // the PCM ridge darkens colours
    switch (c.type) {
        case NodeType::BLEND:
            for (size_t i = 0; i < kids.size(); ++i) {
                out.value += kids[i].value;
                out.gradient += kids[i].gradient;
                w[i] = std::abs(kids[i].value);
            }
            break;
        case NodeType::RICCI: {
            // Relative to the largest child m: F = m (sum (f_i / m)^n)^(1/n),
            // whose terms stay within [0, 1] where f^n would overflow.
            double m = 0.0, sum = 0.0;
            for (const auto& k : kids)
                m = std::max(m, k.value);
            if (m > 0.0)
                for (const auto& k : kids)
                    sum += cb_ricci_term(k.value / m, c.n);
            out.value = m * cb_ricci_finish(sum, c.n);
            for (size_t i = 0; i < kids.size(); ++i) {
                out.gradient += cb_ricci_partial(kids[i].value, out.value, c.n) * kids[i].gradient;
                w[i] = m > 0.0 ? cb_ricci_term(kids[i].value / m, c.n) : 0.0;
            }
            break;
        }
        case NodeType::UNION:
        case NodeType::INTERSECTION:
        case NodeType::DIFFERENCE: {
            size_t pick = 0;
            double best = kids[0].value;
            glm::dvec3 grad = kids[0].gradient;
            for (size_t i = 1; i < kids.size(); ++i) {
                double v = kids[i].value;
                glm::dvec3 g = kids[i].gradient;
                if (c.type == NodeType::DIFFERENCE) {
                    v = cb_csg_complement(v, T);
                    g = -g;
                }
                const bool better = c.type == NodeType::UNION ? v > best : v < best;
                if (better) {
                    best = v;
                    grad = g;
                    pick = i;
                }
            }
            out.value = best;
            out.gradient = grad;
            // The difference keeps the colour of the solid being cut.
            w[c.type == NodeType::DIFFERENCE ? 0 : pick] = 1.0;
            break;
        }
        case NodeType::PCM: {
            // Paper 003 eq. 3: start from the strongest child, then let every
            // other child deform it.
            size_t strongest = 0;
            for (size_t i = 1; i < kids.size(); ++i)
                if (kids[i].value > kids[strongest].value)
                    strongest = i;
            out.value = kids[strongest].value;
            out.gradient = kids[strongest].gradient;
            for (size_t i = 0; i < kids.size(); ++i) {
                w[i] = std::abs(kids[i].value);
                if (i == strongest)
                    continue;
                double dD = 0.0;
                out.value += cb_pcm_deformation(kids[i].value, T, c.width, c.attenuation, &dD);
                out.gradient += dD * kids[i].gradient;
            }
            shade = cb_pcm_ridge_shade(c.darken, out.value - kids[strongest].value, c.width);
            break;
        }
        case NodeType::BETTER_BLEND:
            for (size_t i = 0; i < kids.size(); ++i) {
                double dg = 0.0;
                const double g = cb_better_blend_g(kids[i].value, T, c.k, &dg);
                out.value += g;
                out.gradient += dg * kids[i].gradient;
                w[i] = std::abs(g);
            }
            break;
        default:
            break;
    }
    // A node's colour exists where its field does (black where it is zero).
    out.color = out.value != 0.0 ? shade * weightedColor(kids, w) : glm::dvec3(0.0);
    return out;
}

FieldSample ReferenceEvaluator::sample(int index, const glm::dvec3& p) const
{
    const Node& n = tree_.node(index);
    const double T = tree_.threshold();
    switch (kindOf(n.type)) {
        case NodeKind::Primitive:
            return primitiveSample(n, p, tree_.xT(), tree_.detailLimit());
        case NodeKind::Operator: {
            std::vector<FieldSample> kids;
            kids.reserve(n.children.size());
            for (int c : n.children)
                kids.push_back(sample(c, p));
            if (n.type != NodeType::GBB)
                return combine(n.combiner(), kids, T);
            const GbbParams& g = n.gbb();
            const FieldSample b1 = combine(g.b1, kids, T);
            const FieldSample b2 = combine(g.b2, kids, T);
            const FieldSample fb = sample(g.bound, p);
            double dFb = 0.0;
            FieldSample out;
            out.value = cb_gbb(fb.value, b1.value, b2.value, &dFb);
            const double b = cb_clamp01(fb.value);
            out.gradient = b * b1.gradient + (1.0 - b) * b2.gradient + dFb * fb.gradient;
            out.color = out.value != 0.0 ? b * b1.color + (1.0 - b) * b2.color : glm::dvec3(0.0);
            return out;
        }
        case NodeKind::Warp: {
            double J[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
            cb_vec3 q = toCb(p);
            switch (n.type) {
                case NodeType::TRANSFORM:
                    q = cb_affine_apply(std::get<TransformParams>(n.params).inverse, q, J);
                    break;
                case NodeType::BEND:
                    q = cb_bend_apply(std::get<cb_bend>(n.params), q, J);
                    break;
                case NodeType::TWIST:
                    q = cb_twist_apply(std::get<cb_twist>(n.params), q, J);
                    break;
                case NodeType::TAPER:
                    q = cb_taper_apply(std::get<cb_taper>(n.params), q, J);
                    break;
                default:
                    break;
            }
            FieldSample s = sample(n.children[0], toGlm(q));
            s.gradient = toGlm(cb_mat3_tmul(J, toCb(s.gradient)));
            return s;
        }
    }
    return {};
}

}  // namespace cambium
