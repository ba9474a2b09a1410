// cambium — the stages of a bake (bakeLevelSet, bake/levelset.h), one file
// each, and what passes between them.  Internal to src/bake.
//
// clang-format off
//   1. topology        bake/topology.cpp        leaves that can hold band voxels
//   2. values          bake/levelset.cpp        every voxel of those leaves
//                      bake/leaf_cache.cpp      (in sequences: unchanged leaves' values reused)
//   3. neighbours      bake/neighbours.cpp      each leaf's 26 neighbours
//      surface voxels  bake/surface_voxels.cpp  voxels next to a sign change; then their gradients
//   4. propagation     bake/propagation.cpp     surface points swept through the band, tile by
//                                               tile, into distances and leaves (bake/sweep.inc)
//   5. assembly        bake/assembly.cpp        the grids: leaves, flood fill, fog
//   memory estimate    bake/memory_estimate.cpp
// clang-format on
#pragma once

#include "bake/levelset.h"
#include "bake/sampler.h"
#include "bake/topology.h"
#include "core/memory.h"

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

namespace cambium {

/// Leaves sampled per call of the sampler.
constexpr int kBatchLeaves = 4096;

/// A voxel's index in a leaf's values: x + 8 y + 64 z (VDB leaves order x
/// slowest instead: 64 x + 8 y + z).
inline int vox(int x, int y, int z)
{
    return x + 8 * y + 64 * z;
}

/// One key for the node of size 2^log2 holding voxel (x, y, z): its
/// coordinates, 21 bits each.
inline uint64_t nodeKey(int x, int y, int z, int log2)
{
    return (uint64_t(uint32_t(x >> log2) & 0x1FFFFF) << 42) |
           (uint64_t(uint32_t(y >> log2) & 0x1FFFFF) << 21) |
           uint64_t(uint32_t(z >> log2) & 0x1FFFFF);
}

/// Where each run of consecutive leaves inside one cube of 2^shift voxels a
/// side starts, then leaves.size().  The topology lists leaves depth-first
/// within its 128^3 tiles, so each such cube (shift <= 7) is one run.
std::vector<size_t> cubeRuns(const std::vector<LeafJob>& leaves, int shift);

using Progress = std::function<void(const char* stage, double fraction)>;

// --- 2. values ----------------------------------------------------------------

/// Every voxel's F - T (half floats, kLeafVoxels per leaf, in the leaves'
/// order) into `value`, in batches.
void sampleLeafValues(FieldSampler& sampler, const std::vector<LeafJob>& leaves, double h,
                      uint16_t* value, const Progress& progress);

/// The same with a cache: leaves whose canonical program the cache holds for
/// their origin get its values, the rest are sampled; the cache then holds
/// this bake's leaves.  `reused`: how many leaves were not sampled.
void sampleWithReuse(const FieldProgram& program, FieldSampler& sampler, const BandTopology& topo,
                     double h, LeafValueCache& cache, uint16_t* value, size_t& reused,
                     const Progress& progress);

// --- 3. neighbours and surface voxels -------------------------------------------

/// A leaf's neighbours, indexed (dx + 1) + 3 (dy + 1) + 9 (dz + 1) for the
/// leaf at offset (dx, dy, dz) leaves; -1 where there is none.
using LeafNeighbours = std::array<int32_t, 27>;
constexpr int neighbourSlot(int dx, int dy, int dz)
{
    return (dx + 1) + 3 * (dy + 1) + 9 * (dz + 1);
}
/// The six face neighbours' slots.
constexpr int kNeighbourXPlus = neighbourSlot(1, 0, 0), kNeighbourXMinus = neighbourSlot(-1, 0, 0),
              kNeighbourYPlus = neighbourSlot(0, 1, 0), kNeighbourYMinus = neighbourSlot(0, -1, 0),
              kNeighbourZPlus = neighbourSlot(0, 0, 1), kNeighbourZMinus = neighbourSlot(0, 0, -1);
static_assert(kNeighbourXPlus == 14 && kNeighbourXMinus == 12 && kNeighbourYPlus == 16 &&
                  kNeighbourYMinus == 10 && kNeighbourZPlus == 22 && kNeighbourZMinus == 4,
              "the slots of the face neighbours");

/// Every leaf's neighbours, found through the 128^3 tiles the topology
/// grouped the leaves by.
std::vector<LeafNeighbours> findNeighbours(const std::vector<LeafJob>& leaves);

/// The six face directions, in the order of SurfaceEdge::dir.
extern const int kFaceDirections[6][3];

/// A voxel next to a sign change of F - T, with the distance (voxels) to the
/// nearest crossing along its edges and that edge's direction.
struct SurfaceEdge {
    uint16_t voxel;
    uint8_t dir;
    float t;
    float f;  ///< F - T at the voxel, kept so that making the point reads no values
};

/// The surface voxels of all leaves in one array, leaf by leaf in voxel
/// order: leaf l's are [first[l], first[l + 1]).  `queries` ask the sampler
/// for their gradients and colours.
struct SurfaceVoxels {
    std::vector<size_t> first;
    ParallelArray<SurfaceEdge> edges;
    ParallelArray<SurfaceQuery> queries;
    size_t count() const { return first.empty() ? 0 : first.back(); }
};

/// Finds them from the values and neighbours (a missing neighbour leaf, with
/// no surface within a voxel of it, counts as the same side); the time of
/// each step into `timings` (neighbours excluded).
SurfaceVoxels findSurfaceVoxels(const std::vector<LeafJob>& leaves, const uint16_t* value,
                                const std::vector<LeafNeighbours>& nb, BakeTimings& timings);

// --- 4. propagation -------------------------------------------------------------

/// The grid leaves of the band, one slot per topology leaf (null where a
/// leaf has no band voxel; no colour leaves for a model of one colour), and
/// each leaf's count of active voxels.
struct BandLeaves {
    std::vector<openvdb::FloatTree::LeafNodeType*> surface;
    std::vector<openvdb::Vec3fTree::LeafNodeType*> color;
    std::vector<size_t> active;
};

/// The inputs of propagation: the bake's leaves and what stages 2 and 3 found.
struct PropagationInput {
    const std::vector<LeafJob>& leaves;
    const uint16_t* value;
    const std::vector<LeafNeighbours>& nb;
    const SurfaceVoxels& surface;
    const SurfaceSample* samples;  ///< the sampler's answers to surface.queries
    double voxelSize, halfWidth;
    float background;
    bool uniformColor;  ///< one colour everywhere: no colour per point
};

/// Stage 4, tile by tile: each tile's surface points swept through its
/// leaves and a halo, then its signed distances and grid leaves.
BandLeaves propagate(const PropagationInput& in, const Progress& progress, BakeTimings& timings);

// --- 5. assembly ----------------------------------------------------------------

/// The band's half-width in world units, rounded up so that OpenVDB's checks
/// see at least halfWidth voxels.
float bandBackground(double h, double halfWidth);

/// The grids without voxels: names, class, transform.
void createGrids(BakedGrids& out, double h, float background,
                 const openvdb::Vec3f& colourBackground);

/// The band leaves into the grids (which take them over), the tiles above
/// them flood-filled (and the leaves' inactive voxels too unless `leafSigns`:
/// they already hold +-background by their side); counts into the stats, the
/// flood fill's time into timings.floodFill.
void assembleGrids(BakedGrids& out, const BandLeaves& leaves, BakeStats& stats,
                   BakeTimings& timings, bool leafSigns = true);

/// `density`: the level set as OpenVDB's fog volume.
void addFog(BakedGrids& out);

}  // namespace cambium
