// cambium — the global-to-local growth model.
#include "model/growth.h"

#include "blobtree/stats.h"
#include "core/error.h"
#include "core/random.h"
#include "core/system.h"
#include "core/math.h"

#include <fmt/format.h>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>

namespace cambium {

namespace {

double radians(double deg)
{
    return deg * kDegree;
}

/// Angular distance in degrees, in [0, 180].
double angularDistance(double deg)
{
    const double a = std::fmod(std::abs(deg), 360.0);
    return std::min(a, 360.0 - a);
}

/// SplitMix64: a seeded, platform-independent stream for the stochastic parts.

glm::dvec3 anyPerpendicular(const glm::dvec3& v)
{
    const glm::dvec3 a = std::abs(v.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    return glm::normalize(glm::cross(v, a));
}

}  // namespace

double GrowthBranch::lengthAt(int year) const
{
    const int k = year - (birth - 1);
    if (k <= 0)
        return 0.0;
    return k >= int(length.size()) ? length.back() : length[size_t(k)];
}

GrowthModel::GrowthModel(GrowthParameters params) : p_(std::move(params))
{
    grow();
    // The trunk base's supported length at the end: the radius scale.
    const std::vector<double> support = branchSupports(double(p_.years));
    supportRef_ = std::max(support[0], 1e-12);
    // Each metamer's radius at the end (or when its branch was lost: its
    // support stays), which groups short thick metamers into chords.
    for (size_t b = 0; b < branches_.size(); ++b) {
        std::vector<double> lengths;
        const std::vector<double> beyond = metamerSupports(b, double(p_.years), support, lengths);
        GrowthBranch& br = branches_[b];
        br.finalRadius.resize(lengths.size());
        for (size_t j = 0; j < lengths.size(); ++j)
            br.finalRadius[j] = radiusOf(beyond[j]);
    }
}

std::vector<double> GrowthModel::branchSupports(double t) const
{
    // Each branch's grown length plus its laterals' (lost ones at the length
    // they had: the wood they made stays).
    std::vector<double> support(branches_.size(), 0.0);
    for (size_t b = branches_.size(); b-- > 0;) {
        support[b] += grownLength(int(b), t);
        if (branches_[b].parent >= 0)
            support[size_t(branches_[b].parent)] += support[b];
    }
    return support;
}

std::vector<double> GrowthModel::metamerSupports(size_t bi, double t,
                                                 const std::vector<double>& support,
                                                 std::vector<double>& lengths) const
{
    const GrowthBranch& b = branches_[bi];
    const int m = b.metamers();
    lengths.assign(size_t(m), 0.0);
    std::vector<double> lateralSupport(size_t(m), 0.0);
    for (const GrowthShoot& s : b.shoots)
        for (int k = 0; k < s.metamers; ++k)
            lengths[size_t(s.firstMetamer + k)] = metamerLength(s, k, t);
    for (int c : b.laterals)
        lateralSupport[size_t(branches_[size_t(c)].node)] += support[size_t(c)];
    std::vector<double> beyond(size_t(m) + 1, 0.0);  // beyond[j]: the support of metamer j's base
    for (int j = m - 1; j >= 0; --j)
        beyond[size_t(j)] = beyond[size_t(j) + 1] + lengths[size_t(j)] + lateralSupport[size_t(j)];
    return beyond;
}

double GrowthModel::radiusOf(double support) const
{
    return p_.tipRadius + (p_.baseRadius - p_.tipRadius) *
                              std::pow(std::max(support, 0.0) / supportRef_, p_.thickening);
}

bool GrowthModel::separationHolds(int first, int m, int previous) const
{
    if (previous < 0)
        return true;
    const int last = first + m - 1;
    if (angularDistance((last - previous) * p_.phyllotaxis) < p_.longestSeparation)
        return false;
    return m < 2 || angularDistance((last - 1 - previous) * p_.phyllotaxis) >= p_.longestSeparation;
}

void GrowthModel::grow()
{
    const int Y = p_.years;
    uint64_t rng = p_.seed * 0x2545f4914f6cdd1dull + 17;
    GrowthBranch trunk;
    trunk.order = 0;
    trunk.birth = 1;
    trunk.lost = Y + 1;
    trunk.length.push_back(0.0);
    for (int y = 1; y <= Y; ++y)  // Gh, with eq. 5
        trunk.length.push_back(std::max(p_.trunkLength * p_.Gh(double(y) / Y),
                                        trunk.length.back() + p_.minShootLength));
    branches_.push_back(std::move(trunk));

    // What the growth holds per internode, measured (about 190 bytes at 10
    // million internodes), and as much again for what is made of it; and
    // beyond that, what its branches hold whatever their internodes (their
    // vector, and the next it grows into, and each one's lengths): the
    // growth stops, with the numbers, before it would need more memory than
    // the machine has, whatever max_internodes (up to 10^9) allows.
    // (Counted by internodes alone, a lateral at every bud made 10^7
    // branches, 4.9 GB, and ran out of memory, exit 1.)
    constexpr double kBytesPerInternode = 400.0;
    const double lengthBytes = 16.0 + 8.0 * (Y + 1);
    const double room = availableMemoryBytes();
    long long internodes = 0;
    auto checkMemory = [&](int order, int year) {
        const double branch = sizeof(GrowthBranch), count = double(branches_.size()),
                     capacity = double(branches_.capacity());
        const double bytes = double(internodes) * kBytesPerInternode + capacity * branch +
                             (count == capacity ? 2.0 * capacity * branch : 0.0) +
                             count * lengthBytes;
        if (bytes > room)
            checkMemoryFits(
                bytes, room,
                fmt::format("{}: growing more than {} internodes in {} branches "
                            "(reached at a branch of order {} in year {})",
                            p_.source.empty() ? "the growth" : p_.source,
                            formatCount(double(internodes)), formatCount(count), order, year),
                "raise min_scale, lower Gss or Gm, or lower max_internodes");
    };
    for (size_t bi = 0; bi < branches_.size(); ++bi) {
        {
            GrowthBranch& b = branches_[bi];
            b.azimuth0 = 2.0 * kPi * splitMix01(rng);
            for (double& ph : b.phase)
                ph = 2.0 * kPi * splitMix01(rng);
            // Shoots: m = Gm(l_s / l_s,max) metamers (eq. 14), the nearest
            // count for which the 40 degree rule holds.
            int first = 0, previous = -1;
            for (int y = b.birth; y <= b.lastYear(); ++y) {
                GrowthShoot s;
                s.year = y;
                s.firstMetamer = first;
                s.start = b.lengthAt(y - 1);
                s.length = b.lengthAt(y) - s.start;
                const int m0 = std::max(1, int(std::lround(p_.Gm(s.length / p_.maxShootLength))));
                s.metamers = s.planned = m0;
                for (int d = 0; d <= 16; ++d) {
                    if (separationHolds(first, m0 + d, previous)) {
                        s.metamers = m0 + d;
                        break;
                    }
                    if (m0 - d >= 1 && separationHolds(first, m0 - d, previous)) {
                        s.metamers = m0 - d;
                        break;
                    }
                }
                previous = first + s.metamers - 1;
                first += s.metamers;
                internodes += s.metamers;
                if (double(internodes) > p_.maxInternodes)
                    throw InputError(
                        fmt::format("{}: the parameters grow more than {:.0f} internodes "
                                    "(max_internodes) — reached at a "
                                    "branch of order {} in year {}: raise min_scale, lower Gss or "
                                    "Gm, or raise max_internodes",
                                    !p_.source.empty() ? p_.source
                                    : p_.name.empty()  ? "growth parameters"
                                                       : p_.name,
                                    p_.maxInternodes, b.order, y));
                checkMemory(b.order, y);
                b.shoots.push_back(s);
            }
        }
        // Laterals, from the buds of each shoot, the year after it grew.
        const GrowthBranch b = branches_[bi];  // a copy: branches_ grows below
        const double finalLength = b.length.back();
        std::vector<int> laterals;
        for (const GrowthShoot& s : b.shoots)
            for (int k = 0; k < s.metamers; ++k) {
                const int birth = s.year + 1;
                if (birth > Y || birth >= b.lost)
                    continue;
                const double xs = double(k + 1) / s.metamers;
                const double x = s.start + xs * s.length;
                const double sb = p_.Gss(xs) * b.scale * p_.Gbs(x / finalLength);  // eq. 15
                if (sb < p_.minScale)
                    continue;
                GrowthBranch c;
                c.order = b.order + 1;
                c.parent = int(bi);
                c.node = s.firstMetamer + k;
                c.position = x;
                c.azimuth = radians(c.node * p_.phyllotaxis) + b.azimuth0;
                c.scale = sb;
                c.birth = birth;
                c.lost =
                    std::min(birth + std::max(1, int(std::lround(p_.Ga(sb)))), b.lost);  // eq. 11
                c.length.push_back(0.0);
                for (int y = birth; y < c.lost && y <= Y; ++y) {
                    const double lp = b.lengthAt(y), xy = std::min(1.0, x / lp), ty = double(y) / Y;
                    double ld = lp * ((1.0 - ty) * p_.Gs1(xy) + ty * p_.Gs2(xy)) *
                                sb;  // eq. 6, scaled by s_b
                    if (c.order >= 2)
                        ld /= 0.5 * c.order + 1.0;  // eq. 12
                    c.length.push_back(std::max(ld, c.length.back() + p_.minShootLength));  // eq. 7
                }
                laterals.push_back(int(branches_.size()));
                checkMemory(c.order, birth);
                branches_.push_back(std::move(c));
            }
        branches_[bi].laterals = std::move(laterals);
    }
}

double GrowthModel::organTime(const GrowthShoot& s, int k, double t) const
{
    const double start = s.metamers > 1 ? p_.shootSpread * k / (s.metamers - 1) : 0.0;
    return std::clamp((t - (s.year - 1) - start) / (1.0 - p_.shootSpread), 0.0, 1.0);
}

double GrowthModel::metamerLength(const GrowthShoot& s, int k, double t) const
{
    const double li = s.length / s.metamers;
    const double u = t - (s.year - 1);
    if (u <= 0.0)
        return 0.0;
    if (u >= 1.0)
        return li;
    return li * p_.internodeGrowth(organTime(s, k, t));
}

double GrowthModel::grownLength(int bi, double t) const
{
    const GrowthBranch& b = branches_[size_t(bi)];
    if (t <= b.birth - 1)
        return 0.0;
    const int y = growthYear(t);
    if (y > b.lastYear())
        return b.length.back();
    if (t == y)
        return b.lengthAt(y);  // exactly l_y (a sum of the metamers could differ in the last bit)
    const GrowthShoot& s = b.shoots[size_t(y - b.birth)];
    double l = s.start;
    for (int k = 0; k < s.metamers; ++k)
        l += metamerLength(s, k, t);
    return std::min(l, b.lengthAt(y));  // (rounding could put the sum a bit past l_y)
}

TreeBuildOptions GrowthModel::buildOptions() const
{
    TreeBuildOptions o;
    o.junction = TreeBuildOptions::Junction::Pcm;
    o.bark = p_.bark;
    o.barkDetail = p_.barkDetail;
    o.barkPhoto = p_.barkPhoto;
    o.barkCoherent = p_.barkCoherent;
    o.ridgeYears = p_.ridgeYears;
    o.ridgeRadius = p_.ridgeRadius;
    return o;
}

BlobTree GrowthModel::tree(double t, bool leaves) const
{
    return buildTree(skeleton(t, leaves), buildOptions());
}

int growthYear(double t)
{
    return std::max(1, int(std::ceil(t)));
}

double GrowthModel::growthTime(double time) const
{
    const int y = growthYear(time);
    return (y - 1) + std::min(1.0, (time - (y - 1)) / p_.growingSeason);
}

/// One drawing of the tree at a calendar time, branch by branch, parents
/// first: each branch starts at the frame its parent left at its node.
class GrowthModel::SkeletonDrawer {
public:
    // Growth, ageing and dying back run on the growth clock, which stands
    // still after each growing season; only the leaves fall on the calendar.
    SkeletonDrawer(const GrowthModel& model, double time, bool leaves)
        : model_(model),
          p_(model.p_),
          branches_(model.branches_),
          leaves_(leaves),
          t_(model.growthTime(time)),
          minLength_(1e-3 * p_.tipRadius),
          support_(model.branchSupports(t_)),
          nodes_(branches_.size()),
          visible_(branches_.size(), 0.0),
          grown_(branches_.size(), 0.0),
          alpha_(radians(p_.branchingAngle)),
          wave1_(1.7 * p_.maxShootLength),
          wave2_(0.61 * p_.maxShootLength),
          noise_(radians(p_.orientationNoise)),
          year_(growthYear(t_)),
          u_(t_ - (year_ - 1)),
          fall_(smoothstep(p_.leafFall, std::min(1.0, p_.leafFall + 0.1), time - (year_ - 1))),
          barkDark_(0.55 * p_.bark)
    {
    }

    Skeleton draw()
    {
        for (size_t bi = 0; bi < branches_.size(); ++bi)
            drawBranch(bi);
        return std::move(sk_);
    }

private:
    struct NodeFrame {
        glm::dvec3 p, h, u;  ///< the metamer's tip, heading, reference across it
        double r = 0.0;      ///< radius at the tip
        long long id = -1;   ///< its internode
    };

    /// Where a branch starts, and its frame there (the trunk's: the origin, heading up).
    struct Start {
        glm::dvec3 base{0.0}, h0{0.0, 1.0, 0.0}, axis{1.0, 0.0, 0.0};
        long long parentId = -1;
        double parentRadius = 0.0;
    };

    /// Metamers short for their radius (old, thick wood) are drawn as one
    /// internode up to the next junction, at least four of its final radii
    /// long: cones much shorter than thick would lose most of their length
    /// to the junction rules (eq. 3) and leave waists.  The grouping
    /// depends on final lengths and radii only (and on which laterals
    /// live), so that it does not change from frame to frame.  `pending`
    /// is the internode being gathered, `gathered` its final length.
    struct Gathering {
        Internode pending;
        size_t pendingFrom = 0;  ///< its first metamer's frame
        bool open = false;
        double gathered = 0.0, pendingFinalRadius = 0.0;
        long long previous = -1;  ///< the internode before it
    };

    void drawBranch(size_t bi)
    {
        const GrowthBranch& b = branches_[bi];
        if (t_ <= b.birth - 1)
            return;
        const GrowthBranch* parent = b.parent >= 0 ? &branches_[size_t(b.parent)] : nullptr;
        Start start;
        if (parent && !startOnParent(b, start))
            return;  // the parent died back past it, or is gone
        grown_[bi] = model_.grownLength(int(bi), t_);
        if (t_ >= b.lost) {
            leaveScar(bi, parent != nullptr, start);
            return;
        }
        // Dying back over the year it is lost; carried off with a dying parent.
        double v = b.lost == year_ ? 1.0 - smoothstep(0.0, 1.0, u_) : 1.0;
        if (parent && visible_[size_t(b.parent)] < grown_[size_t(b.parent)]) {
            const double lp = grown_[size_t(b.parent)];
            v = std::min(
                v, std::clamp((visible_[size_t(b.parent)] - b.position) / (lp - b.position), 0.0,
                              1.0));
        }
        const double L = grown_[bi];
        visible_[bi] = L * v;
        if (visible_[bi] < minLength_)
            return;
        drawMetamers(bi, parent != nullptr, start);
    }

    /// The start of lateral `b` at its node on its parent; false when the
    /// parent no longer reaches that node.
    bool startOnParent(const GrowthBranch& b, Start& start) const
    {
        const std::vector<NodeFrame>& pn = nodes_[size_t(b.parent)];
        if (size_t(b.node) >= pn.size())
            return false;
        const NodeFrame& at = pn[size_t(b.node)];
        start.base = at.p;
        start.parentId = at.id;
        start.parentRadius = at.r;
        const glm::dvec3 across =
            std::cos(b.azimuth) * at.u + std::sin(b.azimuth) * glm::cross(at.h, at.u);
        start.h0 = glm::normalize(std::cos(alpha_) * at.h + std::sin(alpha_) * across);
        const glm::dvec3 c = glm::cross(start.h0, at.h);
        start.axis = glm::length(c) > 1e-9 ? glm::normalize(c) : anyPerpendicular(start.h0);
        return true;
    }

    /// Lost: a stub and a scar on the parent, fading as the bark grows over it.
    void leaveScar(size_t bi, bool hasParent, const Start& start)
    {
        const GrowthBranch& b = branches_[bi];
        const double since = t_ - b.lost;
        const double fade = 1.0 - smoothstep(0.0, 2.0 * p_.scarYears, since);
        if (hasParent && fade > 0.0) {
            Scar s;
            s.radius = model_.radiusOf(support_[bi]);
            s.base = start.base;
            s.tip = start.base + start.h0 * (start.parentRadius + 0.3 * s.radius * fade);
            s.parent = start.parentId;
            s.weight = smoothstep(0.0, 0.5, since) * fade;
            sk_.scars.push_back(s);
        }
    }

    /// The internodes of branch bi up to its visible length, with their
    /// rings, buds and leaves, and its apical bud while it grows.
    void drawMetamers(size_t bi, bool hasParent, const Start& start)
    {
        const GrowthBranch& b = branches_[bi];
        const double L = grown_[bi];
        const double sTheta = std::min(1.0, L / p_.maxBranchLength);  // eq. 8

        const int m = b.metamers();
        std::vector<double> lengths;
        const std::vector<double> beyond = model_.metamerSupports(bi, t_, support_, lengths);

        // Nodes whose bud has broken into a lateral, and those where it
        // still lives: the skeleton's internodes end there.
        std::vector<bool> broken(size_t(m), false), junction(size_t(m), false);
        for (int c : b.laterals) {
            const GrowthBranch& lb = branches_[size_t(c)];
            broken[size_t(lb.node)] = broken[size_t(lb.node)] || t_ > lb.birth - 1;
            junction[size_t(lb.node)] =
                junction[size_t(lb.node)] || (t_ > lb.birth - 1 && t_ < lb.lost);
        }

        std::vector<NodeFrame>& out = nodes_[bi];
        glm::dvec3 p = start.base;
        double drawn = 0.0;
        Gathering g;
        g.previous = start.parentId;
        const bool growing = b.lastYear() >= year_ && b.lost > year_;
        for (const GrowthShoot& s : b.shoots) {
            const double li = s.length / s.metamers;
            for (int k = 0; k < s.metamers; ++k) {
                const int j = s.firstMetamer + k;
                double len = std::min(lengths[size_t(j)], visible_[bi] - drawn);
                if (len < minLength_)
                    break;
                glm::dvec3 h, across;
                metamerFrame(b, start, hasParent, s.start + (k + 0.5) * li, L, sTheta, h, across);

                Internode in;
                in.p0 = p;
                in.p1 = p + len * h;
                in.r0 = model_.radiusOf(beyond[size_t(j)]);
                in.r1 = model_.radiusOf(beyond[size_t(j) + 1]);
                in.order = b.order;
                in.module = (long long)bi;
                in.age = t_ - (s.year - 1);
                if (!g.open) {
                    g.pending = in;
                    g.pendingFrom = out.size();
                    g.open = true;
                    g.gathered = 0.0;
                    g.pendingFinalRadius = b.finalRadius[size_t(j)];
                } else {
                    g.pending.p1 = in.p1;
                    g.pending.r1 = in.r1;
                }
                g.gathered += li;
                drawn += len;
                out.push_back({in.p1, h, across, in.r1, -1});
                if (junction[size_t(j)] || g.gathered >= 4.0 * g.pendingFinalRadius)
                    flush(g, out);

                // A bud scale scar ring at the base of each shoot but the seedling's first.
                if (k == 0 && (hasParent || s.year > b.birth) && p_.scarRing > 0.0)
                    addScarRing(in, len, h);
                addNodeOrgans(b, s, k, in, h, across, broken[size_t(j)], growing);
                p = in.p1;
            }
        }
        flush(g, out);
        if (growing && p_.budRadius > 0.0 && !out.empty()) {  // the apical bud
            Organ o;
            o.kind = Organ::Kind::Bud;
            o.p0 = p + out.back().h * (0.5 * p_.budRadius);
            o.radius = p_.budRadius;
            o.colour = p_.bark;
            sk_.organs.push_back(o);
        }
    }

    /// The heading `h` of a metamer whose middle is `sNominal` along branch
    /// `b` of length L (eq. 9: towards the parent's direction, and the
    /// seeded variation), and `across`, the reference across it.
    void metamerFrame(const GrowthBranch& b, const Start& start, bool hasParent, double sNominal,
                      double L, double sTheta, glm::dvec3& h, glm::dvec3& across) const
    {
        const double x = std::clamp(sNominal / L, 0.0, 1.0);
        const double theta =
            hasParent ? radians((1.0 - sTheta) * p_.Go1(x) + sTheta * p_.Go2(x)) : 0.0;
        const double n1 = noise_ * (0.6 * std::sin(2 * kPi * sNominal / wave1_ + b.phase[0]) +
                                    0.4 * std::sin(2 * kPi * sNominal / wave2_ + b.phase[1]));
        const double n2 = noise_ * (0.6 * std::sin(2 * kPi * sNominal / wave1_ + b.phase[2]) +
                                    0.4 * std::sin(2 * kPi * sNominal / wave2_ + b.phase[3]));
        h = rotateAbout(start.h0, start.axis, theta + n1);
        across = start.axis;
        const glm::dvec3 yawAxis = glm::normalize(glm::cross(h, start.axis));
        h = glm::normalize(rotateAbout(h, yawAxis, n2));
        across = glm::normalize(rotateAbout(across, yawAxis, n2));
    }

    /// Ends the internode being gathered, if any: into the skeleton, its
    /// metamers' frames naming it.
    void flush(Gathering& g, std::vector<NodeFrame>& out)
    {
        if (!g.open)
            return;
        g.pending.id = (long long)sk_.internodes.size();
        g.pending.parent = g.previous;
        sk_.internodes.push_back(g.pending);
        g.previous = g.pending.id;
        for (size_t k = g.pendingFrom; k < out.size(); ++k)
            out[k].id = g.pending.id;
        g.open = false;
    }

    /// The bud scale scar ring at the base of internode `in` (its first `len`
    /// drawn), fading over scar_years.
    void addScarRing(const Internode& in, double len, const glm::dvec3& h)
    {
        const double w = p_.scarRing * (1.0 - in.age / std::max(p_.scarYears, 1e-9));
        if (w > 1e-3) {
            Organ ring;
            ring.kind = Organ::Kind::Ring;
            ring.p0 = in.p0;
            ring.p1 = in.p0 + std::min(len, in.r0) * h;
            ring.radius = in.r0;
            ring.weight = w;
            ring.colour = barkDark_;
            sk_.organs.push_back(ring);
        }
    }

    /// This year's organs at the node atop metamer k of shoot s (internode
    /// `in`): a leaf and a lateral bud growing; last year's buds that did not
    /// break fade.
    void addNodeOrgans(const GrowthBranch& b, const GrowthShoot& s, int k, const Internode& in,
                       const glm::dvec3& h, const glm::dvec3& across, bool broken, bool growing)
    {
        const int j = s.firstMetamer + k;
        const double az = b.azimuth0 + radians(j * p_.phyllotaxis);
        const glm::dvec3 side = std::cos(az) * across + std::sin(az) * glm::cross(h, across);
        const double grownFor = model_.organTime(s, k, t_);
        double bud = 0.0;
        if (s.year == year_ && growing)
            bud = p_.budRadius * p_.budGrowth(grownFor);
        else if (s.year == year_ - 1 && !broken && b.lost > year_)
            bud = p_.budRadius * (1.0 - u_);
        if (bud > 1e-3 * p_.budRadius) {
            Organ o;
            o.kind = Organ::Kind::Bud;
            o.p0 = in.p1 + side * (in.r1 + 0.5 * bud);
            o.radius = bud;
            o.colour = p_.bark;
            sk_.organs.push_back(o);
        }
        if (leaves_ && p_.leaves && s.year == year_ && growing) {
            const double size =
                p_.Gl(double(k + 1) / s.metamers) * p_.leafGrowth(grownFor) * (1.0 - fall_);
            if (size > 1e-3 * p_.tipRadius) {
                const glm::dvec3 d = glm::normalize(side + 0.5 * h);
                glm::dvec3 up = glm::dvec3(0, 1, 0) - d * d.y;
                Organ o;
                o.kind = Organ::Kind::Leaf;
                o.p0 = in.p1 + d * in.r1;
                o.p1 = o.p0 + d * size;
                o.radius = 0.35 * size;
                o.thickness = 0.12 * size;
                o.normal = glm::length(up) > 1e-6 ? glm::normalize(up) : across;
                o.colour = p_.leaf;
                sk_.organs.push_back(o);
            }
        }
    }

    const GrowthModel& model_;
    const GrowthParameters& p_;
    const std::vector<GrowthBranch>& branches_;
    const bool leaves_;
    const double t_;          ///< growth time
    const double minLength_;  ///< shorter internodes are not drawn
    const std::vector<double> support_;
    std::vector<std::vector<NodeFrame>> nodes_;  ///< each branch's metamer frames, as drawn
    std::vector<double> visible_, grown_;        ///< each branch's length drawn, and grown
    const double alpha_;
    const double wave1_, wave2_;
    const double noise_;
    const int year_;
    const double u_;     ///< growth time within the current year
    const double fall_;  ///< how far the leaves have fallen, in [0, 1]
    const glm::dvec3 barkDark_;
    Skeleton sk_;
};

Skeleton GrowthModel::skeleton(double time, bool leaves) const
{
    return SkeletonDrawer(*this, time, leaves).draw();
}

GrowthStats GrowthModel::stats(double t, bool leaves) const
{
    return stats(t, skeleton(t, leaves));
}

GrowthStats GrowthModel::stats(double t, const Skeleton& sk) const
{
    GrowthStats s;
    s.time = t;
    t = growthTime(t);
    for (const Internode& in : sk.internodes)
        ++s.internodesByOrder[in.order];
    for (const GrowthBranch& b : branches_) {
        if (t <= b.birth - 1)
            continue;
        if (t >= b.lost)
            ++s.lostBranches;
        else
            ++s.branchesByOrder[b.order];
        for (const GrowthShoot& sh : b.shoots)
            if (t > sh.year - 1) {
                ++s.shoots;
                s.shootsAdjusted += sh.metamers != sh.planned;
            }
    }
    for (const Organ& o : sk.organs)
        ++(o.kind == Organ::Kind::Leaf ? s.leaves : o.kind == Organ::Kind::Bud ? s.buds : s.rings);
    s.height = grownLength(0, t);
    return s;
}

}  // namespace cambium
