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
// Stages 2-4 stream through the topology's slabs (bake/levelset.cpp): values
// and surface voxels a layer of leaves at a time, propagation a slab at a
// time, each a layer or two ahead of the next; a layer's values and surface
// voxels are freed once its neighbours' stages are done with them.
// clang-format on
#pragma once

#include "bake/levelset.h"
#include "bake/sampler.h"
#include "bake/topology.h"
#include "core/memory.h"
#include "io/grids.h"
#include "io/vdb.h"

#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
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

/// Where each run of consecutive leaves [begin, end) inside one cube of
/// 2^shift voxels a side starts, then end.  The topology lists leaves
/// depth-first within its 64^3 cubes, so each such cube (shift <= 6) is one
/// run.
std::vector<size_t> cubeRuns(const std::vector<LeafJob>& leaves, int shift, size_t begin = 0,
                             size_t end = SIZE_MAX);

/// Where each of the topology's slabs (64 voxels thick across `axis`)
/// starts, then leaves.size().
std::vector<size_t> slabRuns(const std::vector<LeafJob>& leaves, int axis);

/// Bytes of the internal nodes of a bake's surface tree (and colour tree,
/// with `colour`) over `leaves` leaves whose origins `origin` gives: 32 KB
/// (colour 64 KB) a node of 128^3 voxels holding any, 256 KB (512 KB) one of
/// 4096^3.  Along a needle they cost more than its leaves: one a 16 leaves.
double internalNodeBytes(size_t leaves, bool colour,
                         const std::function<openvdb::Coord(size_t)>& origin);

using Progress = std::function<void(const char* stage, double fraction)>;

/// A leaf's inside bits (F > T): one 64-bit plane (bit x + 8 y) per z.
using InsideBits = std::array<uint64_t, 8>;

struct SurfacePoint;

/// What the stages have made of each leaf so far.  The bake streams through
/// the topology's slabs, one layer of leaves at a time: a leaf's values and
/// surface voxels are held only while the stages of its own and its
/// neighbouring layers need them (null pointers otherwise).
struct LeafState {
    explicit LeafState(size_t n) : value(n), inside(n), count(n, 0), point(n) {}
    std::vector<const uint16_t*> value;      ///< F - T, kLeafVoxels halves (x + 8 y + 64 z)
    std::vector<InsideBits> inside;          ///< the inside bits of the values
    std::vector<uint32_t> count;             ///< how many surface voxels the leaf has
    std::vector<const SurfacePoint*> point;  ///< their surface points, in voxel order
    size_t surfaceVoxels(size_t l) const { return count[l]; }
};

/// Some of the topology's leaves, by index: a layer of a slab.
struct LeafList {
    const uint32_t* index;
    size_t size;
};

// --- 2. values ----------------------------------------------------------------

/// Every voxel's F - T (half floats, kLeafVoxels per leaf) of the listed
/// leaves into `value`, in their order, in batches.
void sampleLeafValues(FieldSampler& sampler, const std::vector<LeafJob>& leaves, LeafList list,
                      double h, uint16_t* value);

/// The same with a cache: leaves whose canonical program `cache` holds for
/// their origin get its values, the rest are sampled; `next` (a cache with
/// room for every leaf of this bake, see startReuse) collects this bake's.
/// `reused`: how many leaves were not sampled.
void sampleWithReuse(const FieldProgram& program, FieldSampler& sampler, const BandTopology& topo,
                     LeafList list, double h, const LeafValueCache& cache, LeafValueCache& next,
                     uint16_t* value, size_t& reused);

/// An empty cache with room for the topology's leaves; once every leaf's
/// values are in, finishReuse makes it the one a next bake uses.
LeafValueCache startReuse(const BandTopology& topo, double h);
void finishReuse(const BandTopology& topo, LeafValueCache& next, LeafValueCache& cache);

/// The inside bits of the listed leaves from their values.
void findInsideBits(LeafState& state, LeafList list);

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

/// Every leaf's neighbours, found through the 64^3 cubes the topology
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

/// A surface voxel's point on the surface, made once from its edge and the
/// sampler's answer (makeSurfacePoints), with the surface's normal there.
/// IEEE halves: within 2^-10 voxel of where it was computed.
struct SurfacePoint {
    uint16_t n[3];   ///< outward unit normal
    uint16_t at[3];  ///< the point, voxels from the voxel
    uint16_t voxel;  ///< x + 8 y + 64 z
    uint16_t bend;   ///< the lateral offset, voxels, from which its plane gives way
    uint8_t rgb[3];  ///< colour
};

/// The surface voxels of some leaves in one array, leaf by leaf in voxel
/// order (the list's k-th leaf's from first[k]); `queries` ask the sampler
/// for their gradients and colours, its answers go to `samples`; edges and
/// samples become `points`.
struct SurfaceVoxels {
    ParallelArray<SurfaceEdge> edges;
    ParallelArray<SurfaceQuery> queries;
    ParallelArray<SurfaceSample> samples;
    ParallelArray<SurfacePoint> points;
    std::vector<size_t> first;
    size_t count = 0;
};

/// Finds those of the listed leaves from the values and inside bits of the
/// leaves and of their neighbours (a missing neighbour leaf, with no surface
/// within a voxel of it, counts as the same side), and sets their
/// state.count; the time into `timings`.
SurfaceVoxels findSurfaceVoxels(LeafList list, const std::vector<LeafNeighbours>& nb,
                                LeafState& state, BakeTimings& timings);

// --- 4. propagation -------------------------------------------------------------

/// The grid leaves of the band, one slot per topology leaf (null where a
/// leaf has no band voxel; no colour leaves for a model of one colour), and
/// each leaf's count of active voxels.
struct BandLeaves {
    std::vector<openvdb::FloatTree::LeafNodeType*> surface;
    std::vector<openvdb::Vec3fTree::LeafNodeType*> color;
    std::vector<size_t> active;
    /// Packing (BakeOptions::pack): the leaves' buffers go here and the
    /// leaves keep their value masks only, their slot (the topology's leaf
    /// index) in their transient data; `ends` holds whether each leaf's first
    /// (bit 0) and last (bit 1) values are negative, for the flood fill.
    PackedLeaves* surfacePack = nullptr;
    PackedLeaves* colorPack = nullptr;
    std::vector<uint8_t> ends;
    /// Leaves whose colour is one active tile instead (ColourExtent::Shell;
    /// empty, or one slot per leaf).
    std::vector<std::optional<openvdb::Vec3f>> colorTile;
};

/// The inputs of propagation: the bake's leaves and what stages 2 and 3 found.
struct PropagationInput {
    const std::vector<LeafJob>& leaves;
    const std::vector<LeafNeighbours>& nb;
    const LeafState& state;
    double voxelSize, halfWidth;
    float background;
    bool uniformColor;  ///< one colour everywhere (or none kept): no colour per point
    double threshold;   ///< T
    double xT;          ///< w^-1(T): the falloff's argument at the surface (CB_P_XT)
    ColourExtent colour;
};

/// The surface points of the listed leaves (the ones `sv` was found for,
/// with their samples) into sv.points and state.point; frees sv's edges and
/// samples.
void makeSurfacePoints(const PropagationInput& in, LeafList list, SurfaceVoxels& sv,
                       LeafState& state);

/// Stage 4 for leaves [begin, end) (whole 64^3 cubes), tile by tile: each
/// tile's surface points swept through its leaves and a halo (whose surface
/// voxels must be known), then its signed distances and grid leaves into
/// `out` (sized for all leaves).  Times add up in `timings`.
void propagate(const PropagationInput& in, size_t begin, size_t end, BandLeaves& out,
               BakeTimings& timings);

/// A packed leaf's BandLeaves::ends: whether its first (bit 0) and last
/// (bit 1) values, in VDB order, are negative.
inline uint8_t leafEnds(float first, float last)
{
    return uint8_t((first < 0.0f ? 1 : 0) | (last < 0.0f ? 2 : 0));
}

/// A packed leaf (BandLeaves): one with `from`'s value mask and no buffer,
/// its transient data `slot`.
template <class LeafT>
LeafT* maskLeaf(const LeafT& from, const openvdb::Coord& origin,
                const typename LeafT::ValueType& background, uint32_t slot)
{
    auto* leaf = new LeafT(openvdb::PartialCreate(), origin, background, false);
    leaf->getValueMask() = from.getValueMask();
    leaf->setTransientData(slot);
    return leaf;
}

// --- colour shell (bake/colour_shell.cpp) ---------------------------------------

/// The voxels of a leaf (bits x + 8 y of plane z, as InsideBits) that are
/// corners of cells with corners on both sides of the surface: those a
/// trilinear lookup anywhere on the surface reads (ColourExtent::Shell).
/// From the inside bits of the leaf and its neighbours, by neighbourSlot
/// (null: no leaf there; its voxels take the side of the leaf's nearest).
InsideBits colourShell(const InsideBits* const around[27]);

/// The first active value of a colour leaf whose active values all lie
/// within a step of 8-bit colour (1/255) of each other in each channel;
/// none otherwise.
std::optional<openvdb::Vec3f> nearlyUniform(const openvdb::Vec3fTree::LeafNodeType& leaf);

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
