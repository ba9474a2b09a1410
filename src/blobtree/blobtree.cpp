// cambium — BlobTree builders and validation.
#include "blobtree/blobtree.h"

#include "core/error.h"
#include "core/math.h"

#include "cb_primitives.h"

#include <fmt/format.h>
#include <glm/gtc/matrix_inverse.hpp>

#include <cmath>

namespace cambium {

namespace {

struct TypeInfo {
    NodeType type;
    const char* name;
    NodeKind kind;
};

const std::vector<TypeInfo>& typeTable()
{
    static const std::vector<TypeInfo> table = {
#define CB_X(ident, number, name, kind) {NodeType::ident, name, NodeKind::k##kind},
#define kPRIMITIVE Primitive
#define kOPERATOR Operator
#define kWARP Warp
        CB_NODE_TYPES(CB_X)
#undef CB_X
#undef kPRIMITIVE
#undef kOPERATOR
#undef kWARP
    };
    return table;
}

bool finite(const glm::dvec3& v)
{
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

void requireFinite(const glm::dvec3& v, const char* field)
{
    if (!finite(v))
        throw ParameterError(field, "must be a finite point");
}

void requireFinite(double v, const char* field)
{
    if (!std::isfinite(v))
        throw ParameterError(field, "must be a finite number");
}

void requirePositive(double v, const char* field)
{
    requireFinite(v, field);
    if (!(v > 0.0))
        throw ParameterError(field, fmt::format("must be greater than 0 (got {})", v));
}

cb_vec3 toCb(const glm::dvec3& v)
{
    return cb_v3(v.x, v.y, v.z);
}

/// A warp's axis: finite, nonzero, returned normalized.
cb_vec3 unitAxis(const glm::dvec3& axis)
{
    requireFinite(axis, "axis");
    const glm::dvec3 unit = unitDirection(axis);
    if (unit == glm::dvec3(0.0))
        throw ParameterError("axis", "must not be zero");
    return toCb(unit);
}

/// The largest weight a primitive may have: the kernels sample in float, and
/// a weight of 1e39 was infinite there (an inside-out surface, exit 0); far
/// below that, a field a million times its threshold has no surface a
/// voxel could resolve.
constexpr double kMaxWeight = 1e6;
/// A twist's largest rate (radians a unit: a million degrees) and a taper's
/// least scale (its largest the inverse): the warps run in the kernels'
/// float.
constexpr double kMaxTwistRate = 1e6 * kDegree;
/// The sharpest convolution kernel, as s max(r0, r1).
constexpr double kMaxKernelWidthTimesRadius = 100.0;
constexpr double kLeastTaperScale = 1e-3;

void requireWeight(double w)
{
    requireFinite(w, "weight");
    if (w == 0.0)
        throw ParameterError("weight", "must not be 0 (a primitive of weight 0 has no field)");
    if (std::abs(w) > kMaxWeight)
        throw ParameterError("weight", fmt::format("must be within -{:g} and {:g} (got {:g})",
                                                   kMaxWeight, kMaxWeight, w));
}

}  // namespace

const char* typeName(NodeType t)
{
    for (const auto& e : typeTable())
        if (e.type == t)
            return e.name;
    return "?";
}

NodeKind kindOf(NodeType t)
{
    for (const auto& e : typeTable())
        if (e.type == t)
            return e.kind;
    return NodeKind::Operator;
}

std::optional<NodeType> typeFromName(std::string_view name)
{
    for (const auto& e : typeTable())
        if (name == e.name)
            return e.type;
    return std::nullopt;
}

const std::vector<NodeType>& allNodeTypes()
{
    static const std::vector<NodeType> all = [] {
        std::vector<NodeType> v;
        for (const auto& e : typeTable())
            v.push_back(e.type);
        return v;
    }();
    return all;
}

BlobTree::BlobTree(double threshold)
{
    if (!std::isfinite(threshold) || !(threshold > 0.0 && threshold < 1.0))
        throw ParameterError("threshold",
                             fmt::format("must be between 0 and 1, exclusive (got {})", threshold));
    // Nearer 1 a primitive's surface sits deep inside its support (17 times
    // its radius out at 0.99, 1563 at 0.999999), and the bounds, the
    // automatic voxel size and the band's search all start from supports: a
    // sphere at 0.999999 baked as 140 voxels and rendered empty, exit 0.
    if (threshold > kMaxThreshold)
        throw ParameterError(
            "threshold", fmt::format("must be at most {} (got {}): nearer 1 a primitive's surface "
                                     "lies deep inside its support, 17 times its radius out at "
                                     "0.99, where bounds and voxel sizes come from",
                                     kMaxThreshold, threshold));
    // Nearer 0 the surface lies where the field fades out at the edge of the
    // support, flat there (a derivative of 6 T^(2/3)): at 1e-30 the float
    // kernels saw no surface at all and called a crescent thinner than a
    // voxel.
    if (threshold < kMinThreshold)
        throw ParameterError(
            "threshold", fmt::format("must be at least {} (got {}): nearer 0 a primitive's surface "
                                     "lies where its field fades out, too flat to place",
                                     kMinThreshold, threshold));
    T_ = threshold;
    xT_ = cb_wyvill_inverse(threshold);
}

int BlobTree::add(NodeType type, NodeParams params, std::vector<int> children)
{
    Node n;
    n.type = type;
    n.children = std::move(children);
    n.params = std::move(params);
    nodes_.push_back(std::move(n));
    return int(nodes_.size()) - 1;
}

void BlobTree::checkChild(int child, const char* field) const
{
    if (child < 0 || size_t(child) >= nodes_.size())
        throw ParameterError(field, fmt::format("refers to node {}, which does not exist", child));
}

int BlobTree::sphere(const glm::dvec3& center, double radius, const PrimitiveOptions& o)
{
    requireFinite(center, "center");
    requirePositive(radius, "radius");
    return addSkeletal(NodeType::SPHERE, center, center, radius, radius, o);
}

int BlobTree::segment(const glm::dvec3& p0, const glm::dvec3& p1, double radius,
                      const PrimitiveOptions& o)
{
    requirePositive(radius, "radius");
    return addSkeletal(NodeType::SEGMENT, p0, p1, radius, radius, o);
}

int BlobTree::cone(const glm::dvec3& p0, const glm::dvec3& p1, double r0, double r1,
                   const PrimitiveOptions& o)
{
    return addSkeletal(NodeType::CONE, p0, p1, r0, r1, o);
}

void BlobTree::setDetailLimit(double wavelength)
{
    requireFinite(wavelength, "detail limit");
    if (wavelength < 0.0)
        throw ParameterError("detail limit",
                             fmt::format("must not be negative (got {})", wavelength));
    detailLimit_ = wavelength;
}

void BlobTree::setBark(int node, const BarkParams& b)
{
    Node& n = nodes_.at(size_t(node));
    if (n.type != NodeType::CONE)
        throw ParameterError("bark", "is for cones");
    Primitive& p = std::get<Primitive>(n.params);
    for (const auto& [v, name] : {std::pair{b.depth0, "bark.depth0"}, {b.depth1, "bark.depth1"}}) {
        requireFinite(v, name);
        if (v < 0.0)
            throw ParameterError(name, fmt::format("must not be negative (got {})", v));
    }
    // The deepest furrow (P <= 7/4) leaves at least half the radius.
    if (1.75 * b.depth0 > 0.5 * p.r0 || 1.75 * b.depth1 > 0.5 * p.r1)
        throw ParameterError("bark.depth",
                             fmt::format("({}, {}) reaches past half the cone's radii ({}, {})",
                                         b.depth0, b.depth1, p.r0, p.r1));
    requireFinite(b.reference, "bark.reference");
    const glm::dvec3 axis = glm::normalize(p.p1 - p.p0);
    if (std::fabs(glm::length(b.reference) - 1.0) > 1e-9 ||
        std::fabs(glm::dot(b.reference, axis)) > 1e-6)
        throw ParameterError("bark.reference", "must be a unit vector across the axis");
    requireFinite(b.s0, "bark.s0");
    requireFinite(b.phase, "bark.phase");
    if (!(b.around >= 1.0 && b.around <= 4096.0 && b.around == std::floor(b.around)))
        throw ParameterError(
            "bark.around", fmt::format("must be a whole number from 1 to 4096 (got {})", b.around));
    requireFinite(b.along, "bark.along");
    if (b.along < 0.0)
        throw ParameterError("bark.along", fmt::format("must not be negative (got {})", b.along));
    p.bark = b;
}

Primitive BlobTree::primitive(const glm::dvec3& p0, const glm::dvec3& p1, double r0, double r1,
                              double weight)
{
    requireFinite(p0, "p0");
    requireFinite(p1, "p1");
    requirePositive(r0, "r0");
    requirePositive(r1, "r1");
    requireWeight(weight);
    Primitive p;
    p.p0 = p0;
    p.p1 = p1;
    p.r0 = r0;
    p.r1 = r1;
    p.weight = weight;
    return p;
}

int BlobTree::addSkeletal(NodeType type, const glm::dvec3& p0, const glm::dvec3& p1, double r0,
                          double r1, const PrimitiveOptions& o)
{
    Primitive p = primitive(p0, p1, r0, r1, o.weight);
    if (o.support) {
        requirePositive(*o.support, "support");
        p.sigma = *o.support * xT_ / r0;
    }
    return add(type, p);
}

int BlobTree::convolutionSegment(const glm::dvec3& p0, const glm::dvec3& p1, double r0, double r1,
                                 const ConvolutionOptions& o)
{
    Primitive p = primitive(p0, p1, r0, r1, o.weight);
    if (!(glm::length(p1 - p0) > 0.0))
        throw ParameterError("p1", "is equal to p0: a convolution segment needs a length");
    const double rmax = std::max(r0, r1);
    p.kernelWidth = o.kernelWidth.value_or(1.0 / rmax);
    requirePositive(p.kernelWidth, "kernel_width");
    // (s r of 1e3 and more drew a band of other voxels in the kernels' float
    // than in double, 1e8 a terraced surface; at 100 the kernel is already
    // a hundredth of the radius: a cylinder)
    if (p.kernelWidth * rmax > kMaxKernelWidthTimesRadius)
        throw ParameterError(
            "kernel_width",
            fmt::format(
                "must be at most {:g} / max(r0, r1) = {:g} (got {:g}): beyond, the kernel is "
                "narrower than a hundredth of the radius, draws the same cylinder, and "
                "its field leaves the kernels' single precision",
                kMaxKernelWidthTimesRadius, kMaxKernelWidthTimesRadius / rmax, p.kernelWidth));
    p.support = o.support.value_or(3.0 * rmax);
    requirePositive(p.support, "support");
    if (p.support < 2.0 * rmax)
        throw ParameterError("support",
                             fmt::format("must be at least twice the largest radius, {} (got {})",
                                         2.0 * rmax, p.support));
    p.q0 = cb_convolution_density(r0, p.kernelWidth, T_);
    p.q1 = cb_convolution_density(r1, p.kernelWidth, T_);
    return add(NodeType::CONVOLUTION_SEGMENT, p);
}

void BlobTree::validate(const Combiner& c) const
{
    switch (c.type) {
        case NodeType::BLEND:
        case NodeType::UNION:
        case NodeType::INTERSECTION:
        case NodeType::DIFFERENCE:
            return;
        case NodeType::RICCI:
            requireFinite(c.n, "n");
            if (!(c.n >= 1.0))
                throw ParameterError("n", fmt::format("must be at least 1 (got {})", c.n));
            // (the evaluators sum (f / max f)^n, which stays in range for any
            // n; beyond 64 two equal children blend within 1 % of one)
            if (c.n > 64.0)
                throw ParameterError(
                    "n", fmt::format("must be at most 64 (got {}): a larger n is a union (use "
                                     "\"union\")",
                                     c.n));
            return;
        case NodeType::PCM:
            requirePositive(c.width, "width");
            if (c.width > T_)
                throw ParameterError("width",
                                     fmt::format("must not exceed the threshold {} (got {}): the "
                                                 "propagation region must end where fields do",
                                                 T_, c.width));
            requireFinite(c.attenuation, "attenuation");
            if (!(c.attenuation > 1.0))
                throw ParameterError(
                    "attenuation",
                    fmt::format("must be greater than 1 for a C1 bulge (got {})", c.attenuation));
            requireFinite(c.darken, "darken");
            if (!(c.darken >= 0.0 && c.darken <= 1.0))
                throw ParameterError("darken", fmt::format("must be in [0, 1] (got {})", c.darken));
            return;
        case NodeType::BETTER_BLEND:
            requireFinite(c.k, "k");
            if (!(c.k >= 0.0 && c.k < T_))
                throw ParameterError("k", fmt::format("must be in [0, {}) (got {})", T_, c.k));
            return;
        default:
            throw ParameterError("type",
                                 fmt::format("'{}' is not a blending operator", typeName(c.type)));
    }
}

int BlobTree::op(const Combiner& c, std::vector<int> children)
{
    validate(c);
    if (children.empty())
        throw ParameterError("children",
                             fmt::format("a '{}' needs at least one child", typeName(c.type)));
    for (int ch : children)
        checkChild(ch, "children");
    return add(c.type, c, std::move(children));
}

int BlobTree::gbb(int bound, std::vector<int> children, const Combiner& b1, const Combiner& b2)
{
    checkChild(bound, "bound");
    try {
        validate(b1);
    } catch (const ParameterError& e) {
        throw ParameterError("b1." + e.field(), e.what());
    }
    try {
        validate(b2);
    } catch (const ParameterError& e) {
        throw ParameterError("b2." + e.field(), e.what());
    }
    if (children.empty())
        throw ParameterError("children", "a 'gbb' needs at least one child");
    for (int ch : children)
        checkChild(ch, "children");
    return add(NodeType::GBB, GbbParams{b1, b2, bound}, std::move(children));
}

namespace {

/// A transform's parameters: InputError (ParameterError) unless `m` is
/// finite, within reach, affine and invertible.
TransformParams transformParams(const glm::dmat4& m)
{
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 4; ++r)
            if (!std::isfinite(m[c][r]))
                throw ParameterError("matrix", "must have finite entries");
    for (int c = 0; c < 4; ++c)
        for (int r = 0; r < 3; ++r)
            if (std::abs(m[c][r]) > kFarthestCoordinate)
                throw ParameterError("matrix",
                                     fmt::format("has an entry {:g}, beyond the {:g} cambium bakes",
                                                 m[c][r], kFarthestCoordinate));
    if (m[0][3] != 0.0 || m[1][3] != 0.0 || m[2][3] != 0.0 || m[3][3] != 1.0)
        throw ParameterError("matrix", "must be affine (last row 0 0 0 1)");
    const glm::dmat3 a(m);
    const double det = glm::determinant(a);
    const double scale = glm::length(a[0]) * glm::length(a[1]) * glm::length(a[2]);
    if (!(std::abs(det) > 1e-12 * scale) || scale == 0.0)
        throw ParameterError("matrix", "is singular: a transform must be invertible");
    const glm::dmat4 inv = glm::inverse(m);
    TransformParams t;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) {
            t.forward[4 * r + c] = m[c][r];  // glm is column-major: m[col][row]
            t.inverse.m[4 * r + c] = inv[c][r];
        }
    return t;
}

}  // namespace

int BlobTree::transform(const glm::dmat4& m, int child)
{
    checkChild(child, "children");
    return add(NodeType::TRANSFORM, transformParams(m), {child});
}

glm::dmat4 BlobTree::matrix(int node) const
{
    const auto& t = std::get<TransformParams>(nodes_.at(size_t(node)).params);
    glm::dmat4 m(1.0);
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c)
            m[c][r] = t.forward[4 * r + c];
    return m;
}

void BlobTree::setMatrix(int node, const glm::dmat4& m)
{
    Node& n = nodes_.at(size_t(node));
    std::get<TransformParams>(n.params);  // (a transform's, or bad_variant_access)
    n.params = transformParams(m);
}

void BlobTree::setRadii(int node, double r0, double r1)
{
    Primitive& p = std::get<Primitive>(nodes_.at(size_t(node)).params);
    requirePositive(r0, "r0");
    requirePositive(r1, "r1");
    r0 = std::max(r0, p.r0);
    r1 = std::max(r1, p.r1);
    if (nodes_[size_t(node)].type == NodeType::CONVOLUTION_SEGMENT) {
        const double grown = std::max(r0, r1) / std::max(p.r0, p.r1);
        p.kernelWidth /= grown;
        p.support *= grown;
        p.q0 = cb_convolution_density(r0, p.kernelWidth, T_);
        p.q1 = cb_convolution_density(r1, p.kernelWidth, T_);
    }
    p.r0 = r0;
    p.r1 = r1;
}

int BlobTree::bend(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& dir, double angle,
                   int child)
{
    checkChild(child, "children");
    requireFinite(p0, "p0");
    requireFinite(p1, "p1");
    requireFinite(dir, "direction");
    requireFinite(angle, "angle");
    const glm::dvec3 axis = p1 - p0;
    const double len = glm::length(axis);
    if (!(len > 0.0))
        throw ParameterError("p1", "is equal to p0: a bend needs an internode to bend");
    const glm::dvec3 u = axis / len;
    const glm::dvec3 d = unitDirection(dir);
    if (!(glm::length(d - glm::dot(d, u) * u) > 1e-9))
        throw ParameterError("direction",
                             "must not be zero or parallel to p1 - p0: it picks the bend plane");
    if (!(std::abs(angle) < M_PI))
        throw ParameterError("angle", fmt::format("must be less than 180 degrees in magnitude (got "
                                                  "{} degrees)",
                                                  angle * 180.0 / M_PI));
    return add(NodeType::BEND, cb_bend_setup(toCb(p0), toCb(p1), toCb(d), angle), {child});
}

int BlobTree::twist(const glm::dvec3& origin, const glm::dvec3& axis, double rate, int child)
{
    checkChild(child, "children");
    requireFinite(origin, "origin");
    requireFinite(rate, "rate");
    // (a rate of 1e20 degrees a unit was infinite in the kernels' float:
    // the warped cone vanished, exit 0)
    if (!(std::abs(rate) <= kMaxTwistRate))
        throw ParameterError("rate", fmt::format("must be at most {:g} degrees a unit in magnitude "
                                                 "(got {:g})",
                                                 kMaxTwistRate / kDegree, rate / kDegree));
    return add(NodeType::TWIST, cb_twist_setup(toCb(origin), unitAxis(axis), rate), {child});
}

int BlobTree::taper(const glm::dvec3& origin, const glm::dvec3& axis, double length, double scale0,
                    double scale1, int child)
{
    checkChild(child, "children");
    requireFinite(origin, "origin");
    requirePositive(length, "length");
    requirePositive(scale0, "scale0");
    requirePositive(scale1, "scale1");
    // (a taper to 1e-8 divided by a scale that rounds to 0 in the kernels'
    // float: an open, inside-out level set, exit 0)
    for (const auto& [scale, name] : {std::pair{scale0, "scale0"}, std::pair{scale1, "scale1"}})
        if (!(scale >= kLeastTaperScale && scale <= 1.0 / kLeastTaperScale))
            throw ParameterError(name,
                                 fmt::format("must be from {:g} to {:g} (got {:g}): a taper "
                                             "divides the points it warps by its scale",
                                             kLeastTaperScale, 1.0 / kLeastTaperScale, scale));
    return add(NodeType::TAPER,
               cb_taper_setup(toCb(origin), unitAxis(axis), length, scale0, scale1), {child});
}

void BlobTree::setColor(int node, const glm::dvec3& rgb)
{
    checkChild(node, "node");
    if (!finite(rgb) || glm::any(glm::lessThan(rgb, glm::dvec3(0.0))) ||
        glm::any(glm::greaterThan(rgb, glm::dvec3(1.0))))
        throw ParameterError("color", "must be three numbers in [0, 1]");
    nodes_[size_t(node)].color = rgb;
}

void BlobTree::setRoot(int node)
{
    checkChild(node, "root");
    root_ = node;
}

void BlobTree::finalize()
{
    if (root_ < 0)
        throw InputError("the BlobTree has no root");
    // Children always precede their parents, so a reverse sweep visits every
    // parent before its children: inheritance in one pass, no recursion.
    std::vector<char> reached(nodes_.size(), 0);
    const glm::dvec3 fallback(0.8);
    reached[size_t(root_)] = 1;
    nodes_[size_t(root_)].shade = nodes_[size_t(root_)].color.value_or(fallback);
    for (size_t i = nodes_.size(); i-- > 0;) {
        if (!reached[i])
            continue;
        Node& n = nodes_[i];
        auto visit = [&](int c) {
            Node& ch = nodes_[size_t(c)];
            if (!reached[size_t(c)]) {
                reached[size_t(c)] = 1;
                ch.shade = ch.color.value_or(n.shade);
            }
        };
        for (int c : n.children)
            visit(c);
        if (n.type == NodeType::GBB)
            visit(n.gbb().bound);
    }
}

}  // namespace cambium
