// cambium — the narrow-band topology: which 8^3 leaves of voxels can hold
// voxels within the band, found hierarchically from coarse tiles down with
// interval bounds of the field, each leaf with its specialised program.
#pragma once

#include "bake/sampler.h"
#include "field/program.h"

#include <cstddef>
#include <functional>
#include <limits>
#include <vector>

namespace cambium {

struct BandTopology {
    /// In slabs 64 voxels thick across slabAxis (the box's longest), then
    /// 64^3 cube by cube, depth-first within each cube (deterministic): the
    /// bake streams its stages through the slabs in this order.
    std::vector<LeafJob> leaves;
    int slabAxis = 0;
    /// A tile's bake (BandTile): the leaves it owns lie in [ownedLo, ownedHi)
    /// across slabAxis (index space, multiples of 128); the other leaves are
    /// its halo.  The whole band owns everything.
    long long ownedLo = std::numeric_limits<long long>::min();
    long long ownedHi = std::numeric_limits<long long>::max();
    bool owns(const LeafJob& leaf) const
    {
        return leaf.origin[slabAxis] >= ownedLo && leaf.origin[slabAxis] < ownedHi;
    }
    std::vector<Instr> pool;  ///< the leaves' programs
    size_t boxesTested = 0;   ///< interval evaluations over boxes
};

/// One of `count` tiles of a band (bake --tiles): the leaves the search
/// finds (those a bake samples) are counted per 128-voxel layer across the
/// slab axis (a layer of OpenVDB's internal nodes), and the layers cut into
/// `count` runs of about equal leaves; tile `index` owns its run's leaves
/// and samples a halo of kTileHalo voxels either side, so that its band
/// voxels are exactly those of the whole band's bake.  count 0: the whole
/// band.
struct BandTile {
    int index = 0, count = 0;
};
/// The halo: a tile's surface voxels need their neighbour leaves' values,
/// and its propagation the surface voxels of a leaf beyond its own.
constexpr int kTileHalo = 16;

/// Finds every leaf (origin a multiple of 8, voxel (i, j, k) at (i, j, k) * h)
/// that can contain a voxel within halfWidth voxels of the surface F = T: a
/// leaf is kept when the field's interval over its voxel-centre box grown by
/// halfWidth * h contains T.  Boxes that fail the test are never subdivided,
/// so the work follows the surface, not the volume.  Each leaf's program is
/// specialised to its voxel-centre box.
/// The leaves' programs are counted as they are made: InputError naming
/// `source` once they would take more than half the memory this process had
/// when the search began, or more instructions than a leaf's offset holds
/// (operators over many overlapping children, PCM over 2000 children, keep
/// every child in every leaf's program: its memory grows with children
/// times leaves, which no estimate from the primitives' areas sees).
BandTopology findBandLeaves(const FieldProgram& program, double voxelSize, double halfWidth,
                            const std::function<void(double)>& progress = {}, BandTile tile = {},
                            const std::string& source = "the model");

/// Index-space box (inclusive, leaf-aligned) that the search covers: the
/// field's positive support grown by the band.
void bandIndexBounds(const FieldProgram& program, double voxelSize, double halfWidth,
                     long long lo[3], long long hi[3]);
/// The 128-voxel layers across the slab axis (the box's longest): at most
/// this many BandTiles hold leaves, the others are empty.
long long bandLayers(const FieldProgram& program, double voxelSize, double halfWidth);

}  // namespace cambium
