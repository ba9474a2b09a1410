// cambium — procedural multi-scale detail (paper 004, section 4): each a
// function d = F(p, level) added to a level's details in the local frames of
// the evolving surface, and the surface tools they share (neighbours,
// distances over the surface, Poisson-disk seeds).
#pragma once

#include "shape/shape.h"
#include "subdiv/multires.h"

#include <memory>
#include <vector>

namespace cambium {

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

/// One detail of a shape, applied level by level during synthesis.
class Detail {
public:
    virtual ~Detail() = default;
    /// Adds its part to level `l`'s detail and scalarDetail (Q and frames are
    /// set).  Called for every level, in order, from the first re-synthesised.
    virtual void apply(int l, SubdivLevel& level, const Adjacency& adjacency) = 0;
};

std::unique_ptr<Detail> makeDetail(const DetailSpec& spec);

/// Scales the details of the edit's levels near its point (section 5.2).
void applyEdit(const EditSpec& edit, int l, SubdivLevel& level, const Adjacency& adjacency);

}  // namespace cambium
