// cambium — procedural multi-scale details and local edits.
#include "shape/details.h"

#include "core/box.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/hash.h"
#include "core/math.h"
#include "core/random.h"

#include <fmt/format.h>
#include <glm/gtc/noise.hpp>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <queue>
#include <unordered_map>

namespace cambium {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// A double in [0, 1) from (seed, a, b, c), the same everywhere.
double hash01(uint32_t seed, uint64_t a, uint64_t b, uint64_t c = 0)
{
    uint64_t s =
        mix64(mix64(mix64(uint64_t(seed) ^ 0x5eedull) ^ a) ^ (b * 0x9e3779b97f4a7c15ull)) ^ c;
    return splitMix01(s);
}

/// The detail's seeds as vertices of the level they are chosen at: the given
/// points' nearest vertices, or a Poisson-disk set.
std::vector<int> chooseSeeds(const DetailSpec& d, const SubdivLevel& level)
{
    if (!d.at.empty()) {
        std::vector<int> out;
        for (const glm::dvec3& p : d.at)
            out.push_back(nearestVertex(level.subdivided, p));
        return out;
    }
    return poissonDisk(level.subdivided, d.spacing, d.seed);
}

/// The index of level l in the detail's levels, or -1.
int levelIndex(const DetailSpec& d, int l)
{
    const auto it = std::find(d.levels.begin(), d.levels.end(), l);
    return it == d.levels.end() ? -1 : int(it - d.levels.begin());
}

/// Adds a displacement along vertex v's normal, weighted by the detail's
/// displace and scalar weights.
void addNormal(SubdivLevel& level, size_t v, double value, const DetailSpec& d)
{
    level.detail[v].z += d.displace * value;
    level.scalarDetail[v] += d.scalar * value;
}

/// Adds a world-space displacement to vertex v's detail (in its frame).
void addWorld(SubdivLevel& level, size_t v, const glm::dvec3& w, const DetailSpec& spec)
{
    const glm::dvec3 d = level.frames[v].toLocal(w);
    level.detail[v] += spec.displace * d;
    level.scalarDetail[v] += spec.scalar * d.z;
}

// --- rock ------------------------------------------------------------------------

class Rock : public Detail {
public:
    explicit Rock(const DetailSpec& d) : d_(d) {}
    void apply(int l, SubdivLevel& level, const Adjacency&, const VertexMask* mask) override
    {
        const int k = levelIndex(d_, l);
        if (k < 0)
            return;
        forEachIndex(level.vertexCount(), [&](size_t v) {
            if (!wanted(mask, v))
                return;
            const double value =
                d_.perControlPoint
                    ? rockControlValue(int(v), l, k, d_.amplitude, d_.seed)
                    : rockValue(level.subdivided[v], k, d_.amplitude, d_.frequency, d_.seed);
            addNormal(level, v, value, d_);
        });
    }

private:
    DetailSpec d_;
};

// --- berry -----------------------------------------------------------------------

/// The domes a berry's generation may hold (40 bytes each: 400 MB).
constexpr double kMaxBerryDomes = 1e7;

struct Dome {
    glm::dvec3 centre;
    double radius;
    int vertex;  // nearest vertex at its level
};

class Berry : public Detail {
public:
    explicit Berry(const DetailSpec& d) : d_(d) {}
    void apply(int l, SubdivLevel& level, const Adjacency&, const VertexMask* mask) override
    {
        const int k = levelIndex(d_, l);
        if (k < 0)
            return;
        const std::vector<Dome>& domes = generation(k, level);
        // A generation's domes share one radius, and each is centred on a
        // vertex: the seeds on one vertex are one dome (children collect on
        // a few vertices by the thousand).
        const double radius = d_.radius * std::ldexp(1.0, -k);
        std::vector<char> seeded(level.vertexCount(), 0);
        std::vector<glm::dvec3> centres;
        for (const Dome& d : domes)
            if (!seeded[size_t(d.vertex)]) {
                seeded[size_t(d.vertex)] = 1;
                centres.push_back(d.centre);
            }
        const PointTree seeds(centres);
        forEachIndex(level.vertexCount(), [&](size_t v) {
            if (!wanted(mask, v))
                return;
            // The nearest seed (section 4.2.2: each point belongs to one).
            const glm::dvec3 q = level.subdivided[v];
            const int which = seeds.nearest(q, radius);
            if (which >= 0)
                addNormal(level, v, domeHeight(glm::length(q - centres[size_t(which)]), radius),
                          d_);
        });
    }

private:
    /// The seeds of generation k: at the first, the placed seeds; then each
    /// seed's children, scattered in its dome and moved to this level's
    /// nearest vertex, at half the radius.
    std::vector<Dome>& generation(int k, const SubdivLevel& level)
    {
        gens_.resize(size_t(k) + 1);
        std::vector<Dome>& out = gens_[size_t(k)];
        out.clear();
        if (k == 0) {
            for (int v : chooseSeeds(d_, level))
                out.push_back({level.subdivided[size_t(v)], d_.radius, v});
            return out;
        }
        const std::vector<Dome>& parents = gens_[size_t(k) - 1];
        if (double(parents.size()) * d_.children > kMaxBerryDomes)
            throw InputError(fmt::format(
                "{}: {} seeds of {} children each make {:.3g} domes at the berry's level {}, "
                "more than the {:g} a shape holds: a larger spacing or fewer children",
                d_.path, parents.size(), d_.children, double(parents.size()) * d_.children, k + 1,
                kMaxBerryDomes));
        uint64_t stream = mix64(uint64_t(d_.seed) * 7919u + uint64_t(k));
        const PointTree vertices(level.subdivided);
        for (const Dome& parent : parents) {
            const int pv = vertices.nearest(parent.centre);
            const Frame& f = level.frames[size_t(pv)];
            for (int c = 0; c < d_.children; ++c) {
                const double a = 2.0 * kPi * splitMix01(stream);
                const double r = parent.radius * (0.25 + 0.5 * splitMix01(stream));
                const glm::dvec3 p = level.subdivided[size_t(pv)] +
                                     r * (std::cos(a) * f.t + std::sin(a) * f.b) +
                                     f.n * (parent.radius * 0.5);
                const int v = vertices.nearest(p);
                out.push_back({level.subdivided[size_t(v)], parent.radius * 0.5, v});
            }
        }
        return out;
    }

    DetailSpec d_;
    std::vector<std::vector<Dome>> gens_;
};

// --- tentacle --------------------------------------------------------------------

class Tentacle : public Detail {
public:
    explicit Tentacle(const DetailSpec& d) : d_(d) {}
    void apply(int l, SubdivLevel& level, const Adjacency&, const VertexMask*) override
    {
        const int k = levelIndex(d_, l);
        if (k < 0)
            return;
        if (k == 0)  // a vertex keeps its index at finer levels: the seeds correspond
            seeds_ = chooseSeeds(d_, level);
        const glm::dvec3 d = tentacleDetail(d_.length, d_.angle, l);
        for (int v : seeds_) {
            level.detail[size_t(v)] += d_.displace * d;
            level.scalarDetail[size_t(v)] += d_.scalar * d.z;
        }
    }

private:
    DetailSpec d_;
    std::vector<int> seeds_;
};

// --- spur (fig. 10) --------------------------------------------------------------

/// A pointed bump at each seed, radius and height halving per level from
/// the first level's: (1 - s)^2 of s = r / radius.  Control points: r in
/// edge hops times the mean edge length, along each vertex's normal; chart:
/// r on the seed's tangent plane, along the seed's normal.
class Spur : public Detail {
public:
    explicit Spur(const DetailSpec& d) : d_(d) {}
    void apply(int l, SubdivLevel& level, const Adjacency& adj, const VertexMask*) override
    {
        const int k = levelIndex(d_, l);
        if (k < 0)
            return;
        if (k == 0)
            seeds_ = chooseSeeds(d_, level);
        const double scale = std::ldexp(1.0, -(l - 1));
        const double R = d_.radius * scale, H = d_.height * scale;
        for (int s : seeds_) {
            const glm::dvec3 c = level.subdivided[size_t(s)];
            const Frame& fs = level.frames[size_t(s)];
            if (d_.placement == Placement::ControlPoints) {
                const std::vector<double> r = surfaceDistances(level, adj, s, R, true);
                for (size_t v = 0; v < r.size(); ++v)
                    if (r[v] < R)
                        addNormal(level, v, H * spurProfile(r[v] / R), d_);
            } else {
                // The chart: the region around the seed reached through
                // vertices within R on its tangent plane.
                for (int v : chartRegion(level, adj, s, R)) {
                    const glm::dvec3 d = level.subdivided[size_t(v)] - c;
                    const double r = glm::length(d - glm::dot(d, fs.n) * fs.n);
                    if (r < R)
                        addWorld(level, size_t(v), fs.n * (H * spurProfile(r / R)), d_);
                }
            }
        }
    }

    static double spurProfile(double s) { return s < 1.0 ? (1.0 - s) * (1.0 - s) : 0.0; }

    /// Vertices connected to `seed` through vertices whose tangent-plane
    /// distance from it is below R.
    static std::vector<int> chartRegion(const SubdivLevel& level, const Adjacency& adj, int seed,
                                        double R)
    {
        const glm::dvec3 c = level.subdivided[size_t(seed)], n = level.frames[size_t(seed)].n;
        std::vector<int> out{seed}, stack{seed};
        std::unordered_map<int, bool> seen{{seed, true}};
        while (!stack.empty()) {
            const int v = stack.back();
            stack.pop_back();
            for (int i = adj.start[size_t(v)]; i < adj.start[size_t(v) + 1]; ++i) {
                const int w = adj.neighbour[size_t(i)];
                if (seen.count(w))
                    continue;
                seen[w] = true;
                const glm::dvec3 d = level.subdivided[size_t(w)] - c;
                if (glm::length(d - glm::dot(d, n) * n) < R && glm::dot(d, n) > -R) {
                    out.push_back(w);
                    stack.push_back(w);
                }
            }
        }
        return out;
    }

private:
    DetailSpec d_;
    std::vector<int> seeds_;
};

// --- mushroom cloud --------------------------------------------------------------

/// Hybrid morphogenic (section 4.2.4): from each seed, in the seed's own
/// frame (fixed at the first level) and the 3D coordinates around it.  The
/// first half of its levels raise a stem along the seed's normal: a height
/// field over the tangent plane, 1 within 0.6 of the stem radius (a third of
/// `radius`) falling smoothly to 0 at it.  The second half spread a cap:
/// points high on the stem, psi(h) = smoothstep(0.6, 0.95, h / height), move
/// outwards on the tangent plane in proportion to their distance r from the
/// axis, r (1 + 2 share psi), until the cap is three times the stem's width.
/// Each level's share grows with its index (morphogenic).  At one height the
/// spread scales every r alike and a height field has one radius per height,
/// so on a plane the profile stays one simple curve: the surface does not
/// fold onto itself (tests/test_shape.cpp checks it).
class Mushroom : public Detail {
public:
    explicit Mushroom(const DetailSpec& d) : d_(d) {}

    void apply(int l, SubdivLevel& level, const Adjacency&, const VertexMask* mask) override
    {
        const int k = levelIndex(d_, l);
        if (k < 0)
            return;
        if (k == 0) {
            seeds_.clear();
            for (int v : chooseSeeds(d_, level))
                seeds_.push_back({level.subdivided[size_t(v)], level.frames[size_t(v)]});
        }
        const int n = int(d_.levels.size());
        const int stemLevels = std::max(1, (n + 1) / 2), capLevels = n - stemLevels;
        const bool stem = k < stemLevels;
        // Shares proportional to the index within each phase, summing to 1.
        const int j = stem ? k + 1 : k - stemLevels + 1, m = stem ? stemLevels : capLevels;
        const double share = double(j) / (0.5 * m * (m + 1));
        const double R = d_.radius, Rs = R / 3.0, H = d_.height;
        forEachIndex(level.vertexCount(), [&](size_t v) {
            if (!wanted(mask, v))
                return;
            const glm::dvec3 q = level.subdivided[v];
            for (const Seed& s : seeds_) {
                const glm::dvec3 d = q - s.centre;
                const double h = glm::dot(d, s.frame.n);
                const glm::dvec3 radial = d - h * s.frame.n;
                const double r = glm::length(radial);
                if (r >= R || h < -0.5 * R)
                    continue;
                if (stem) {
                    const double b = 1.0 - smoothstep(0.6 * Rs, Rs, r);
                    if (b > 0.0)
                        addWorld(level, v, s.frame.n * (H * share * b), d_);
                } else if (H > 0.0) {
                    const double psi = smoothstep(0.6, 0.95, h / H);
                    if (psi > 0.0)
                        addWorld(level, v, radial * (2.0 * share * psi), d_);
                }
            }
        });
    }

private:
    struct Seed {
        glm::dvec3 centre;
        Frame frame;
    };
    DetailSpec d_;
    std::vector<Seed> seeds_;
};

}  // namespace

Adjacency::Adjacency(const SubdivLevel& level)
{
    const size_t n = level.vertexCount();
    start.assign(n + 1, 0);
    for (const auto& e : level.edges) {
        ++start[size_t(e[0]) + 1];
        ++start[size_t(e[1]) + 1];
    }
    for (size_t v = 0; v < n; ++v)
        start[v + 1] += start[v];
    neighbour.resize(size_t(start[n]));
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (const auto& e : level.edges) {
        neighbour[size_t(fill[size_t(e[0])]++)] = e[1];
        neighbour[size_t(fill[size_t(e[1])]++)] = e[0];
    }
}

std::vector<double> surfaceDistances(const SubdivLevel& level, const Adjacency& adj, int from,
                                     double limit, bool topological)
{
    std::vector<double> dist(level.vertexCount(), kInf);
    using Item = std::pair<double, int>;
    std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
    dist[size_t(from)] = 0.0;
    queue.push({0.0, from});
    while (!queue.empty()) {
        const auto [d, v] = queue.top();
        queue.pop();
        if (d > dist[size_t(v)])
            continue;
        for (int i = adj.start[size_t(v)]; i < adj.start[size_t(v) + 1]; ++i) {
            const int w = adj.neighbour[size_t(i)];
            const double step =
                topological
                    ? level.meanEdgeLength
                    : glm::length(level.subdivided[size_t(w)] - level.subdivided[size_t(v)]);
            const double nd = d + step;
            if (nd < dist[size_t(w)] && nd <= limit) {
                dist[size_t(w)] = nd;
                queue.push({nd, w});
            }
        }
    }
    return dist;
}

PointTree::PointTree(std::vector<glm::dvec3> points)
    : points_(std::move(points)), order_(points_.size()), axis_(points_.size(), 0)
{
    std::iota(order_.begin(), order_.end(), 0);
    build(0, order_.size());
}

void PointTree::build(size_t lo, size_t hi)
{
    if (hi - lo < 2)
        return;
    Box box;
    for (size_t i = lo; i < hi; ++i)
        box.expand(points_[size_t(order_[i])]);
    const glm::dvec3 size = box.size();
    const int axis = size.x >= size.y && size.x >= size.z ? 0 : size.y >= size.z ? 1 : 2;
    const size_t mid = lo + (hi - lo) / 2;
    std::nth_element(order_.begin() + std::ptrdiff_t(lo), order_.begin() + std::ptrdiff_t(mid),
                     order_.begin() + std::ptrdiff_t(hi), [&](int a, int b) {
                         return points_[size_t(a)][axis] < points_[size_t(b)][axis];
                     });
    axis_[mid] = static_cast<unsigned char>(axis);
    build(lo, mid);
    build(mid + 1, hi);
}

void PointTree::search(size_t lo, size_t hi, const glm::dvec3& p, int& best, double& bestD2) const
{
    if (lo >= hi)
        return;
    const size_t mid = lo + (hi - lo) / 2;
    const int id = order_[mid];
    const glm::dvec3& q = points_[size_t(id)];
    const glm::dvec3 e = q - p;
    const double d2 = glm::dot(e, e);
    if (d2 < bestD2 || (d2 == bestD2 && (best < 0 || id < best)))
        best = id, bestD2 = d2;
    if (hi - lo == 1)
        return;
    const int axis = axis_[mid];
    const double along = p[axis] - q[axis];
    // The near side first; the far one while it may hold a point as near
    // (equal too: a tie with a lower index).
    if (along < 0.0) {
        search(lo, mid, p, best, bestD2);
        if (along * along <= bestD2)
            search(mid + 1, hi, p, best, bestD2);
    } else {
        search(mid + 1, hi, p, best, bestD2);
        if (along * along <= bestD2)
            search(lo, mid, p, best, bestD2);
    }
}

int PointTree::nearest(const glm::dvec3& p, double within) const
{
    int best = -1;
    double bestD2 = within * within;
    search(0, order_.size(), p, best, bestD2);
    return best;
}

int nearestVertex(const std::vector<glm::dvec3>& points, const glm::dvec3& p)
{
    int best = 0;
    double bestD = kInf;
    for (size_t i = 0; i < points.size(); ++i) {
        const glm::dvec3 d = points[i] - p;
        const double d2 = glm::dot(d, d);
        if (d2 < bestD)
            bestD = d2, best = int(i);
    }
    return best;
}

std::vector<int> poissonDisk(const std::vector<glm::dvec3>& points, double spacing, uint32_t seed)
{
    std::vector<int> order(points.size());
    std::iota(order.begin(), order.end(), 0);
    uint64_t stream = mix64(uint64_t(seed) ^ 0xd15cull);
    for (size_t i = order.size(); i > 1; --i)  // Fisher-Yates
        std::swap(order[i - 1], order[size_t(splitMix01(stream) * double(i))]);
    PointGrid grid(spacing);
    std::vector<int> out;
    for (int v : order) {
        bool free = true;
        grid.near(points[size_t(v)], spacing, [&](int, const glm::dvec3& q) {
            free = free && glm::length(q - points[size_t(v)]) >= spacing;
        });
        if (free) {
            grid.insert(v, points[size_t(v)]);
            out.push_back(v);
        }
    }
    std::sort(out.begin(), out.end());
    return out;
}

double editDropOff(double s)
{
    if (!(s < 1.0))
        return 0.0;
    s = std::max(s, 0.0);
    return (1.0 - s) * (1.0 - s) * (1.0 + 2.0 * s);
}

double rockValue(const glm::dvec3& p, int k, double amplitude, double frequency, uint32_t seed)
{
    // Each level its own offset into the noise, so that levels are independent.
    const glm::dvec3 offset(97.0 * hash01(seed, uint64_t(k), 1),
                            97.0 * hash01(seed, uint64_t(k), 2),
                            97.0 * hash01(seed, uint64_t(k), 3));
    const double f = std::ldexp(frequency, k);
    const double n = glm::perlin(p * f + offset) / kNoisePeak;
    return std::ldexp(amplitude, -k) * std::clamp(n, -1.0, 1.0);
}

size_t rockFoldsOnAPlane(const DetailSpec& rock, double edge)
{
    ControlMesh plane;
    for (int j = 0; j <= 4; ++j)
        for (int i = 0; i <= 4; ++i)
            plane.points.push_back({edge * i, edge * j, 0.0});
    for (int j = 0; j < 4; ++j)
        for (int i = 0; i < 4; ++i) {
            plane.faceSizes.push_back(4);
            plane.faceVerts.insert(plane.faceVerts.end(), {j * 5 + i, j * 5 + i + 1,
                                                           (j + 1) * 5 + i + 1, (j + 1) * 5 + i});
        }
    const int levels = std::min(rock.levels.back(), 6);
    MultiresSurface s(plane, levels, "probe");
    Rock detail(rock);
    s.synthesize([&](int l, SubdivLevel& lv) {
        std::fill(lv.detail.begin(), lv.detail.end(), glm::dvec3(0.0));
        if (l > 0)
            detail.apply(l, lv, Adjacency(lv), nullptr);
    });
    const SubdivLevel& f = s.finest();
    size_t flipped = 0;
    for (size_t q = 0; q < f.faceCount(); ++q) {
        const int* c = f.faceVerts.data() + f.faceStart[q];
        const glm::dvec3 &a = f.points[size_t(c[0])], &b = f.points[size_t(c[1])],
                         &cc = f.points[size_t(c[2])], &d = f.points[size_t(c[3])];
        flipped += (cc.x - a.x) * (d.y - b.y) - (cc.y - a.y) * (d.x - b.x) <= 0.0;
    }
    return flipped;
}

double rockControlValue(int vertex, int level, int k, double amplitude, uint32_t seed)
{
    return std::ldexp(amplitude, -k) *
           (2.0 * hash01(seed, uint64_t(level), uint64_t(vertex)) - 1.0);
}

glm::dvec3 tentacleDetail(double referenceLength, double theta, int level)
{
    const double magnitude = referenceLength * level, ph = kPi / 3.0 * level;
    glm::dvec3 d(std::sin(theta + ph), std::cos(theta + ph), 1.0);
    if (level % 2 == 0)
        d *= -1.0;  // (the extracted text's "displace *= 1")
    return d * magnitude;
}

double domeHeight(double r, double R)
{
    return r < R ? R * std::sqrt(1.0 - (r * r) / (R * R)) : 0.0;
}

std::unique_ptr<Detail> makeDetail(const DetailSpec& spec)
{
    switch (spec.type) {
        case DetailType::Rock:
            return std::make_unique<Rock>(spec);
        case DetailType::Berry:
            return std::make_unique<Berry>(spec);
        case DetailType::Tentacle:
            return std::make_unique<Tentacle>(spec);
        case DetailType::Mushroom:
            return std::make_unique<Mushroom>(spec);
        case DetailType::Spur:
            return std::make_unique<Spur>(spec);
    }
    return nullptr;
}

void applyEdit(const EditSpec& e, int l, SubdivLevel& level, const Adjacency& adj)
{
    if (std::find(e.levels.begin(), e.levels.end(), l) == e.levels.end() || e.gain == 1.0)
        return;
    const int seed = nearestVertex(level.subdivided, e.at);
    // Distances from the surface point nearest `at`: from its nearest vertex
    // plus that vertex's offset (so that the drop-off does not jump with it).
    const double offset = glm::length(level.subdivided[size_t(seed)] - e.at);
    const std::vector<double> dist =
        surfaceDistances(level, adj, seed, std::max(0.0, e.radius - offset), e.topological);
    for (size_t v = 0; v < dist.size(); ++v) {
        const double d = dist[v] + offset;
        if (!(d < e.radius))
            continue;
        const double g = 1.0 + (e.gain - 1.0) * editDropOff(d / e.radius);
        level.detail[v] *= g;
        level.scalarDetail[v] *= g;
    }
}

}  // namespace cambium
