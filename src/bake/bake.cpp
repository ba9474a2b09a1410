// cambium — the bake command's work.
#include "bake/bake.h"

#include "bake/bark_photo.h"
#include "bake/options.h"

#include "cl/runtime.h"
#include "io/vdb.h"
#include "blobtree/scene_io.h"
#include "core/error.h"
#include "core/files.h"
#include "core/system.h"
#include "core/math.h"

#include <fmt/format.h>

#include <filesystem>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdlib>
#include <exception>
#include <fstream>
#include <future>
#include <limits>
#include <memory>
#include <sys/resource.h>
#include <thread>
#include <unistd.h>

namespace cambium {

void checkVoxelSize(double voxelSize, const std::string& name)
{
    static_assert(kMaxVoxelSize == 1e9, "the message says 1e9");
    if (!(voxelSize >= kMinVoxelSize && voxelSize <= kMaxVoxelSize))
        throw InputError(fmt::format("{} must be a number from {:g} to 1e9 (got {})", name,
                                     kMinVoxelSize, voxelSize));
}

void checkHalfWidth(double halfWidth, const std::string& name)
{
    if (!(halfWidth >= 1.0 && halfWidth <= 64.0))
        throw InputError(
            fmt::format("{} must be between 1 and 64 voxels (got {})", name, halfWidth));
}

void checkBakeOptions(const BakeRequest& req)
{
    checkHalfWidth(req.halfWidth);
    checkMinRadius(req.minRadius);
}

std::vector<std::string> bakeInputFiles(const BakeRequest& req)
{
    std::vector<std::string> files = modelFiles(req.input);
    files.push_back(req.barkPhoto);
    return files;
}

double checkModelReach(const Box& bounds, const std::string& input)
{
    const double far =
        std::max({std::abs(bounds.lo.x), std::abs(bounds.lo.y), std::abs(bounds.lo.z),
                  std::abs(bounds.hi.x), std::abs(bounds.hi.y), std::abs(bounds.hi.z)});
    const glm::dvec3 size = bounds.size();
    if (!std::isfinite(size.x + size.y + size.z) || !std::isfinite(far) ||
        far > kFarthestCoordinate)
        throw InputError(fmt::format(
            "{}: the model reaches {:.3g} from the origin: coordinates or radii this large "
            "cannot be baked or evaluated",
            input, far));
    return far;
}

VoxelPlan planVoxelSize(const FieldProgram& program, const BakeRequest& req)
{
    VoxelPlan plan;
    const Box bounds = program.positiveBounds();
    if (bounds.empty())
        throw InputError(
            fmt::format("{}: the model has no surface: its field is nowhere above the "
                        "threshold (empty scene, or only negative fields)",
                        req.input));
    const glm::dvec3 size = bounds.size();
    plan.extent = std::max({size.x, size.y, size.z});
    const double far = checkModelReach(bounds, req.input);
    if (req.voxelSize) {
        plan.voxelSize = *req.voxelSize;
        checkVoxelSize(plan.voxelSize);
        // (A voxel of 1e9 over the bush baked 7 leaves of nothing, and its
        // mesh had an area of 1e-59, exit 0.)
        if (req.voxelSizeOfThisModel && plan.voxelSize > plan.extent)
            throw InputError(fmt::format(
                "{}: {} {:g} is larger than the whole model, whose field reaches {:.3g} "
                "across: no voxel would resolve its surface (automatic: {:.3g})",
                req.input, req.voxelSizeName, plan.voxelSize, plan.extent, autoVoxelSize(program)));
    } else {
        plan.voxelSize = autoVoxelSize(program);
        plan.automatic = true;
        if (!(plan.voxelSize >= kMinVoxelSize))
            throw InputError(
                fmt::format("{}: the surface is only {:.3g} across: 512 voxels across it would be "
                            "smaller than {:g}; scale the model up",
                            req.input, plan.extent, kMinVoxelSize));
        if (!(plan.voxelSize <= kMaxVoxelSize))
            throw InputError(
                fmt::format("{}: the surface is {:.3g} across: 512 voxels across it would be "
                            "larger than {:g}; scale the model down",
                            req.input, plan.extent, kMaxVoxelSize));
    }
    const double h = plan.voxelSize;
    checkHalfRange(req.half, h, req.halfWidth, req.input);
    // Positions in single precision a fraction of a voxel apart (and well
    // inside OpenVDB's 32-bit index space).
    checkVoxelsFromOrigin(far + req.halfWidth * h, h, fmt::format("{}: the surface", req.input));
    // ... and so in every primitive's and warp's own frame, where the kernels
    // compare (a cone authored at x = 1e5 and moved to the origin baked
    // grooved, its floats 0.008 apart at voxels of 0.003, exit 0; so did a
    // cone inside translations of +1e6 and -1e6).
    checkVoxelsFromOrigin(program.farthestLocal() + req.halfWidth * h, h,
                          fmt::format("{}: a primitive or warp, in its own frame before the "
                                      "transforms above it (in world units),",
                                      req.input));
    // (A species file's bark photo, which the program does not tell, stops
    // the packing too: its frames need about 8 bytes a band voxel more.)
    plan.bytes = estimateBakeBytes(program, h, req.halfWidth, packs(req));
    plan.bandVoxels = estimateBandVoxels(program, h, req.halfWidth);
    plan.fileBytes = estimateFileBytes(program, h, req.halfWidth, req.colour, req.half, req.fog);
    checkMemoryFits(
        plan.bytes * tileMemoryShare(req.tile.count),
        fmt::format("{}: a voxel size of {:g} for a surface {:.4g} across ({:.3g} voxels)",
                    req.input, h, plan.extent, plan.extent / h),
        "use a larger " + req.voxelSizeName +
            (!req.tilesOffered    ? std::string()
             : req.tile.count > 0 ? fmt::format(" or more than {} --tiles", req.tile.count)
                                  : std::string(" or --tiles")));
    return plan;
}

PlannedModel planModel(BlobTree& tree, const BakeRequest& req)
{
    FieldProgram program = FieldProgram::compile(tree, req.input);
    const VoxelPlan plan = planVoxelSize(program, req);
    const Thickened thickened = thickenThinParts(tree, req.minRadius * plan.voxelSize);
    if (thickened.parts == 0)
        return {std::move(program), plan, thickened};
    // The thickened tree's program and estimates, at the voxel size planned.
    BakeRequest fixed = req;
    fixed.voxelSize = plan.voxelSize;
    FieldProgram grown = FieldProgram::compile(tree, req.input);
    VoxelPlan again = planVoxelSize(grown, fixed);
    again.automatic = plan.automatic;
    again.extent = plan.extent;  // (what an automatic voxel size was taken from)
    return {std::move(grown), again, thickened};
}

namespace {

/// The notice of what planModel thickened (empty when nothing was).
std::string thickenedNotice(const Thickened& t, const BakeRequest& req, double h)
{
    if (t.parts == 0)
        return {};
    return fmt::format(
        "{} of {} parts have a radius under {:g} voxels of {:g} (the thinnest: {:.3g}): "
        "thickened to a radius of {:.3g} (or to {:g} times their own where that is less), as a "
        "level set holds no thinner feature (--min-radius 0 bakes them as they are{})",
        formatCount(double(t.parts)), formatCount(double(t.positive)), req.minRadius, h, t.thinnest,
        req.minRadius * h, kMaxThickening,
        t.thinnest / req.minRadius >= kMinVoxelSize
            ? fmt::format("; --voxel-size {:.3g} resolves them", t.thinnest / req.minRadius)
            : std::string());
}

}  // namespace

void checkHalfRange(bool half, double voxelSize, double halfWidth, const std::string& what)
{
    if (half && !(voxelSize * halfWidth <= kLargestHalf))
        throw InputError(fmt::format(
            "{}: --half stores distances as 16-bit floats, at most {:g}, and the band reaches "
            "{:.4g} ({:g} voxels of {:g}): use a smaller --voxel-size or leave out --half",
            what, kLargestHalf, voxelSize * halfWidth, halfWidth, voxelSize));
}

VoxelPlan checkBakeFits(const FieldProgram& program, double voxelSize, const std::string& what,
                        double held)
{
    BakeRequest planned;
    planned.input = what;
    planned.voxelSize = voxelSize;
    planned.tilesOffered = false;
    const VoxelPlan plan = planVoxelSize(program, planned);
    if (held > 1.0)
        checkMemoryFits(held * plan.bytes,
                        fmt::format("{} at voxel size {:g}, {:g} bakes' grids held at once", what,
                                    voxelSize, held),
                        "use a larger voxel size");
    return plan;
}

/// A bake estimated longer than this says how long before it starts.
constexpr double kSayBakeSeconds = 10.0;

BarkPaint barkPaint(const BakeRequest& req, const BlobTree& tree,
                    std::shared_ptr<const ColourHistogram> known)
{
    BarkPaint p;
    const BarkLook& look = tree.barkLook();
    p.photo = req.barkPhoto.empty() ? look.photo : req.barkPhoto;
    p.coherent = req.barkCoherent.value_or(look.coherent);
    p.color = look.color;
    checkOutputIsNoInput(req.output, {p.photo});  // (a scene's or growth file's photo)
    // (a photo that paints nothing was ignored without a word)
    if (!p.photo.empty() && !hasBarkToPaint(tree, p.color))
        throw InputError(fmt::format(
            "{}: the bark photo would paint nothing: no cone or segment of {} has the bark "
            "colour ({:g}, {:g}, {:g}) (a scene names its bark's colour as \"bark\": "
            "{{\"color\": [r, g, b]}})",
            p.photo, req.input, p.color.x, p.color.y, p.color.z));
    if (!p.photo.empty())
        p.histogram =
            known ? std::move(known)
                  : std::make_shared<const ColourHistogram>(ColourHistogram::fromPhoto(p.photo));
    return p;
}

void paintBark(BakedGrids& grids, const BlobTree& tree, const BarkPaint& paint, ColourExtent colour)
{
    if (!paint.histogram || !grids.color)
        return;
    colourBarkFromPhoto(grids, tree, *paint.histogram,
                        paint.coherent ? BarkColouring::Coherent : BarkColouring::Random,
                        paint.color);
    if (colour == ColourExtent::Shell)
        keepColourShell(grids);
}

std::unique_ptr<FieldSampler> makeSampler(Device device)
{
    return device == Device::Cpu ? makeCpuSampler()
                                 : withOpenCLHint("bake", [] { return makeOpenCLSampler(); });
}

void checkSomethingBaked(const BakeStats& stats, const BakeRequest& req)
{
    if (stats.activeVoxels == 0)
        throw InputError(
            fmt::format("{}: the surface is thinner than a voxel of {:g} everywhere: "
                        "nothing to bake (use a smaller --voxel-size)",
                        req.input, stats.voxelSize));
}

VdbFileInfo bakeFileInfo(const BakeRequest& req, double threshold, double time)
{
    VdbFileInfo info;
    info.scene = req.input;
    info.threshold = threshold;
    info.sequence = req.key;
    if (req.tile.count > 0)
        info.part = tilePart(req.tile.index, req.tile.count);
    info.halfWidth = req.halfWidth;
    info.half = req.half;
    info.time = time;
    return info;
}

namespace {

/// A single bake's request: its voxel size is its model's own (a tile's is
/// the whole frame's).
BakeRequest singleBake(const BakeRequest& req)
{
    BakeRequest single = req;
    single.voxelSizeOfThisModel = req.tile.count == 0;
    return single;
}

}  // namespace

VoxelPlan planBake(const BakeRequest& req)
{
    checkBakeOptions(req);
    checkOutputPath(req.output);
    BlobTree tree = loadModel(req.input, req.model);
    barkPaint(req, tree);  // (its photo checked)
    const VoxelPlan plan = planModel(tree, singleBake(req)).plan;
    checkDiskSpace(req.output, plan.fileBytes, req.output);
    return plan;
}

BakeReport runBake(const BakeRequest& req, const BakeCallbacks& callbacks)
{
    BakeReport report;
    checkBakeOptions(req);
    checkOutputPath(req.output);
    // What a killed bake of this file left (its process gone): removed,
    // as a sequence removes its frames' (a tile's are its farm's to keep).
    if (req.tile.count == 0)
        for (const std::string& stale : staleTemporaries(req.output))
            if (std::filesystem::remove(stale) && callbacks.notice)
                callbacks.notice(
                    fmt::format("removed {}, a temporary file left by an interrupted run", stale));
    const ThreadLimit threads(req.threads);
    // The model is read on a thread of its own while this one starts the
    // device (PoCL: its libraries, the device, the programs from cambium's
    // cache; about 0.2 s).  The device starts here, not on that thread:
    // PoCL's first call sets up per-thread state (an alternate signal stack)
    // that must not go away with a short-lived thread.  A bad model is
    // reported before a missing device.
    ModelOptions model = req.model;
    model.progress = callbacks.progress;
    std::future<BlobTree> loading =
        std::async(std::launch::async, [&req, &model] { return loadModel(req.input, model); });
    std::unique_ptr<FieldSampler> sampler;
    std::exception_ptr deviceError;
    try {
        sampler = makeSampler(req.device);
    } catch (...) {
        deviceError = std::current_exception();
    }
    BlobTree tree = loading.get();
    const BarkPaint paint = barkPaint(req, tree);
    // (as it was, for the note on parts thinner than a voxel below)
    const std::optional<BlobTree> asItWas =
        req.minRadius < 0.5 && callbacks.notice ? std::optional<BlobTree>(tree) : std::nullopt;
    const PlannedModel planned = planModel(tree, singleBake(req));
    const FieldProgram& program = planned.program;
    const VoxelPlan& plan = planned.plan;
    // (--tiles bakes one tile a layer at most; a tile beyond that would be
    // empty, written with exit 0)
    if (const long long layers = bandLayers(program, plan.voxelSize, req.halfWidth);
        req.tile.count > layers)
        throw InputError(fmt::format(
            "--tile {}/{}: the frame spans {} layers of 128 voxels across its longest side, and "
            "a tile is a run of them: at most {} tiles",
            req.tile.index + 1, req.tile.count, layers, layers));
    checkDiskSpace(req.output, plan.fileBytes, req.output);
    report.extent = plan.extent;
    report.autoVoxelSize = plan.automatic;
    if (planned.thickened.parts && callbacks.notice)
        callbacks.notice(thickenedNotice(planned.thickened, req, plan.voxelSize));
    // With a smallest radius below half a voxel, parts thinner than a voxel
    // bake as voxel-sized blocks or vanish: say so rather than leave a user
    // puzzling over a cube (counted as thickenThinParts counts, on a copy of
    // the model as it was read).
    if (asItWas) {
        BlobTree copy = *asItWas;
        const Thickened thin = thickenThinParts(copy, 0.5 * plan.voxelSize);
        // (The advice only where it is a voxel size a bake takes.)
        if (thin.parts)
            callbacks.notice(fmt::format(
                "{} of {} parts are thinner than a voxel of {:g} (the thinnest: radius {:.3g}): "
                "they bake as voxel-sized blocks or not at all; --min-radius {:g} thickens them{}",
                formatCount(double(thin.parts)), formatCount(double(thin.positive)), plan.voxelSize,
                thin.thinnest, kDefaultMinRadiusVoxels,
                thin.thinnest / 2.0 >= kMinVoxelSize
                    ? fmt::format(", --voxel-size {:.3g} resolves them", thin.thinnest / 2.0)
                    : fmt::format(" (no voxel size resolves them: the smallest baked is {:g})",
                                  kMinVoxelSize)));
    }
    // A long bake says so before it starts (one of three minutes said
    // nothing until it was done where stderr is not a terminal).
    const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
    if (const double seconds = estimateBakeSeconds(plan.bandVoxels, cores);
        seconds > kSayBakeSeconds && callbacks.notice)
        callbacks.notice(
            fmt::format("baking about {} band voxels: roughly {} on this machine's {} "
                        "cores",
                        formatCount(plan.bandVoxels), formatDuration(seconds), cores));

    if (deviceError)
        std::rethrow_exception(deviceError);
    report.device = sampler->name();

    BakeOptions opt;
    opt.source = req.input;
    opt.voxelSize = plan.voxelSize;
    opt.halfWidth = req.halfWidth;
    opt.fog = req.fog;
    opt.colour = req.colour;
    // The grids only go to the file: each leaf is serialised as it is made
    // (unless the fog or a photo's colours need the values afterwards).
    opt.pack = packs(req) && !paint.histogram;
    opt.half = req.half;
    opt.progress = callbacks.progress;
    opt.tile = req.tile;
    BakedGrids grids = bakeLevelSet(program, *sampler, opt);
    paintBark(grids, tree, paint, req.colour);
    if (req.tile.count == 0)  // (a tile may hold none)
        checkSomethingBaked(grids.stats, req);
    writeVdb(grids, req.output, bakeFileInfo(req, tree.threshold(), tree.time()));
    report.stats = grids.stats;
    report.peakMemoryBytes = peakMemoryBytes();
    return report;
}

}  // namespace cambium
