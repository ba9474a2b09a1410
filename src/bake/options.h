// cambium — a bake's options, what it reports and what it is estimated to
// cost: no OpenVDB, for every command that plans or checks a bake
// (bake/levelset.h bakes).
#pragma once

#include "bake/sampler.h"
#include "bake/topology.h"
#include "field/program.h"

#include <array>
#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

namespace cambium {

/// The sampled values of a bake's leaves, keyed by each leaf's origin and a
/// 128-bit hash of its specialised program in canonical form
/// (FieldProgram::canonical): a later bake at the same voxel size given the
/// cache samples only the leaves whose program changed and copies the others'
/// values — the same values a full bake computes, since the same program
/// gives the same samples.  It then holds that bake's leaves (about 1 KB
/// each: the values; the hash instead of the ~0.8 KB canonical program).
struct LeafValueCache {
    double voxelSize = 0.0;
    std::unordered_map<uint64_t, size_t> slot;      ///< packed leaf origin -> entry
    std::vector<std::array<uint64_t, 2>> programs;  ///< hashes of the canonical leaf programs
    std::vector<uint16_t> values;                   ///< 512 per entry
};

/// Where a bake keeps the colour grid `Cd` (bake --colour).
enum class ColourExtent {
    /// The voxels a trilinear lookup anywhere on the surface reads: the
    /// corners of the cells the surface crosses (about half the band at a
    /// half-width of 3), with the band's values; a leaf whose colours there
    /// lie within a step of the bake's 8-bit colours becomes one active tile
    /// of the first of them.
    Shell,
    Band,  ///< every band voxel
    None,  ///< no Cd grid
};
/// "shell", "band" or "none" (InputError naming --colour otherwise), and back.
ColourExtent parseColourExtent(const std::string& name);
const char* colourExtentName(ColourExtent extent);

struct BakeOptions {
    std::string source = "the model";  ///< its file, for messages
    double voxelSize = 0.0;  ///< world units per voxel (must be > 0 here; see autoVoxelSize)
    double halfWidth = 3.0;  ///< narrow-band half-width in voxels
    bool fog = false;        ///< also make a `density` fog volume
    ColourExtent colour = ColourExtent::Shell;
    /// Consecutive layers of leaves (a leaf thick across the slabs) are
    /// sampled together up to this many leaves: fewer sampler calls, a
    /// little more held at once.
    size_t layerGroupLeaves = 4096;
    LeafValueCache* reuse =
        nullptr;  ///< values of unchanged leaves from an earlier bake (sequences)
    /// For writeVdb only: each finished leaf is serialised for the file at
    /// once (stored as halves where `half`) and keeps its value mask only, so
    /// that the bake never holds the grid's values (a third of its memory as
    /// compressed bytes: LevelSetGrids::surfacePacked).  Not with `fog`.
    bool pack = false;
    bool half = false;
    /// One spatial tile of the band (bake --tiles, BandTile): only its
    /// leaves become grid leaves, each exactly the whole bake's.
    BandTile tile;
    /// Called with a stage name and the fraction done; may be called from
    /// several threads at once.
    std::function<void(const char* stage, double fraction)> progress;
    /// When raised (by another thread), the bake stops where it reports its
    /// progress (a tile of the topology search, a layer of leaves) and
    /// throws BakeInterrupted: what a live preview does with a stale bake.
    const std::atomic<bool>* interrupt = nullptr;
};

/// What a bake whose BakeOptions::interrupt was raised throws.
struct BakeInterrupted : std::exception {
    const char* what() const noexcept override { return "the bake was interrupted"; }
};

/// Where a bake's time went, stage by stage (seconds; thread time where
/// noted), for `cambium bake --timings`.
struct BakeTimings {
    double values = 0.0;  ///< sampling every voxel of the candidate leaves
    double neighbours = 0.0, insideBits = 0.0, signChanges = 0.0;  ///< finding the surface voxels
    double surfaceSamples = 0.0;  ///< sampling gradients and colours there
    double surfacePoints = 0.0;   ///< their surface points made from them
    double propagation = 0.0;     ///< propagation and grid leaves, wall time
    double halos = 0.0, points = 0.0, sweeps = 0.0, sweepAxis[3] = {0.0, 0.0, 0.0},
           leaves = 0.0;  ///< thread time
    double freeing = 0.0, tree = 0.0, floodFill = 0.0;
    double startToSampling = 0.0;  ///< process start to the first leaf sampled (processAgeSeconds)
    size_t tiles = 0, tileLeaves = 0;  ///< 64^3 tiles, and their leaves with halos
};

struct BakeStats {
    double voxelSize = 0.0;
    size_t boxesTested = 0;          ///< interval tests during the topology search
    size_t candidateLeaves = 0;      ///< leaves sampled
    size_t activeLeaves = 0;         ///< leaves holding band voxels
    size_t reusedLeaves = 0;         ///< sampled leaves whose values came from BakeOptions::reuse
    size_t activeVoxels = 0;         ///< voxels in the band
    size_t surfacePoints = 0;        ///< voxels next to a sign change (the first layer)
    size_t heldLeaves = 0;           ///< most leaves whose values were held at once (streaming)
    size_t heldSurfacePoints = 0;    ///< most surface points held at once
    double meanProgramLength = 0.0;  ///< instructions per leaf program
    double topologySeconds = 0.0, samplingSeconds = 0.0, assemblySeconds = 0.0, seconds = 0.0;
    BakeTimings timings;
};

/// A voxel size that puts about `voxels` voxels across the largest extent of
/// the surface bounds.
double autoVoxelSize(const FieldProgram& program, double voxels = 512.0);

/// How far out a skeletal primitive's surface lies, in units of its radius,
/// at weight `weight` (sigma its support's width, T the threshold, xT =
/// w^-1(T)): 1 at a weight of 1 and below (counted so: an overestimate), up
/// to its support's reach at large weights (a sphere of radius 0.01, support
/// 60 and weight 1000 has its surface 28 out).
double surfaceRadiusScale(double weight, double sigma, double T, double xT);

/// Estimated voxels within the band at this voxel size, from the
/// primitives' surface area (an overestimate where they overlap).
double estimateBandVoxels(const FieldProgram& program, double voxelSize, double halfWidth);

/// Estimated bytes a bake needs at this voxel size (from the primitives'
/// surface area): used to refuse a voxel size the machine cannot hold.
/// `packed`: the bake packs its leaves (BakeOptions::pack).
double estimateBakeBytes(const FieldProgram& program, double voxelSize, double halfWidth,
                         bool packed);

/// Estimated bytes of the .vdb a bake of these options writes (its
/// compressed leaves), for the check that it fits on the output's disk.
double estimateFileBytes(const FieldProgram& program, double voxelSize, double halfWidth,
                         ColourExtent colour, bool half, bool fog);

/// Rough seconds `cores` take to bake `bandVoxels` estimated band voxels
/// (what a plan reports, never a limit).
double estimateBakeSeconds(double bandVoxels, int cores);

/// Bytes a bake needs at least for the leaves the band's topology search
/// found to sample (a truer count where the primitives' areas miss the
/// surface: sums of flat fields, folding warps).
double estimateBakeBytesFromLeaves(size_t sampledLeaves);

/// Estimated bytes of the two leaf-value caches a sequence's bake holds
/// besides (BakeOptions::reuse: the last frame's and the one being filled,
/// each about 1.1 KB per sampled leaf).
double estimateReuseBytes(const FieldProgram& program, double voxelSize, double halfWidth);

}  // namespace cambium
