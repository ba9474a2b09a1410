// cambium — FieldProgram compiler, interval bounds and region specialisation.
#include "field/program.h"

#include "blobtree/bounds.h"
#include "core/error.h"
#include "core/math.h"

#include "cb_program.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstring>
#include <deque>
#include <array>
#include <cmath>
#include <iterator>
#include <limits>
#include <type_traits>

namespace cambium {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

class Compiler {
public:
    Compiler(const BlobTree& tree, const std::vector<NodeBounds>& bounds,
             const std::vector<double>& areaScales, std::vector<double>& params,
             std::vector<Instr>& code, std::vector<Box>& boxes, std::vector<double>& boxAreaScales)
        : tree_(tree),
          bounds_(bounds),
          areaScales_(areaScales),
          P_(params),
          code_(code),
          boxes_(boxes),
          boxAreaScales_(boxAreaScales)
    {
    }

    size_t primitives = 0, bark = 0;
    std::vector<glm::dvec3> shades;  ///< the distinct primitive colours, up to two

    void emit(int index)
    {
        const Node& n = tree_.node(index);
        current_ = index;
        switch (kindOf(n.type)) {
            case NodeKind::Primitive:
                emitPrimitive(n);
                break;
            case NodeKind::Operator:
                emitOperator(index, n);
                break;
            case NodeKind::Warp:
                emitWarp(index, n);
                break;
        }
    }

private:
    /// Appends a parameter block of `size` values, to be written field by
    /// field through the layout names of kernels/cb_program.h, and returns its
    /// offset.  It starts as NaN so that a field left unwritten poisons every
    /// sample instead of quietly reading as 0.
    int newBlock(int size)
    {
        const int at = int(P_.size());
        P_.resize(P_.size() + size_t(size), std::numeric_limits<double>::quiet_NaN());
        return at;
    }
    /// The block at offset `at`; valid until the next newBlock.
    double* blockAt(int at) { return P_.data() + at; }

    template <class Vec3>  // glm::dvec3 or cb_vec3
    static void put3(double* field, const Vec3& v)
    {
        field[0] = v.x;
        field[1] = v.y;
        field[2] = v.z;
    }

    void emitPrimitive(const Node& n)
    {
        const Primitive& p = n.prim();
        const glm::dvec3 axis = p.p1 - p.p0;
        const double len = glm::length(axis);
        const glm::dvec3 u = len > 0.0 ? axis / len : glm::dvec3(0.0);
        int at;
        switch (n.type) {
            case NodeType::SPHERE: {
                at = newBlock(CB_SPHERE_SIZE);
                double* q = blockAt(at);
                put3(q + CB_SPHERE_CENTER, p.p0);
                q[CB_SPHERE_RADIUS] = p.r0;
                q[CB_SPHERE_SIGMA] = p.sigma;
                q[CB_SPHERE_WEIGHT] = p.weight;
                put3(q + CB_SPHERE_RGB, n.shade);
                break;
            }
            case NodeType::SEGMENT:
            case NodeType::CONE: {
                at = newBlock(p.bark.active() ? CB_BARK_SIZE : CB_CONE_SIZE);
                double* q = blockAt(at);
                if (p.bark.active()) {
                    put3(q + CB_BARK_REF, p.bark.reference);
                    q[CB_BARK_S0] = p.bark.s0;
                    q[CB_BARK_A0] = p.bark.depth0;
                    q[CB_BARK_A1] = p.bark.depth1;
                    q[CB_BARK_AROUND] = p.bark.around;
                    q[CB_BARK_ALONG] = p.bark.along;
                    q[CB_BARK_PHASE] = p.bark.phase;
                }
                put3(q + CB_CONE_P0, p.p0);
                put3(q + CB_CONE_AXIS, u);
                q[CB_CONE_LEN] = len;
                q[CB_CONE_R0] = p.r0;
                q[CB_CONE_R1] = p.r1;
                q[CB_CONE_SIGMA] = p.sigma;
                q[CB_CONE_WEIGHT] = p.weight;
                put3(q + CB_CONE_RGB, n.shade);
                break;
            }
            default: {  // CONVOLUTION_SEGMENT
                at = newBlock(CB_CONV_SIZE);
                double* q = blockAt(at);
                put3(q + CB_CONV_P0, p.p0);
                put3(q + CB_CONV_AXIS, u);
                q[CB_CONV_LEN] = len;
                q[CB_CONV_Q0] = p.q0;
                q[CB_CONV_Q1] = p.q1;
                q[CB_CONV_KERNEL_WIDTH] = p.kernelWidth;
                q[CB_CONV_SUPPORT] = p.support;
                q[CB_CONV_WEIGHT] = p.weight;
                put3(q + CB_CONV_RGB, n.shade);
                break;
            }
        }
        const bool bark_ = n.type == NodeType::CONE && p.bark.active();
        code_.push_back({bark_ ? CB_I_BARK_CONE : int(n.type), at, 0, box(current_)});
        ++primitives;
        bark += bark_ ? 1 : 0;
        if (shades.size() < 2 && (shades.empty() || shades[0] != n.shade))
            shades.push_back(n.shade);
    }

    static void putCombiner(double* op, const Combiner& c)
    {
        op[CB_OP_TYPE] = double(c.type);
        op[CB_OP_N] = c.n;
        op[CB_OP_WIDTH] = c.width;
        op[CB_OP_ATTENUATION] = c.attenuation;
        op[CB_OP_K] = c.k;
        op[CB_OP_DARKEN] = c.darken;
    }

    int box(int index)
    {
        boxes_.push_back(bounds_[size_t(index)].support);
        boxAreaScales_.push_back(areaScales_[size_t(index)]);
        return int(boxes_.size()) - 1;
    }

    void emitOperator(int index, const Node& n)
    {
        const bool gbb = n.type == NodeType::GBB;
        const int at = newBlock(gbb ? CB_GBB_SIZE : CB_OP_SIZE);
        if (gbb) {
            putCombiner(blockAt(at) + CB_GBB_B1, n.gbb().b1);
            putCombiner(blockAt(at) + CB_GBB_B2, n.gbb().b2);
        } else {
            putCombiner(blockAt(at), n.combiner());
        }
        const int type = int(n.type);
        code_.push_back({CB_I_OPEN, at, type, box(index)});
        for (size_t i = 0; i < n.children.size(); ++i) {
            emit(n.children[i]);
            code_.push_back({CB_I_ACC, at, type, i == 0 ? 1 : 0});
        }
        if (gbb)
            emit(n.gbb().bound);
        code_.push_back({CB_I_CLOSE, at, type, 0});
    }

    void emitWarp(int index, const Node& n)
    {
        int at;
        switch (n.type) {
            case NodeType::TRANSFORM: {
                const auto& inv = std::get<TransformParams>(n.params).inverse;
                static_assert(std::extent_v<decltype(cb_affine::m)> ==
                              CB_AFFINE_SIZE - CB_AFFINE_M);
                at = newBlock(CB_AFFINE_SIZE);
                std::copy(std::begin(inv.m), std::end(inv.m), blockAt(at) + CB_AFFINE_M);
                break;
            }
            case NodeType::BEND: {
                const cb_bend& b = std::get<cb_bend>(n.params);
                at = newBlock(CB_BEND_SIZE);
                double* w = blockAt(at);
                put3(w + CB_BEND_P0, b.p0);
                put3(w + CB_BEND_U, b.u);
                put3(w + CB_BEND_V, b.v);
                put3(w + CB_BEND_W, b.w);
                w[CB_BEND_LEN] = b.len;
                w[CB_BEND_THETA] = b.theta;
                w[CB_BEND_RHO] = b.rho;
                w[CB_BEND_CH] = b.ch;
                w[CB_BEND_SH] = b.sh;
                w[CB_BEND_LSCALE] = b.lscale;
                break;
            }
            case NodeType::TWIST: {
                const cb_twist& t = std::get<cb_twist>(n.params);
                at = newBlock(CB_TWIST_SIZE);
                double* w = blockAt(at);
                put3(w + CB_TWIST_ORIGIN, t.o);
                put3(w + CB_TWIST_AXIS, t.a);
                w[CB_TWIST_RATE] = t.rate;
                w[CB_TWIST_PHASE] = t.phase;
                break;
            }
            default: {
                const cb_taper& t = std::get<cb_taper>(n.params);
                at = newBlock(CB_TAPER_SIZE);
                double* w = blockAt(at);
                put3(w + CB_TAPER_ORIGIN, t.o);
                put3(w + CB_TAPER_AXIS, t.a);
                w[CB_TAPER_LEN] = t.len;
                w[CB_TAPER_SCALE0] = t.scale0;
                w[CB_TAPER_SCALE1] = t.scale1;
                w[CB_TAPER_START] = t.start;
                break;
            }
        }
        code_.push_back({CB_I_WARP, at, int(n.type), box(index)});
        emit(n.children[0]);
        code_.push_back({CB_I_UNWARP, at, int(n.type), 0});
    }

    const BlobTree& tree_;
    const std::vector<NodeBounds>& bounds_;
    const std::vector<double>& areaScales_;
    int current_ = -1;
    std::vector<double>& P_;
    std::vector<Instr>& code_;
    std::vector<Box>& boxes_;
    std::vector<double>& boxAreaScales_;
};

double wyvill(double x)
{
    double dw;
    return cb_wyvill(x, &dw);
}

glm::dvec3 load3(const double* p)
{
    return {p[0], p[1], p[2]};
}

double pointBoxDistance(const glm::dvec3& p, const Box& b)
{
    const glm::dvec3 d = glm::max(glm::max(b.lo - p, p - b.hi), glm::dvec3(0.0));
    return glm::length(d);
}

/// Largest distance from the segment [a, b] to the points of a box: distance
/// to a segment is convex, so a corner attains it.
double segmentBoxMaxDistance(const glm::dvec3& a, const glm::dvec3& b, const Box& box)
{
    const glm::dvec3 ab = b - a;
    const double l2 = glm::dot(ab, ab), inv = l2 > 0.0 ? 1.0 / l2 : 0.0;
    double m2 = 0.0;
    for (int i = 0; i < 8; ++i) {
        const glm::dvec3 c(i & 1 ? box.hi.x : box.lo.x, i & 2 ? box.hi.y : box.lo.y,
                           i & 4 ? box.hi.z : box.lo.z);
        const double t = std::clamp(glm::dot(c - a, ab) * inv, 0.0, 1.0);
        const glm::dvec3 e = c - (a + t * ab);
        m2 = std::max(m2, glm::dot(e, e));
    }
    return std::sqrt(m2);
}

/// Whether the Wyvill falloff w(k (d/r - 1 + sigma)) is zero for every d >= dmin, r <= rmax.
bool beyondSupport(double dmin, double rmax, double sigma, double xT)
{
    return xT / sigma * (dmin / rmax - 1.0 + sigma) >= 1.0;
}

/// Interval of the Wyvill falloff w(k (d/r - 1 + sigma)) for d in [dmin, dmax], r in [rmin, rmax].
Interval skeletalInterval(double dmin, double dmax, double rmin, double rmax, double sigma,
                          double xT, double weight)
{
    const double k = xT / sigma;
    const double f0 = wyvill(k * (dmin / rmax - 1.0 + sigma));  // largest value
    const double f1 = wyvill(k * (dmax / rmin - 1.0 + sigma));  // smallest value
    return weight > 0.0 ? Interval{weight * f1, weight * f0} : Interval{weight * f0, weight * f1};
}

/// PCM deformation bounds over f in [a, b] (cb_pcm_deformation: T - f inside,
/// a bump of height at most w k^k/(k+1)^(k+1) just outside, 0 beyond).
double pcmMinD(double b, double T)
{
    return b > T ? T - b : 0.0;
}
double pcmMaxD(double a, double b, double T, double w, double k)
{
    if (a >= T)
        return T - a;
    if (b <= T - w)
        return 0.0;
    return w * std::pow(k, k) / std::pow(k + 1.0, k + 1.0);
}

double betterBlendG(double t, double T, double k)
{
    double d;
    return cb_better_blend_g(t, T, k, &d);
}

/// The interval of a combiner over children intervals.
Interval combine(const double* op, const std::vector<Interval>& iv, double T)
{
    const int type = int(op[CB_OP_TYPE]);
    Interval r;
    switch (type) {
        case CB_BLEND:
            for (const auto& i : iv) {
                r.lo += i.lo;
                r.hi += i.hi;
            }
            return r;
        case CB_RICCI: {
            // Monotone in every child; relative to the largest bound, as the
            // evaluators, so that f^n cannot overflow.
            double m = 0.0;
            for (const auto& i : iv)
                m = std::max(m, i.hi);
            if (!(m > 0.0))
                return {0.0, 0.0};
            if (!std::isfinite(m))
                return {0.0, kInf};
            double slo = 0.0, shi = 0.0;
            for (const auto& i : iv) {
                slo += cb_ricci_term(i.lo / m, op[CB_OP_N]);
                shi += cb_ricci_term(i.hi / m, op[CB_OP_N]);
            }
            return {m * cb_ricci_finish(slo, op[CB_OP_N]), m * cb_ricci_finish(shi, op[CB_OP_N])};
        }
        case CB_UNION:
            r = {-kInf, -kInf};
            for (const auto& i : iv) {
                r.lo = std::max(r.lo, i.lo);
                r.hi = std::max(r.hi, i.hi);
            }
            return r;
        case CB_INTERSECTION:
        case CB_DIFFERENCE:
            r = {kInf, kInf};
            for (size_t j = 0; j < iv.size(); ++j) {
                Interval i = iv[j];
                if (type == CB_DIFFERENCE && j > 0)
                    i = {2.0 * T - i.hi, 2.0 * T - i.lo};
                r.lo = std::min(r.lo, i.lo);
                r.hi = std::min(r.hi, i.hi);
            }
            return r;
        case CB_PCM: {
            r = {-kInf, -kInf};
            double dlo = 0.0, dhi = 0.0;
            for (const auto& i : iv) {
                r.lo = std::max(r.lo, i.lo);
                r.hi = std::max(r.hi, i.hi);
                dlo += std::min(0.0, pcmMinD(i.hi, T));
                dhi +=
                    std::max(0.0, pcmMaxD(i.lo, i.hi, T, op[CB_OP_WIDTH], op[CB_OP_ATTENUATION]));
            }
            return {r.lo + dlo, r.hi + dhi};
        }
        case CB_BETTER_BLEND:
            for (const auto& i : iv) {  // g is non-decreasing
                r.lo += betterBlendG(i.lo, T, op[CB_OP_K]);
                r.hi += betterBlendG(i.hi, T, op[CB_OP_K]);
            }
            return r;
        default:
            return {-kInf, kInf};
    }
}

/// Which children a combiner can do without on a region where the children's
/// fields lie in `iv`: removing them changes neither value nor gradient nor
/// colour anywhere in the region (up to ties between equal values).
void droppable(const double* op, const std::vector<Interval>& iv, double T, std::vector<char>& drop)
{
    const int type = int(op[CB_OP_TYPE]);
    const size_t n = iv.size();
    drop.assign(n, 0);
    switch (type) {
        case CB_BLEND:
            for (size_t i = 0; i < n; ++i)
                drop[i] = iv[i].isZero();
            break;
        case CB_RICCI:
            for (size_t i = 0; i < n; ++i)
                drop[i] = iv[i].hi <= 0.0;
            break;
        case CB_BETTER_BLEND:
            for (size_t i = 0; i < n; ++i)
                drop[i] = iv[i].lo >= -op[CB_OP_K] && iv[i].hi <= op[CB_OP_K];
            break;
        case CB_UNION:
        case CB_PCM: {
            // Keep the child with the largest lower bound; a child that stays
            // below it is never the maximum, not even in a tie (ties would pick the
            // colour by child order).  PCM weighs colours by |f| over all children,
            // so it drops only children that are zero as well (D(0) = 0 since
            // width <= T); and PCM picks no colour, so a zero child goes beside
            // any child that is never negative: the maximum's value is the same,
            // and a tie at 0 is where that child's field, at least 0 over the
            // box, is least, its gradient 0.  (Kept where the best child's
            // bound was 0, 300 laterals meeting at one node left 516
            // instructions in every leaf of the tree.)
            size_t best = 0;
            for (size_t i = 1; i < n; ++i)
                if (iv[i].lo > iv[best].lo)
                    best = i;
            for (size_t i = 0; i < n; ++i)
                drop[i] = i != best && (type == CB_UNION ? iv[i].hi < iv[best].lo
                                                         : iv[i].isZero() && iv[best].lo >= 0.0);
            break;
        }
        case CB_INTERSECTION:
        case CB_DIFFERENCE: {
            std::vector<Interval> t = iv;
            if (type == CB_DIFFERENCE)
                for (size_t i = 1; i < n; ++i)
                    t[i] = {2.0 * T - iv[i].hi, 2.0 * T - iv[i].lo};
            size_t best = 0;
            for (size_t i = 1; i < n; ++i)
                if (t[i].hi < t[best].hi)
                    best = i;
            // The solid being cut (child 0 of a difference) is always kept: it gives
            // the colour, so a cutter may tie with the minimum and still go; an
            // intersection's child must stay strictly above it (ties pick colours).
            for (size_t i = type == CB_DIFFERENCE ? 1 : 0; i < n; ++i)
                drop[i] = i != best &&
                          (type == CB_DIFFERENCE ? t[i].lo >= t[best].hi : t[i].lo > t[best].hi);
            break;
        }
        default:
            break;
    }
}

/// Whether an operator left with its one child `iv` computes exactly that child.
bool collapsesToChild(const double* op, const Interval& iv)
{
    switch (int(op[CB_OP_TYPE])) {
        case CB_BLEND:
        case CB_UNION:
        case CB_INTERSECTION:
        case CB_DIFFERENCE:
        case CB_PCM:
            return true;
        case CB_RICCI:
            return iv.lo >= 0.0;
        default:
            return false;
    }
}

/// Index of the instruction after the subtree starting at pos (no evaluation).
size_t skipSubtree(Code in, size_t pos)
{
    int depth = 0;
    do {
        const int op = in.data[pos].op;
        if (op == CB_I_OPEN || op == CB_I_WARP)
            ++depth;
        else if (op == CB_I_CLOSE || op == CB_I_UNWARP)
            --depth;
        ++pos;
    } while (depth > 0);
    return pos;
}

}  // namespace

double segmentBoxDistance2(const glm::dvec3& a, const glm::dvec3& b, const Box& box)
{
    // g(t) = |a + t d - box|^2 is convex and piecewise quadratic in t; its
    // derivative g'(t) = 2 sum_k d_k e_k(t), e_k the excess of coordinate k
    // beyond the box, is nondecreasing and piecewise linear.  The minimum on
    // [0, 1] is at an end where g' does not change sign there, else on the
    // piece where g' crosses zero, where it is linear.
    const glm::dvec3 d = b - a;
    auto excess = [&](int k, double t) {
        const double x = a[k] + t * d[k];
        return x < box.lo[k] ? x - box.lo[k] : (x > box.hi[k] ? x - box.hi[k] : 0.0);
    };
    auto slope = [&](double t) {
        return d.x * excess(0, t) + d.y * excess(1, t) + d.z * excess(2, t);
    };
    auto value = [&](double t) {
        const double ex = excess(0, t), ey = excess(1, t), ez = excess(2, t);
        return ex * ex + ey * ey + ez * ez;
    };
    if (slope(0.0) >= 0.0)
        return value(0.0);
    if (slope(1.0) <= 0.0)
        return value(1.0);
    double breaks[8];
    int nb = 0;
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0)
            continue;
        for (double face : {box.lo[k], box.hi[k]}) {
            const double t = (face - a[k]) / d[k];
            if (t > 0.0 && t < 1.0)
                breaks[nb++] = t;
        }
    }
    breaks[nb++] = 1.0;
    for (int i = 1; i < nb; ++i)  // insertion sort: at most seven
        for (int j = i; j > 0 && breaks[j - 1] > breaks[j]; --j)
            std::swap(breaks[j - 1], breaks[j]);
    double t0 = 0.0;
    for (int i = 0; i < nb; ++i) {
        const double t1 = breaks[i];
        if (t1 <= t0)
            continue;
        if (slope(t1) >= 0.0 || i == nb - 1) {
            // g' is linear on [t0, t1], negative at t0: its zero.
            const double s0 = slope(t0), s1 = slope(t1);
            const double t = s1 > s0 ? std::clamp(t0 + (t1 - t0) * (-s0 / (s1 - s0)), t0, t1) : t1;
            return std::max(std::min({value(t), value(t0), value(t1)}), 0.0);
        }
        t0 = t1;
    }
    return value(1.0);
}

int FieldProgram::maxStackDepth()
{
    return CB_STACK_DEPTH;
}
int FieldProgram::maxWarpDepth()
{
    return CB_WARP_DEPTH;
}

void FieldProgram::canonical(Code code, std::vector<double>& out) const
{
    out.push_back(params_[CB_P_T]);
    out.push_back(params_[CB_P_XT]);
    out.push_back(params_[CB_P_DETAIL]);
    for (size_t i = 0; i < code.size; ++i) {
        const Instr& in = code.data[i];
        size_t size = 0;
        switch (in.op) {
            case CB_SPHERE:
                size = CB_SPHERE_SIZE;
                break;
            case CB_SEGMENT:
            case CB_CONE:
                size = CB_CONE_SIZE;
                break;
            case CB_I_BARK_CONE:
                size = CB_BARK_SIZE;
                break;
            case CB_CONVOLUTION_SEGMENT:
                size = CB_CONV_SIZE;
                break;
            case CB_I_CONST:
                size = CB_CONST_SIZE;
                break;
            case CB_I_OPEN:
            case CB_I_ACC:
            case CB_I_CLOSE:
                size = in.b == CB_GBB ? CB_GBB_SIZE : CB_OP_SIZE;
                break;
            case CB_I_WARP:
                size = in.b == CB_TRANSFORM ? CB_AFFINE_SIZE
                       : in.b == CB_BEND    ? CB_BEND_SIZE
                       : in.b == CB_TWIST   ? CB_TWIST_SIZE
                                            : CB_TAPER_SIZE;
                break;
            default:
                break;  // UNWARP reads no parameters
        }
        out.push_back(in.op);
        out.push_back(in.b);
        out.push_back(in.op == CB_I_ACC ? in.c : 0);  // (c is a host-side box index elsewhere)
        out.insert(out.end(), params_.begin() + in.a, params_.begin() + in.a + long(size));
    }
}

bool FieldProgram::identical(const FieldProgram& other) const
{
    return params_ == other.params_ && code_.size() == other.code_.size() &&
           std::memcmp(code_.data(), other.code_.data(), code_.size() * sizeof(Instr)) == 0;
}

namespace {

/// The length of column c of a row-major 3x4 matrix: how much it stretches
/// axis c.
double columnLength(const double* m, int c)
{
    return std::sqrt(m[c] * m[c] + m[4 + c] * m[4 + c] + m[8 + c] * m[8 + c]);
}

/// The largest distance of a box from the line through o along the unit
/// axis a (0 for an empty box).
double fromAxis(const Box& box, const cb_vec3& o, const cb_vec3& a)
{
    if (box.empty())
        return 0.0;
    double hmin, hmax, rmax;
    axialExtent(box, glm::dvec3(o.x, o.y, o.z), glm::dvec3(a.x, a.y, a.z), hmin, hmax, rmax);
    return rmax;
}

/// How much the warps above each node scale the frame it lives in.
struct FrameScales {
    /// World units per unit of the frame: the transforms (a column's
    /// length: exact for a similarity) and tapers above it.
    std::vector<double> length;
    /// World area per unit of area in the frame, at most: the lengths'
    /// squares, and a twist's stretch along its turns, sqrt(1 + (rate r)^2)
    /// at the farthest r from its axis that its box reaches (a sphere
    /// twisted at 1000 degrees a unit 3 from the axis is a sheet of 19
    /// times its area).
    std::vector<double> area;
};

FrameScales frameScales(const BlobTree& tree, const std::vector<NodeBounds>& bounds)
{
    FrameScales out{std::vector<double>(tree.size(), 0.0), std::vector<double>(tree.size(), 0.0)};
    out.length[size_t(tree.root())] = out.area[size_t(tree.root())] = 1.0;
    for (size_t i = tree.size(); i-- > 0;) {  // parents follow their children
        const Node& n = tree.node(int(i));
        double f = 1.0, g = 1.0;
        if (n.type == NodeType::TRANSFORM) {
            f = 0.0;
            for (int c = 0; c < 3; ++c)
                f = std::max(f, columnLength(std::get<TransformParams>(n.params).forward, c));
            g = f * f;
        } else if (n.type == NodeType::TAPER) {
            const cb_taper& t = std::get<cb_taper>(n.params);
            f = std::max(t.scale0, t.scale1);
            g = f * f;
        } else if (n.type == NodeType::TWIST) {
            // (its child's positive box: the twist keeps the distance from
            // its axis, and the surface lies inside)
            const cb_twist& t = std::get<cb_twist>(n.params);
            const double r = fromAxis(bounds[size_t(n.children[0])].positive, t.o, t.a);
            g = std::sqrt(1.0 + t.rate * t.rate * r * r);
        } else if (n.type == NodeType::BEND) {
            // Lengthened along the arc, and a point r from the internode
            // lies up to rho + r from the arc's centre: at most
            // (arc / chord) (1 + r / rho).
            const cb_bend& b = std::get<cb_bend>(n.params);
            const double r = fromAxis(bounds[size_t(n.children[0])].positive, b.p0, b.u);
            if (b.theta != 0.0)
                g = (1.0 + r / b.rho) / b.lscale;
        }
        for (int c : n.children) {
            out.length[size_t(c)] = std::max(out.length[size_t(c)], out.length[i] * f);
            out.area[size_t(c)] = std::max(out.area[size_t(c)], out.area[i] * g);
        }
    }
    return out;
}

/// FieldProgram::farthestLocal(): where the kernels compare points with the
/// primitives, in each one's own frame under the warps above it, and every
/// number a warp computes on the way there (its input point, its origin, an
/// affine map's terms: nested translations of +1e6 and -1e6 cancel in
/// double, not in float).  Each in world units: a frame's coordinates times
/// how much the transforms above it scale them (a bark ridge drawn 1000
/// times larger and scaled down is as precise as one drawn to size).
double farthestInFrames(const BlobTree& tree, const std::vector<NodeBounds>& bounds,
                        const std::vector<double>& scale)
{
    double far = 0.0;
    for (size_t i = 0; i < tree.size(); ++i) {
        const Node& n = tree.node(int(i));
        const Box& b = bounds[i].positive;
        if (b.empty() || scale[i] == 0.0 || kindOf(n.type) == NodeKind::Operator)
            continue;
        // The node's box and parameters are in the frame it lives in.
        const double P = std::max({std::abs(b.lo.x), std::abs(b.lo.y), std::abs(b.lo.z),
                                   std::abs(b.hi.x), std::abs(b.hi.y), std::abs(b.hi.z)});
        double here = P;
        switch (n.type) {
            case NodeType::TRANSFORM: {
                // q = A p + b in the child's frame, each coordinate in world
                // units: times the length of the forward map's column for
                // its axis (a scale of [100, 1, 100] leaves y as it is).
                const auto& t = std::get<TransformParams>(n.params);
                const glm::dvec3 e = glm::max(glm::abs(b.lo), glm::abs(b.hi));
                for (int r = 0; r < 3; ++r) {
                    const double* row = t.inverse.m + 4 * r;
                    const double q = std::abs(row[0]) * e.x + std::abs(row[1]) * e.y +
                                     std::abs(row[2]) * e.z + std::abs(row[3]);
                    here = std::max(here, q * columnLength(t.forward, r));
                }
                break;
            }
            case NodeType::BEND:
                here += cb_length(std::get<cb_bend>(n.params).p0);
                break;
            case NodeType::TWIST:
                here += cb_length(std::get<cb_twist>(n.params).o);
                break;
            case NodeType::TAPER:
                here += cb_length(std::get<cb_taper>(n.params).o);
                break;
            default:
                break;
        }
        far = std::max(far, here * scale[i]);
    }
    return far;
}

}  // namespace

FieldProgram FieldProgram::compile(const BlobTree& tree)
{
    FieldProgram prog;
    prog.params_.assign(CB_P_HEADER, 0.0);
    prog.params_[CB_P_T] = tree.threshold();
    prog.params_[CB_P_XT] = tree.xT();
    prog.params_[CB_P_ZERO] = 0.0;
    prog.params_[CB_P_DETAIL] = tree.detailLimit();
    const auto bounds = computeBounds(tree);
    const FrameScales scales = frameScales(tree, bounds);
    Compiler c(tree, bounds, scales.area, prog.params_, prog.code_, prog.subtreeSupport_,
               prog.subtreeAreaScale_);
    c.emit(tree.root());
    prog.primitives_ = c.primitives;
    prog.bark_ = c.bark;
    if (c.shades.size() == 1)
        prog.uniformColor_ = c.shades[0];
    prog.positive_ = bounds[size_t(tree.root())].positive;
    prog.support_ = bounds[size_t(tree.root())].support;
    prog.farthestLocal_ = farthestInFrames(tree, bounds, scales.length);
    int stack = 0, warps = 0;
    depths(prog.code_, stack, warps);
    if (stack > CB_STACK_DEPTH || warps > CB_WARP_DEPTH)
        throw InputError(fmt::format(
            "the BlobTree nests too deeply for the field kernels: it needs {} stack entries and {} "
            "nested warps, the kernels hold {} and {}; flatten nested operators",
            stack, warps, CB_STACK_DEPTH, CB_WARP_DEPTH));
    return prog;
}

FieldProgram FieldProgram::compile(const BlobTree& tree, const std::string& source)
{
    try {
        return compile(tree);
    } catch (const InputError& e) {  // (the nesting depth, named by no file)
        throw InputError(fmt::format("{}: {}", source, e.what()));
    }
}

double FieldProgram::threshold() const
{
    return params_[CB_P_T];
}

double FieldProgram::detailLimit() const
{
    return params_[CB_P_DETAIL];
}

void FieldProgram::setDetailLimit(double wavelength)
{
    if (!(std::isfinite(wavelength) && wavelength >= 0.0))
        throw InputError(fmt::format("detail limit {}: must be a finite length >= 0", wavelength));
    params_[CB_P_DETAIL] = wavelength;
}

std::vector<float> FieldProgram::paramsFloat() const
{
    return std::vector<float>(params_.begin(), params_.end());
}

void FieldProgram::depths(Code code, int& stack, int& warps)
{
    int top = 0, w = 0;
    stack = warps = 0;
    for (size_t i = 0; i < code.size; ++i) {
        const Instr& in = code.data[i];
        switch (in.op) {
            case CB_I_OPEN:
                top += in.b == CB_GBB ? 2 : 1;
                break;
            case CB_I_ACC:
                --top;
                break;
            case CB_I_CLOSE:
                top -= in.b == CB_GBB ? 2 : 0;
                break;
            case CB_I_WARP:
                ++w;
                break;
            case CB_I_UNWARP:
                --w;
                break;
            default:
                ++top;
                break;  // primitives and constants push
        }
        stack = std::max(stack, top);
        warps = std::max(warps, w);
    }
}

FieldSample FieldProgram::evaluate(Code code, const glm::dvec3& p) const
{
    const cb_sample s = cb_run_program(reinterpret_cast<const int*>(code.data), int(code.size),
                                       params_.data(), cb_v3(p.x, p.y, p.z));
    return {s.v, {s.g.x, s.g.y, s.g.z}, {s.c.x, s.c.y, s.c.z}};
}

FieldSample FieldProgram::surfaceStep(Code code, const glm::dvec3& p, double reach,
                                      glm::dvec3& step) const
{
    cb_vec3 d;
    const cb_sample s = cb_surface_step(reinterpret_cast<const int*>(code.data), int(code.size),
                                        params_.data(), cb_v3(p.x, p.y, p.z), reach, &d);
    step = {d.x, d.y, d.z};
    return {s.v, {s.g.x, s.g.y, s.g.z}, {s.c.x, s.c.y, s.c.z}};
}

Interval FieldProgram::specialize(Code code, const Box& box, std::vector<Instr>* out) const
{
    size_t pos = 0;
    return node(code, pos, box, out, 0);
}

Interval FieldProgram::primitiveInterval(const Instr& in, const Box& box) const
{
    const double* q = params_.data() + in.a;
    const double xT = params_[CB_P_XT];
    double dmin, dmax;
    switch (in.op) {
        case CB_SPHERE: {
            const glm::dvec3 c = load3(q + CB_SPHERE_CENTER);
            const double r = q[CB_SPHERE_RADIUS], sigma = q[CB_SPHERE_SIGMA];
            dmin = pointBoxDistance(c, box);
            if (beyondSupport(dmin, r, sigma, xT))
                return {0.0, 0.0};  // the farthest corner need not be found
            dmax = segmentBoxMaxDistance(c, c, box);
            return skeletalInterval(dmin, dmax, r, r, sigma, xT, q[CB_SPHERE_WEIGHT]);
        }
        case CB_SEGMENT:
        case CB_CONE:
        case CB_I_BARK_CONE: {
            const glm::dvec3 a = load3(q + CB_CONE_P0),
                             b = a + q[CB_CONE_LEN] * load3(q + CB_CONE_AXIS);
            // Bark only deepens furrows: the radius is at least r - 7/4 A.
            const double furrow =
                in.op == CB_I_BARK_CONE ? 1.75 * std::max(q[CB_BARK_A0], q[CB_BARK_A1]) : 0.0;
            const double rmin = std::min(q[CB_CONE_R0], q[CB_CONE_R1]) - furrow,
                         rmax = std::max(q[CB_CONE_R0], q[CB_CONE_R1]);
            dmin = std::sqrt(segmentBoxDistance2(a, b, box));
            if (beyondSupport(dmin, rmax, q[CB_CONE_SIGMA], xT))
                return {0.0, 0.0};
            dmax = segmentBoxMaxDistance(a, b, box);
            return skeletalInterval(dmin, dmax, rmin, rmax, q[CB_CONE_SIGMA], xT,
                                    q[CB_CONE_WEIGHT]);
        }
        default: {  // convolution segment
            const glm::dvec3 a = load3(q + CB_CONV_P0),
                             b = a + q[CB_CONV_LEN] * load3(q + CB_CONV_AXIS);
            const double s = q[CB_CONV_KERNEL_WIDTH], support = q[CB_CONV_SUPPORT],
                         weight = q[CB_CONV_WEIGHT];
            dmin = std::sqrt(segmentBoxDistance2(a, b, box));
            if (dmin >= support)
                return {0.0, 0.0};
            // Every kernel value is at most 1/(1 + s^2 (dmin^2 + tau^2))^2 for the
            // distance tau along the axis from the closest point, so the integral
            // is at most that of an infinite line at distance dmin; the window is
            // at most W(dmin).
            const double P2 = 1.0 + s * s * dmin * dmin;
            double dW;
            const double W = cb_wyvill(2.0 * dmin / support - 1.0, &dW);
            const double top =
                std::max(q[CB_CONV_Q0], q[CB_CONV_Q1]) * M_PI / (2.0 * s * P2 * std::sqrt(P2)) * W;
            return weight > 0.0 ? Interval{0.0, weight * top} : Interval{weight * top, 0.0};
        }
    }
}

Box FieldProgram::warpChildBox(const Instr& in, const Box& box) const
{
    const double* w = params_.data() + in.a;
    if (in.b == CB_TRANSFORM)
        return affineImage(box, w + CB_AFFINE_M);
    if (in.b == CB_BEND) {
        const glm::dvec3 p0 = load3(w + CB_BEND_P0), u = load3(w + CB_BEND_U),
                         v = load3(w + CB_BEND_V);
        const glm::dvec3 ax = load3(w + CB_BEND_W);
        const double len = w[CB_BEND_LEN], theta = w[CB_BEND_THETA], rho = w[CB_BEND_RHO];
        const double ch = w[CB_BEND_CH], sh = w[CB_BEND_SH], ls = w[CB_BEND_LSCALE];
        // Local coordinates of the box's points: x along u, y along v, z along ax.
        double x0 = kInf, x1 = -kInf, y0 = kInf, y1 = -kInf, z0 = kInf, z1 = -kInf;
        for (const auto& c : box.corners()) {
            const glm::dvec3 d = c - p0;
            x0 = std::min(x0, glm::dot(d, u));
            x1 = std::max(x1, glm::dot(d, u));
            y0 = std::min(y0, glm::dot(d, v));
            y1 = std::max(y1, glm::dot(d, v));
            z0 = std::min(z0, glm::dot(d, ax));
            z1 = std::max(z1, glm::dot(d, ax));
        }
        // Child-space images, as (a, y') boxes in the same frame, of those of
        // cb_bend_apply's three regions the box reaches: the arc for the
        // angles about its centre that the box spans, the straight parts
        // before p0 and after p1 where it reaches them.  (Each taken whole,
        // a leaf beside the arc bounded the child over the internode's
        // length, and a nested bend sampled 265 times the leaves it kept.)
        std::vector<std::array<double, 4>> parts;  // a0 a1 y0 y1
        if (theta <= 0.0) {
            parts.push_back({x0, x1, y0, y1});
        } else {
            const double h = 0.5 * theta;
            const glm::dvec3 centre = p0 + 0.5 * len * u - rho * ch * v;
            // The angles phi = atan2(x - L/2, y + rho cos(theta/2)) of the
            // corners, as the kernel's: over the box's projection, a convex
            // polygon, they are extreme at corners unless it surrounds the
            // centre (a span of pi or more: then every angle).
            double phi0 = kInf, phi1 = -kInf;
            for (const auto& c : box.corners()) {
                const glm::dvec3 d = c - centre;
                const double phi = std::atan2(glm::dot(d, u), glm::dot(d, v));
                phi0 = std::min(phi0, phi);
                phi1 = std::max(phi1, phi);
            }
            if (!(phi1 - phi0 < M_PI)) {
                phi0 = -M_PI;
                phi1 = M_PI;
            }
            if (phi1 >= -h && phi0 <= h) {
                // Arc: a = (phi + theta/2) L / theta; y' = r - rho with r the
                // distance from the arc's axis (through its centre, along ax).
                const double reach =
                    1e3 * (1.0 + glm::length(box.size()) + glm::length(centre - p0));
                const double rmin =
                    std::sqrt(segmentBoxDistance2(centre - reach * ax, centre + reach * ax, box));
                double rmax = 0.0;
                for (const auto& c : box.corners()) {
                    const glm::dvec3 d = c - centre;
                    rmax = std::max(rmax, glm::length(d - glm::dot(d, ax) * ax));
                }
                const double k = len / theta;
                parts.push_back({(std::max(phi0, -h) + h) * k, (std::min(phi1, h) + h) * k,
                                 rmin - rho, rmax - rho});
            }
            // Before p0 and after p1: rigid motions (scaled along the tangent).
            auto linear = [&](double ox, double j00, double j01, double j10, double j11,
                              double a0) {
                double a[4] = {kInf, -kInf, kInf, -kInf};
                for (double x : {x0, x1})
                    for (double y : {y0, y1}) {
                        const double av = a0 + j00 * (x - ox) + j01 * y,
                                     yv = j10 * (x - ox) + j11 * y;
                        a[0] = std::min(a[0], av);
                        a[1] = std::max(a[1], av);
                        a[2] = std::min(a[2], yv);
                        a[3] = std::max(a[3], yv);
                    }
                parts.push_back({a[0], a[1], a[2], a[3]});
            };
            if (phi0 < -h)
                linear(0.0, ls * ch, ls * sh, -sh, ch, 0.0);
            if (phi1 > h)
                linear(len, ls * ch, -ls * sh, sh, ch, len);
        }
        Box out;
        for (const auto& q : parts)
            for (double a : {q[0], q[1]})
                for (double y : {q[2], q[3]})
                    for (double z : {z0, z1})
                        out.expand(p0 + a * u + y * v + z * ax);
        return out;
    }
    // Twist and taper keep the height along their axis and move points only
    // across it.  (Bounded by the whole cylinder about the axis that the box
    // spans, a leaf beside one twig of a twisted pair saw both.)
    static_assert(CB_TWIST_ORIGIN == CB_TAPER_ORIGIN && CB_TWIST_AXIS == CB_TAPER_AXIS);
    const glm::dvec3 o = load3(w + CB_TWIST_ORIGIN), a = load3(w + CB_TWIST_AXIS);
    double hmin, hmax, rmax;
    axialExtent(box, o, a, hmin, hmax, rmax);
    const auto corners = box.corners();
    Box out;
    if (in.b == CB_TWIST) {
        // The box turned by the angle at the middle of its heights: every
        // point's own angle is within half the span of it, so its image is
        // within the chord 2 r sin(span / 4).
        const double rate = w[CB_TWIST_RATE], phase = w[CB_TWIST_PHASE];
        const double span = std::abs(rate) * (hmax - hmin);
        if (!(span < M_PI))
            return cylinderBox(o + hmin * a, o + hmax * a, a, rmax);
        const double mid = phase - rate * 0.5 * (hmin + hmax);
        for (const auto& c : corners)
            out.expand(o + rotateAbout(c - o, a, mid));
        return out.padded(2.0 * rmax * std::sin(0.25 * span));
    }
    // Taper: q = o + h a + k d_perp with k = 1 / s(h); for a fixed k an
    // affine map, and q linear in k: the images of the corners at the
    // least and the greatest k over the box's heights bound it.
    auto scale = [&](double h) {
        return cb_taper_scale(w[CB_TAPER_SCALE0], w[CB_TAPER_SCALE1], w[CB_TAPER_LEN],
                              w[CB_TAPER_START], h);
    };
    for (double k : {1.0 / scale(hmin), 1.0 / scale(hmax)})
        for (const auto& c : corners) {
            const glm::dvec3 d = c - o;
            const double h = glm::dot(d, a);
            out.expand(o + h * a + k * (d - h * a));
        }
    return out;
}

namespace {

/// operatorNode()'s working lists, one set per depth of the recursion and
/// thread, reused from call to call (the topology search specialises millions
/// of times; five fresh vectors per call cost as much as the intervals).
struct NodeScratch {
    struct Child {
        size_t begin, end;
    };
    std::vector<Child> kids;
    std::vector<Interval> iv;
    std::vector<char> drop, drop2;
    std::vector<size_t> kept;
    std::vector<Instr> segment;
};
thread_local std::deque<NodeScratch> tlsNodeScratch;  // a deque: growing keeps references valid

void emitZero(std::vector<Instr>* out)
{
    if (out)
        out->push_back({CB_I_CONST, CB_P_ZERO, 0, 0});
}

/// What an operator computes on a region where its children's fields lie in
/// scratch.iv: the combiner that remains (for a GBB whose bound is 1 or 0
/// everywhere there, B1's or B2's alone), whether the whole GBB remains, and
/// the bounds of its field; scratch.drop receives the children it can do
/// without.
struct OperatorReduction {
    const double* op;
    bool keepGbb;
    Interval result;
};

OperatorReduction reduceOperator(const double* block, bool gbb, const Interval& bound, double T,
                                 NodeScratch& scratch)
{
    const auto& iv = scratch.iv;
    auto& drop = scratch.drop;
    if (!gbb) {
        const Interval result = combine(block, iv, T);
        droppable(block, iv, T, drop);
        return {block, false, result};
    }
    const double* op1 = block + CB_GBB_B1;
    const double* op2 = block + CB_GBB_B2;
    const Interval i1 = combine(op1, iv, T), i2 = combine(op2, iv, T);
    const double b0 = std::clamp(bound.lo, 0.0, 1.0), b1 = std::clamp(bound.hi, 0.0, 1.0);
    if (b1 <= 0.0) {  // bound 0 everywhere: B2 alone
        droppable(op2, iv, T, drop);
        return {op2, false, i2};
    }
    if (b0 >= 1.0) {  // bound 1 everywhere: B1 alone
        droppable(op1, iv, T, drop);
        return {op1, false, i1};
    }
    droppable(op1, iv, T, drop);
    droppable(op2, iv, T, scratch.drop2);
    for (size_t i = 0; i < iv.size(); ++i)
        drop[i] = drop[i] && scratch.drop2[i];
    return {op1, true, {std::min(i1.lo, i2.lo), std::max(i1.hi, i2.hi)}};
}

/// Replaces an operator's specialised code, out[start, end), by the code of
/// what remains of it: the constant 0 when no child is left, the one child
/// left when the combiner would pass it through unchanged, else OPEN (reading
/// the block at `a`, support box `supportBox`) and the kept children.
void rebuildOperator(const OperatorReduction& r, int a, int supportBox,
                     NodeScratch::Child boundCode, size_t start, NodeScratch& scratch,
                     std::vector<Instr>& out)
{
    const auto& kids = scratch.kids;
    auto& segment = scratch.segment;
    auto& kept = scratch.kept;
    segment.clear();
    kept.clear();
    for (size_t i = 0; i < kids.size(); ++i)
        if (!scratch.drop[i])
            kept.push_back(i);
    auto copy = [&](size_t b, size_t e) {
        segment.insert(segment.end(), out.begin() + long(b), out.begin() + long(e));
    };
    if (kept.empty()) {
        segment.push_back({CB_I_CONST, CB_P_ZERO, 0, 0});
    } else if (!r.keepGbb && kept.size() == 1 && collapsesToChild(r.op, scratch.iv[kept[0]])) {
        copy(kids[kept[0]].begin, kids[kept[0]].end);
    } else {
        const int type = r.keepGbb ? CB_GBB : int(r.op[CB_OP_TYPE]);
        segment.push_back({CB_I_OPEN, a, type, supportBox});
        for (size_t k = 0; k < kept.size(); ++k) {
            copy(kids[kept[k]].begin, kids[kept[k]].end);
            segment.push_back({CB_I_ACC, a, type, kept[k] == 0 ? 1 : 0});
        }
        if (r.keepGbb)
            copy(boundCode.begin, boundCode.end);
        segment.push_back({CB_I_CLOSE, a, type, 0});
    }
    out.resize(start);
    out.insert(out.end(), segment.begin(), segment.end());
}

}  // namespace

Interval FieldProgram::node(Code in, size_t& pos, const Box& box, std::vector<Instr>* out,
                            size_t depth) const
{
    const Instr head = in.data[pos];
    if (head.op == CB_I_CONST) {
        ++pos;
        if (out)
            out->push_back(head);
        const double v = params_[size_t(head.a + CB_CONST_VALUE)];
        return {v, v};
    }
    if (head.op != CB_I_OPEN && head.op != CB_I_WARP) {
        ++pos;
        return primitiveNode(head, box, out);
    }
    // A subtree whose support misses the box is zero there: skip it unread.
    const Box& support = subtreeSupport_[size_t(head.c)];
    if (support.intersected(box).empty()) {
        pos = skipSubtree(in, pos);
        emitZero(out);
        return {0.0, 0.0};
    }
    if (head.op == CB_I_WARP)
        return warpNode(in, pos, box, out, depth);
    return operatorNode(in, pos, box, out, depth);
}

Interval FieldProgram::primitiveNode(const Instr& head, const Box& box,
                                     std::vector<Instr>* out) const
{
    // Most primitives of a big tree are far from a given box: their
    // support box says so before any distance is computed.
    const Interval iv = subtreeSupport_[size_t(head.c)].intersected(box).empty()
                            ? Interval{0.0, 0.0}
                            : primitiveInterval(head, box);
    if (iv.isZero())
        emitZero(out);
    else if (out)
        out->push_back(head);
    return iv;
}

Interval FieldProgram::warpNode(Code in, size_t& pos, const Box& box, std::vector<Instr>* out,
                                size_t depth) const
{
    const Instr head = in.data[pos++];
    const size_t start = out ? out->size() : 0;
    if (out)
        out->push_back(head);
    const Interval iv = node(in, pos, warpChildBox(head, box), out, depth + 1);
    ++pos;  // UNWARP
    if (out) {
        if (iv.isZero()) {
            out->resize(start);
            emitZero(out);
        } else {
            out->push_back(in.data[pos - 1]);
        }
    }
    return iv;
}

Interval FieldProgram::operatorNode(Code in, size_t& pos, const Box& box, std::vector<Instr>* out,
                                    size_t depth) const
{
    // OPEN child ACC child ACC ... [bound] CLOSE
    const Instr head = in.data[pos++];
    if (tlsNodeScratch.size() <= depth)
        tlsNodeScratch.resize(depth + 1);
    NodeScratch& scratch = tlsNodeScratch[depth];
    scratch.kids.clear();
    scratch.iv.clear();
    const size_t start = out ? out->size() : 0;
    Interval bound{0.0, 0.0};
    NodeScratch::Child boundCode{0, 0};
    while (in.data[pos].op != CB_I_CLOSE) {
        const size_t b = out ? out->size() : 0;
        const Interval i = node(in, pos, box, out, depth + 1);
        const size_t e = out ? out->size() : 0;
        if (in.data[pos].op == CB_I_ACC) {
            ++pos;
            scratch.kids.push_back({b, e});
            scratch.iv.push_back(i);
        } else {  // the bounding field of a GBB
            bound = i;
            boundCode = {b, e};
        }
    }
    ++pos;  // CLOSE

    const OperatorReduction r =
        reduceOperator(params_.data() + head.a, head.b == CB_GBB, bound, params_[CB_P_T], scratch);
    if (out) {
        // A whole GBB reads both combiners from its own block; one combiner
        // left alone reads its own.
        const int a = r.keepGbb ? head.a : int(r.op - params_.data());
        rebuildOperator(r, a, head.c, boundCode, start, scratch, *out);
    }
    return r.result;
}

}  // namespace cambium
