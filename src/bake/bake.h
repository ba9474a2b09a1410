// cambium — a bake from a model file to a .vdb file: validation, sampling
// device, level set, output.  What `cambium bake` runs; no OpenVDB here.
#pragma once

#include "bake/options.h"
#include "bake/thicken.h"
#include "blobtree/blobtree.h"
#include "core/system.h"
#include "io/vdb_header.h"
#include "model/load_model.h"

#include <functional>
#include <memory>
#include <optional>
#include <string>

namespace cambium {

struct BakedGrids;  // bake/levelset.h

/// One bake: a model file to one .vdb file.
struct BakeRequest {
    std::string input;                ///< scene, L-system, skeleton or growth parameter file
    ModelOptions model;               ///< how L-systems and skeletons are built
    std::string output;               ///< .vdb path (a sequence: a pattern with a run of '#')
    std::optional<double> voxelSize;  ///< default: 512 voxels across the surface bounds
    double halfWidth = 3.0;           ///< voxels
    /// The smallest radius baked, in voxels: thinner parts are thickened to
    /// it (bake/thicken.h); 0: baked as they are.
    double minRadius = kDefaultMinRadiusVoxels;
    Device device = Device::OpenCL;
    bool fog = false;
    bool half = false;
    ColourExtent colour = ColourExtent::Shell;  ///< where Cd is kept (--colour)
    int threads = 0;                            ///< 0: all cores
    /// A photo whose colours the bark takes (paper 002 section 3.5; the
    /// model's own "bark.photo" when empty), drawn coherently or at random
    /// (the model's choice when unset).
    std::string barkPhoto;
    std::optional<bool> barkCoherent;
    /// One tile of the band (--tile K/N, what --tiles runs): its leaves only,
    /// each exactly the whole bake's (BakeOptions::tile); the memory check
    /// takes the tile's share of the frame's estimate.
    BandTile tile;
    /// Whether the command offers --tiles (the memory check's advice names
    /// it): bake's, not preview's.
    bool tilesOffered = true;
    /// What the command calls the voxel size (the memory check's advice).
    std::string voxelSizeName = "--voxel-size";
    /// Whether a given voxel size was chosen for this very model (a single
    /// bake's --voxel-size, a shape's fine_voxel_size): one larger than the
    /// whole model is refused.  Not where it is inherited: a sequence's
    /// chunk or sampled frames, preview's later models, a tile.
    bool voxelSizeOfThisModel = false;
    /// A farm's key for the file's metadata (`cambium_sequence`): what its
    /// final job checks a tile's file against (farm/slurm.h tileFarmKey).
    std::string key;
};

/// The share of a frame's estimated memory one of `tiles` tiles needs: its
/// part of the leaves (balanced to a 128-voxel layer), its halo and the
/// frame's topology search, taken as 1.5 / tiles.
inline double tileMemoryShare(int tiles)
{
    return tiles > 1 ? 1.5 / tiles : 1.0;
}

/// Whether a bake of `req` serialises its leaves as it makes them
/// (BakeOptions::pack): unless a fog volume or a photo's colours need the
/// values afterwards (a species file's photo is found later: barkPaint).
inline bool packs(const BakeRequest& req)
{
    return !req.fog && req.barkPhoto.empty();
}

/// The bark photo of a bake, read before any work (InputError naming the
/// file), from the request or the model.  `known`: the photo's histogram
/// when the caller has it already (the preview, while the file is the same).
struct BarkPaint {
    std::shared_ptr<const class ColourHistogram> histogram;  ///< none: no photo
    bool coherent = true;
    glm::dvec3 color{0.0};  ///< the bark colour the photo replaces
    std::string photo;
};
BarkPaint barkPaint(const BakeRequest& request, const BlobTree& tree,
                    std::shared_ptr<const class ColourHistogram> known = nullptr);

/// The bake's grids with the bark painted (no-op without a photo), then
/// kept where `colour` says (the painting colours the whole band).
void paintBark(BakedGrids& grids, const BlobTree& tree, const BarkPaint& paint,
               ColourExtent colour);

/// How a bake talks to whoever runs it (the library never prints).
struct BakeCallbacks {
    /// A stage name and the fraction done; may be called from several
    /// threads at once.
    std::function<void(const char*, double)> progress;
    /// Things a user should know that are not errors (thin primitives, stale
    /// temporaries removed, damaged frames baked again), one line each.
    std::function<void(const std::string&)> notice;
};

/// InputError unless the half-width and the smallest radius are valid.
void checkBakeOptions(const BakeRequest& request);

/// The files a bake reads (the model's, modelFiles, and --bark-photo): what
/// no output of it may replace.
std::vector<std::string> bakeInputFiles(const BakeRequest& request);

/// The voxel size of a bake: `request.voxelSize` or 512 voxels across the
/// program's surface bounds.  InputError when the model has no surface, or
/// when the bake would need more memory than the machine has or coordinates
/// beyond OpenVDB's index space.
struct VoxelPlan {
    double voxelSize = 0.0;
    bool automatic = false;
    double extent = 0.0;      ///< largest extent of the surface bounds
    double bytes = 0.0;       ///< estimated memory of one bake
    double bandVoxels = 0.0;  ///< estimated voxels in the band (an overestimate)
    double fileBytes = 0.0;   ///< estimated bytes of the .vdb written
};
/// The smallest voxel size baked: OpenVDB's transforms refuse a voxel whose
/// volume is below 3e-15 (h < 1.44e-5).
constexpr double kMinVoxelSize = 1e-4;
constexpr double kMaxVoxelSize = 1e9;
VoxelPlan planVoxelSize(const FieldProgram& program, const BakeRequest& request);

/// A bake's model made ready at its voxel size: the voxel size planned from
/// `tree` (planVoxelSize), the parts thinner than `request.minRadius` voxels
/// of it thickened in `tree` (thickenThinParts), and the program and plan of
/// the tree so thickened.  What every bake samples (bake, a frame of a
/// sequence, a tile, a preview, a shape's model base).
struct PlannedModel {
    FieldProgram program;
    VoxelPlan plan;
    Thickened thickened;
};
PlannedModel planModel(BlobTree& tree, const BakeRequest& request);

/// InputError naming `input` when a model's surface (`bounds`, its
/// positive bounds) reaches farther from the origin than cambium's
/// coordinates may (kFarthestCoordinate): a bake's, and eval's (a cone to
/// z = 1e300 evaluated to a NaN gradient, exit 0).  The reach.
double checkModelReach(const Box& bounds, const std::string& input);

/// planVoxelSize's checks of a bake of `program` at `voxelSize` alone
/// (InputError naming `what` when it would not fit this machine's memory),
/// and of `held` such bakes' memory at once (a benchmark keeps several
/// methods' grids): what the benchmarks check before they bake.  The plan.
VoxelPlan checkBakeFits(const FieldProgram& program, double voxelSize, const std::string& what,
                        double held = 1.0);

/// The band's options as every command that bakes checks them (bake, shape,
/// preview, and the mesh bake under them): a voxel size from kMinVoxelSize
/// to kMaxVoxelSize, a half-width from 1 to 64 voxels.  InputError naming
/// the option (`name`) and the value.
void checkVoxelSize(double voxelSize, const std::string& name = "--voxel-size");
void checkHalfWidth(double halfWidth, const std::string& name = "--half-width");

/// InputError (`what` first) when `--half` could not hold the band's
/// distances: a half float's largest is 65504 (a band of 3 voxels of 23437.5
/// was written as infinities, exit 0, and mesh and render refused the file).
void checkHalfRange(bool half, double voxelSize, double halfWidth, const std::string& what);

/// The sampler of `device` (an OpenCL failure is named with a hint to use
/// --device cpu).
std::unique_ptr<FieldSampler> makeSampler(Device device);

struct BakeReport {
    BakeStats stats;
    bool autoVoxelSize = false;
    double extent = 0.0;  ///< largest extent of the surface bounds
    double peakMemoryBytes = 0.0;
    std::string device;
};

/// InputError when a bake of `request` found no band voxel (the surface
/// thinner than a voxel everywhere): nothing is written.
void checkSomethingBaked(const BakeStats& stats, const BakeRequest& request);

/// What a bake of `request` writes into its file's metadata, for a model
/// whose iso-value is `threshold` at model time `time` (BlobTree::time).
VdbFileInfo bakeFileInfo(const BakeRequest& request, double threshold, double time);

/// Validates everything first (model, voxel size, memory, output path) and
/// throws InputError naming the problem before any work or output; then
/// bakes and writes.  An OpenCL failure names the problem and suggests
/// --device cpu.
BakeReport runBake(const BakeRequest& request, const BakeCallbacks& callbacks = {});

/// What runBake would do (bake --dry-run): the model read and compiled, its
/// voxel size and estimates, every check runBake makes before it bakes;
/// nothing sampled or written.
VoxelPlan planBake(const BakeRequest& request);

}  // namespace cambium
