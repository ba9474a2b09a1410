// cambium — the live preview's session: a model file to a picture, keeping
// what can be kept between pictures.
#include "preview/preview.h"

#include "bake/bake.h"
#include "bake/levelset.h"
#include "use/render.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"
#include "field/program.h"
#include "io/image_file.h"
#include "shape/shape.h"
#include "shape/synthesis.h"
#include "bake/mesh_levelset.h"
#include "model/growth.h"
#include "model/growth_params.h"

#include <fmt/format.h>

#include <algorithm>
#include <new>
#include <cmath>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>

namespace cambium {

struct PreviewSession::State {
    std::unique_ptr<FieldSampler> sampler;
    std::unique_ptr<OpenCLMarcher> marcher;  // (Device::OpenCL)
    LeafValueCache cache;                    // the last bake's leaves
    std::optional<double> voxelSize;         // decided by the first good model
    std::optional<Camera> camera;            // framed on the first good model
    std::optional<BakedGrids> grids;         // the last bake
    // A growth parameter file's grown model (its global phase), kept while
    // the file's text is the same: a new time (the year slider) draws the
    // tree again without growing it again.
    std::optional<GrowthModel> grown;
    uint64_t grownText = 0;
    // --frames: the years baked in the background, for the text they were
    // baked from.
    std::map<uint64_t, BakedGrids> prebaked;
    std::set<uint64_t> unbakeable;  // years of the text whose bake failed
    uint64_t prebakedText = 0;
    double prebakedBytes = 0.0;     // the kept frames' grids
    double framesMemory = 0.0;      // what they may take
    bool prebakeFull = false;       // a frame did not fit: no more for this text
    bool marcherStale = true;       // the marcher holds an older bake
    std::optional<uint64_t> baked;  // its file text and time, when known
    // The model's bark photo (a scene's or growth file's), painted as a bake
    // paints it: its histogram kept while the file's name, size and time
    // are the same.  A photo changed under the same text is baked again
    // (seen at the next update: an edit, a view).
    std::string photoPath, photoStamp;
    std::shared_ptr<const ColourHistogram> photo;
    PreviewView pictured;  // the last picture's view
    size_t pictures = 0;
    mutable std::mutex viewMutex;
    PreviewView view;  // the next update's
};

namespace {

/// A file's name, size and modification time ("" where it cannot be read:
/// it is read again, and its reader names the fault).
std::string fileStamp(const std::string& path)
{
    std::error_code sizeError, timeError;
    const auto size = std::filesystem::file_size(path, sizeError);
    const auto time = std::filesystem::last_write_time(path, timeError);
    if (sizeError || timeError)
        return {};
    return fmt::format("{}\n{}\n{}", path, size, time.time_since_epoch().count());
}

/// The key of a bake: the file's text and the time it was grown to.
uint64_t bakeKey(const std::string& text, const std::optional<double>& time)
{
    return fnv1a64(fmt::format("{}\n{}", time ? fmt::format("{:.17g}", *time) : "last", text));
}

}  // namespace

PreviewSession::PreviewSession(PreviewSettings settings)
    : settings_(std::move(settings)), state_(std::make_unique<State>())
{
    checkInputFile(settings_.input, "model");
    checkModelOptions(settings_.model);
    checkMinRadius(settings_.minRadius);
    if (settings_.voxelSize)
        checkVoxelSize(*settings_.voxelSize);
    checkPicture(settings_.width, settings_.height, settings_.spp);
    checkImageOutput(settings_.output);
    checkOutputIsNoInput(settings_.output, {settings_.input});
    // The camera's spec, before any work.
    parseCamera(settings_.camera, Box(glm::dvec3(0.0), glm::dvec3(1.0)), 1.0);
    state_->view.time = settings_.model.time;
    if (!(settings_.framesMemory >= 0.0) || !std::isfinite(settings_.framesMemory))
        throw InputError(fmt::format("--frames-memory must be a number of GB >= 0 (got {})",
                                     settings_.framesMemory / 1e9));
    state_->framesMemory =
        settings_.framesMemory > 0.0 ? settings_.framesMemory : 0.25 * availableMemoryBytes();
    if (!settings_.frames.empty()) {
        if (!isGrowthParameterFile(settings_.input))
            throw InputError(fmt::format(
                "--frames: {} is not a growth parameter file (frames are years of a grown tree)",
                settings_.input));
        // (A file that does not read now is reported by the first update.)
        std::optional<GrowthParameters> p;
        try {
            p = loadGrowthParameters(settings_.input);
        } catch (const InputError&) {
        }
        for (double year : settings_.frames)
            if (!(year >= 0.0) || (p && year > p->years))
                throw InputError(fmt::format("--frames: {} is not a year of {} (0 to {})", year,
                                             settings_.input, p ? p->years : 0));
    }
}

void PreviewSession::setView(const PreviewView& view)
{
    if (view.time && !(std::isfinite(*view.time) && *view.time >= 0.0))
        throw InputError(
            fmt::format("the time must be a number of years >= 0 (got {})", *view.time));
    if (!std::isfinite(view.azimuth) || !std::isfinite(view.elevation))
        throw InputError(fmt::format("the camera's angles must be finite (got {}, {})",
                                     view.azimuth, view.elevation));
    std::lock_guard<std::mutex> lock(state_->viewMutex);
    state_->view = view;
}

PreviewView PreviewSession::view() const
{
    std::lock_guard<std::mutex> lock(state_->viewMutex);
    return state_->view;
}

PreviewSession::~PreviewSession() = default;

BakedGrids PreviewSession::bakeText(const std::string& text, std::optional<double> time,
                                    const std::atomic<bool>* interrupt, PreviewUpdate& u,
                                    bool& known)
{
    State& s = *state_;
    auto stop = [&] {
        if (interrupt && interrupt->load(std::memory_order_relaxed))
            throw BakeInterrupted();
    };
    auto t = Clock::now();
    ModelOptions options = settings_.model;
    options.time = time;
    known = true;
    std::optional<BlobTree> tree;
    if (looksLikeShapeFile(settings_.input)) {
        // A shape file (paper 004): synthesised from the text read above
        // (at animation time `time`), its mesh baked.
        const ShapeSpec spec = parseShape(
            text, settings_.input, std::filesystem::path(settings_.input).parent_path().string(),
            time.value_or(0.0));
        checkShapeLevels(spec, spec.levels);
        ShapeSurface shape(spec, spec.levels, settings_.device);
        shape.synthesize();
        const TriangleMesh mesh = shape.mesh();
        u.model = secondsSince(t);
        stop();
        t = Clock::now();
        MeshBakeOptions mo;
        mo.voxelSize = settings_.voxelSize ? *settings_.voxelSize
                       : s.voxelSize
                           ? *s.voxelSize
                           : std::max(meshExtent(mesh) / kPreviewVoxelsAcross, kMinVoxelSize);
        BakedGrids grids = bakeMeshLevelSet(mesh, mo, settings_.input);
        u.bake = secondsSince(t);
        return grids;
    }
    if (isGrowthParameterFile(settings_.input)) {
        // (From the text read above: what the picture shows is known.)
        const uint64_t textKey = fnv1a64(text);
        if (!s.grown || s.grownText != textKey) {
            s.grown.reset();
            s.grown.emplace(parseGrowthParameters(text, settings_.input));
            s.grownText = textKey;
            u.regrown = true;
        }
        tree = grownTree(*s.grown, settings_.input, options);
    } else {
        tree = loadModel(settings_.input, options);
        // (The model read the file again: a save in between makes the
        // picture's text unknown, and the next update bakes again.)
        known = readTextFile(settings_.input, "model") == text;
    }
    u.model = secondsSince(t);
    stop();
    t = Clock::now();
    // The voxel size: the first good model's, kept (its memory checked for
    // every model: a grown tree needs more).  Thin parts thickened as a
    // bake's.
    BakeRequest planned;
    planned.input = settings_.input;
    planned.tilesOffered = false;
    planned.minRadius = settings_.minRadius;
    planned.voxelSize = settings_.voxelSize ? settings_.voxelSize : s.voxelSize;
    if (!planned.voxelSize)
        planned.voxelSize =
            planVoxelSize(FieldProgram::compile(*tree, settings_.input), planned).extent /
            kPreviewVoxelsAcross;
    const PlannedModel model = planModel(*tree, planned);
    const FieldProgram& program = model.program;
    const VoxelPlan& plan = model.plan;
    // (its photo read, or refused, before the bake)
    const std::string photo = tree->barkLook().photo;
    const std::string stamp = photo.empty() ? std::string() : fileStamp(photo);
    const BarkPaint paint =
        barkPaint(planned, *tree, !stamp.empty() && stamp == s.photoStamp ? s.photo : nullptr);
    s.photoPath = photo;
    s.photoStamp = stamp;
    s.photo = paint.histogram;
    u.compile = secondsSince(t);
    stop();
    t = Clock::now();
    if (!s.sampler)
        s.sampler = makeSampler(settings_.device);
    BakeOptions opt;
    opt.source = settings_.input;
    opt.voxelSize = plan.voxelSize;
    opt.reuse = &s.cache;
    opt.interrupt = interrupt;
    opt.progress = settings_.progress;
    BakedGrids grids = bakeLevelSet(program, *s.sampler, opt);
    paintBark(grids, *tree, paint, ColourExtent::Shell);
    u.bake = secondsSince(t);
    return grids;
}

/// A photo changed since it was last read: the picture and the frames baked
/// in the background hold its old colours, and are baked again.  Checked
/// before every bake, a background frame's too (it reads the new photo,
/// and the update after it would see no change).
void PreviewSession::forgetStalePhoto()
{
    State& s = *state_;
    if (s.photoPath.empty() || fileStamp(s.photoPath) == s.photoStamp)
        return;
    s.baked.reset();
    s.prebaked.clear();
    s.prebakedText = 0;
    s.prebakedBytes = 0.0;
    s.prebakeFull = false;
}

bool PreviewSession::prebake(const std::atomic<bool>* interrupt)
{
    State& s = *state_;
    // (After the first picture: it decides the voxel size and the camera.)
    if (settings_.frames.empty() || !s.voxelSize || !s.camera)
        return false;
    try {
        forgetStalePhoto();
        const std::string text = readTextFile(settings_.input, "model");
        if (s.prebakedText != fnv1a64(text)) {
            s.prebaked.clear();
            s.unbakeable.clear();
            s.prebakedText = fnv1a64(text);
            s.prebakedBytes = 0.0;
            s.prebakeFull = false;
        }
        if (s.prebakeFull)
            return false;
        for (double year : settings_.frames) {
            const uint64_t key = bakeKey(text, year);
            if (s.prebaked.count(key) || s.unbakeable.count(key))
                continue;
            PreviewUpdate u;
            bool known = true;
            try {
                BakedGrids grids = bakeText(text, year, interrupt, u, known);
                const double bytes = double(grids.surface->memUsage()) +
                                     (grids.color ? double(grids.color->memUsage()) : 0.0);
                if (known && s.prebakedBytes + bytes > s.framesMemory) {
                    // (Kept, it would pass the cap: it and the frames after
                    // it are baked when the slider reaches them.)
                    s.prebakeFull = true;
                    return false;
                }
                if (known) {
                    s.prebaked.emplace(key, std::move(grids));
                    s.prebakedBytes += bytes;
                }
            } catch (const BakeInterrupted&) {
                return false;
            } catch (const std::exception&) {
                // (A year this text cannot make, such as one before the tree
                // begins: the slider's own update says why.  The others go on.)
                s.unbakeable.insert(key);
            }
            return true;
        }
    } catch (const std::exception&) {
        // A file that does not read now: its update says so.
    }
    return false;
}

size_t PreviewSession::prebakedFrames() const
{
    return state_->prebaked.size();
}

double PreviewSession::prebakedBytes() const
{
    return state_->prebakedBytes;
}

bool PreviewSession::prebakeFull() const
{
    return state_->prebakeFull;
}

PreviewUpdate PreviewSession::update(const std::atomic<bool>* interrupt)
{
    PreviewUpdate u;
    State& s = *state_;
    const auto start = Clock::now();
    auto stop = [&] {
        if (interrupt && interrupt->load(std::memory_order_relaxed))
            throw BakeInterrupted();
    };
    u.view = view();
    try {
        // The file as it is now: with the view, the last picture's, nothing
        // to do (an editor that saves twice, a touch).
        auto t = Clock::now();
        const std::string text = readTextFile(settings_.input, "model");
        const uint64_t key = bakeKey(text, u.view.time);
        const bool moved =
            u.view.azimuth != s.pictured.azimuth || u.view.elevation != s.pictured.elevation;
        forgetStalePhoto();
        if (s.grids && s.baked == key && !moved) {
            u.outcome = PreviewUpdate::Outcome::Unchanged;
            u.pictures = s.pictures;
            return u;
        }
        if (!s.grids || s.baked != key) {
            bool known = true;
            BakedGrids grids;
            const auto frame = s.prebaked.find(key);
            if (frame != s.prebaked.end() && s.prebakedText == fnv1a64(text)) {
                // Baked in the background (--frames): nothing to do.
                grids = frame->second;
                u.prebaked = true;
            } else {
                grids = bakeText(text, u.view.time, interrupt, u, known);
            }
            u.leaves = grids.stats.candidateLeaves;
            u.reusedLeaves = grids.stats.reusedLeaves;
            u.activeVoxels = grids.stats.activeVoxels;
            const Box bounds = activeWorldBounds(*grids.surface);
            if (!s.camera) {
                if (bounds.empty())
                    throw InputError(fmt::format(
                        "{}: the surface is thinner than a voxel of {:g} everywhere: nothing to "
                        "see (use a smaller --voxel-size)",
                        settings_.input, grids.stats.voxelSize));
                const double aspect = double(settings_.width) / double(settings_.height);
                s.camera = parseCamera(settings_.camera, bounds, aspect);
            }
            // Kept from here on: the bake is good whatever happens to its
            // picture.
            s.voxelSize = grids.stats.voxelSize;
            s.grids = std::move(grids);
            s.marcherStale = true;
            s.baked = known ? std::optional<uint64_t>(key) : std::nullopt;
            u.rebaked = true;
            stop();
        }
        u.voxelSize = *s.voxelSize;
        t = Clock::now();
        const Camera camera = orbitCamera(*s.camera, u.view.azimuth, u.view.elevation);
        const BakedGrids& grids = *s.grids;
        RenderImage image;
        if (settings_.renderDevice == Device::Cpu) {
            image = renderLevelSetCpu(*grids.surface, grids.color.get(), camera, settings_.width,
                                      settings_.height, settings_.spp);
        } else {
            if (!s.marcher)
                s.marcher = std::make_unique<OpenCLMarcher>(*grids.surface, grids.color.get());
            else if (s.marcherStale)
                s.marcher->load(*grids.surface, grids.color.get());
            s.marcherStale = false;
            image = s.marcher->render(camera, settings_.width, settings_.height, settings_.spp);
        }
        u.render = secondsSince(t);
        stop();
        t = Clock::now();
        // (every picture: an edit may name a photo, or the picture may have
        // become a link to the model; --once wrote over its own model)
        checkOutputIsNoInput(settings_.output, modelFiles(settings_.input));
        writeImage(image, settings_.output);
        u.write = secondsSince(t);
        s.pictured = u.view;
        ++s.pictures;
        u.outcome = PreviewUpdate::Outcome::Rendered;
    } catch (const BakeInterrupted&) {
        // (The leaf cache is the last finished bake's: an interrupted bake
        // replaces it only at its end.)
        u.outcome = PreviewUpdate::Outcome::Interrupted;
    } catch (const InputError& e) {
        u.outcome = PreviewUpdate::Outcome::Failed;
        u.inputError = true;
        u.error = e.what();
    } catch (const std::bad_alloc&) {  // (its what() is "std::bad_alloc")
        u.outcome = PreviewUpdate::Outcome::Failed;
        u.error = "out of memory";
    } catch (const std::exception& e) {
        u.outcome = PreviewUpdate::Outcome::Failed;
        u.error = e.what();
    }
    u.total = secondsSince(start);
    u.pictures = s.pictures;
    return u;
}

}  // namespace cambium
