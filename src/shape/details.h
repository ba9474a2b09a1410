// cambium — procedural multi-scale detail (paper 004, section 4): each a
// function d = F(p, level) added to a level's details in the local frames of
// the evolving surface, and the surface tools they share (neighbours,
// distances over the surface, Poisson-disk seeds).
#pragma once

#include "shape/shape.h"
#include "subdiv/multires.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

namespace cambium {

/// Points hashed into cubic cells, for the seeds near a point.
class PointGrid {
public:
    explicit PointGrid(double cell) : cell_(cell > 0.0 ? cell : 1.0) {}
    void insert(int id, const glm::dvec3& p)
    {
        cells_[key(cellOf(p))].push_back({id, p});
        ++count_;
    }
    /// f(id, point) for every point in the cells within `radius` of p.
    template <class F>
    void near(const glm::dvec3& p, double radius, const F& f) const
    {
        const glm::ivec3 lo = cellOf(p - glm::dvec3(radius)), hi = cellOf(p + glm::dvec3(radius));
        for (int x = lo.x; x <= hi.x; ++x)
            for (int y = lo.y; y <= hi.y; ++y)
                for (int z = lo.z; z <= hi.z; ++z) {
                    const auto it = cells_.find(key({x, y, z}));
                    if (it != cells_.end())
                        for (const auto& [id, q] : it->second)
                            f(id, q);
                }
    }

    /// The id of the point nearest to p (-1 when empty; ties: the lowest id):
    /// shells of cells searched outwards while they hold fewer cells than
    /// there are points, then every point.
    int nearest(const glm::dvec3& p) const
    {
        int best = -1;
        double bestDistance = 0.0;
        auto consider = [&](int id, const glm::dvec3& q) {
            const double d = glm::length(q - p);
            if (best < 0 || d < bestDistance || (d == bestDistance && id < best))
                best = id, bestDistance = d;
        };
        for (double r = cell_;; r *= 2.0) {
            const double cells = std::pow(2.0 * r / cell_ + 2.0, 3.0);
            if (cells > double(count_)) {
                for (const auto& [k, list] : cells_)
                    for (const auto& [id, q] : list)
                        consider(id, q);
                return best;
            }
            near(p, r, consider);
            if (best >= 0 && bestDistance <= r)
                return best;
        }
    }

private:
    glm::ivec3 cellOf(const glm::dvec3& p) const
    {
        // Clamped before the conversion (out of int's range it is
        // undefined); cells far out share keys, which only adds candidates.
        auto at = [&](double x) { return int(std::clamp(std::floor(x / cell_), -1e9, 1e9)); };
        return glm::ivec3(at(p.x), at(p.y), at(p.z));
    }
    static uint64_t key(const glm::ivec3& c)
    {
        return (uint64_t(uint32_t(c.x) & 0x1FFFFF) << 42) |
               (uint64_t(uint32_t(c.y) & 0x1FFFFF) << 21) | uint64_t(uint32_t(c.z) & 0x1FFFFF);
    }
    double cell_;
    size_t count_ = 0;
    std::unordered_map<uint64_t, std::vector<std::pair<int, glm::dvec3>>> cells_;
};

/// Points in a k-d tree (median splits on the widest axis, built once) for
/// nearest-point queries in about log n steps wherever the query lies: the
/// point a scan of every one finds (ties: the lowest index).  A grid's
/// shells cost the cube of the distance in cells: a berry's children, a
/// dome's radius off the surface, took minutes that way.
class PointTree {
public:
    explicit PointTree(std::vector<glm::dvec3> points);
    /// The index of the point nearest to p no farther than `within` (-1:
    /// none).
    int nearest(const glm::dvec3& p, double within = HUGE_VAL) const;

private:
    void build(size_t lo, size_t hi);
    void search(size_t lo, size_t hi, const glm::dvec3& p, int& best, double& bestD2) const;
    std::vector<glm::dvec3> points_;
    std::vector<int> order_;           ///< the tree: the node of [lo, hi) at its middle
    std::vector<unsigned char> axis_;  ///< each node's split axis
};

/// A level's vertex neighbours (compressed rows from its edges).
struct Adjacency {
    std::vector<int> start, neighbour;
    explicit Adjacency(const SubdivLevel& level);
};

/// Distances over the surface of `level` (its subdivided points Q) from
/// vertex `from`, up to `limit` (beyond: infinity): metric (Dijkstra along
/// the edges) or topological (edge hops times the level's mean edge length).
std::vector<double> surfaceDistances(const SubdivLevel& level, const Adjacency& adjacency, int from,
                                     double limit, bool topological);

/// The vertex of `points` nearest to p.
int nearestVertex(const std::vector<glm::dvec3>& points, const glm::dvec3& p);

/// A maximal Poisson-disk subset of `points`: no two closer than `spacing`,
/// and every point within `spacing` of one of them (dart throwing over all
/// points in an order drawn from `seed`).
std::vector<int> poissonDisk(const std::vector<glm::dvec3>& points, double spacing, uint32_t seed);

/// The local edit's drop-off k(s) = (1 - s)^2 (1 + 2 s) for s in [0, 1], 0
/// beyond: 1 at the point, 0 with zero slope at the radius (C1).
double editDropOff(double s);

/// glm::perlin's largest magnitude, measured over 4 million random points
/// (1.146): the rock's noise is perlin / kNoisePeak, clamped to [-1, 1].
constexpr double kNoisePeak = 1.15;

/// Quads of a plane turned over by a rock detail (seen from above): a
/// plane of 4 x 4 quads `edge` long, subdivided to the detail's last level
/// (at most 6) with the detail alone.  Zero when the detail leaves a plane a
/// height field, which then does not fold onto itself.
size_t rockFoldsOnAPlane(const DetailSpec& rock, double edge);

/// The rock's one-pass noise at p for level index k (0 at its first level):
/// amplitude 2^-k, frequency `frequency` 2^k (1/f), in [-1, 1] scaled.
double rockValue(const glm::dvec3& p, int k, double amplitude, double frequency, uint32_t seed);
/// The rock's two-pass form: a random value in [-amplitude 2^-k, amplitude 2^-k]
/// per control point (vertex index) and level.
double rockControlValue(int vertex, int level, int k, double amplitude, uint32_t seed);

/// The tentacle's detail at a seed for `level` (section 4.2.2): (sin(theta +
/// ph), cos(theta + ph), 1) times reference length * level, ph = (pi / 3)
/// level, negated at even levels.
glm::dvec3 tentacleDetail(double referenceLength, double theta, int level);

/// A dome of radius R at distance r: R (1 - r^2 / R^2)^(1/2), 0 for r >= R.
double domeHeight(double r, double R);

/// The vertices of a level whose details are wanted (a blend side's, where
/// its alpha is not 0): null for all.
using VertexMask = std::vector<uint8_t>;
inline bool wanted(const VertexMask* mask, size_t v)
{
    return !mask || (*mask)[v];
}

/// One detail of a shape, applied level by level during synthesis.
class Detail {
public:
    virtual ~Detail() = default;
    /// Adds its part to level `l`'s detail and scalarDetail (Q and frames are
    /// set) at least at the vertices of `mask` (all when null; elsewhere it
    /// may skip them: their details are not used).  Called for every level,
    /// in order, from the first re-synthesised.
    virtual void apply(int l, SubdivLevel& level, const Adjacency& adjacency,
                       const VertexMask* mask = nullptr) = 0;
};

std::unique_ptr<Detail> makeDetail(const DetailSpec& spec);

/// Scales the details of the edit's levels near its point (section 5.2).
void applyEdit(const EditSpec& edit, int l, SubdivLevel& level, const Adjacency& adjacency);

}  // namespace cambium
