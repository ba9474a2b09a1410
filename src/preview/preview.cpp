// cambium — the live preview's session: a model file to a picture, keeping
// what can be kept between pictures.
#include "preview/preview.h"

#include "bake/bake.h"
#include "bake/levelset.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/hash.h"
#include "field/program.h"
#include "io/image_file.h"

#include <fmt/format.h>

namespace cambium {

struct PreviewSession::State {
    std::unique_ptr<FieldSampler> sampler;
    std::unique_ptr<OpenCLMarcher> marcher;  // (Device::OpenCL)
    LeafValueCache cache;                    // the last bake's leaves
    std::optional<double> voxelSize;         // decided by the first good model
    std::optional<Camera> camera;            // framed on the first good model
    uint64_t lastText = 0;                   // the file's text of the last picture
    bool pictured = false;
    size_t pictures = 0;
};

PreviewSession::PreviewSession(PreviewSettings settings)
    : settings_(std::move(settings)), state_(std::make_unique<State>())
{
    checkInputFile(settings_.input, "model");
    checkModelOptions(settings_.model);
    if (settings_.voxelSize && !(*settings_.voxelSize > 0.0))
        throw InputError(
            fmt::format("--voxel-size must be a positive number (got {})", *settings_.voxelSize));
    if (settings_.width < 1 || settings_.height < 1 || settings_.width > 8192 ||
        settings_.height > 8192 || settings_.spp < 1 || settings_.spp > 1024)
        throw InputError(fmt::format(
            "the picture must be 1 to 8192 pixels a side with 1 to 1024 samples a pixel (got {} x "
            "{}, {})",
            settings_.width, settings_.height, settings_.spp));
    checkImageOutput(settings_.output);
    // The camera's spec, before any work.
    parseCamera(settings_.camera, Box(glm::dvec3(0.0), glm::dvec3(1.0)), 1.0);
}

PreviewSession::~PreviewSession() = default;

PreviewUpdate PreviewSession::update(const std::atomic<bool>* interrupt)
{
    PreviewUpdate u;
    State& s = *state_;
    const auto start = Clock::now();
    auto stop = [&] {
        if (interrupt && interrupt->load(std::memory_order_relaxed))
            throw BakeInterrupted();
    };
    try {
        // The file as it is now: unchanged since the last picture, nothing
        // to do (an editor that saves twice, a touch).
        auto t = Clock::now();
        const uint64_t text = fnv1a64(readTextFile(settings_.input, "model"));
        if (s.pictured && text == s.lastText) {
            u.outcome = PreviewUpdate::Outcome::Unchanged;
            u.pictures = s.pictures;
            return u;
        }
        const BlobTree tree = loadModel(settings_.input, settings_.model);
        u.model = secondsSince(t);
        stop();
        t = Clock::now();
        const FieldProgram program = FieldProgram::compile(tree);
        // The voxel size: the first good model's, kept (its memory checked
        // for every model: a grown tree needs more).
        BakeRequest planned;
        planned.input = settings_.input;
        planned.voxelSize = settings_.voxelSize ? settings_.voxelSize : s.voxelSize;
        VoxelPlan plan = planVoxelSize(program, planned);
        if (!planned.voxelSize) {
            planned.voxelSize = plan.extent / kPreviewVoxelsAcross;
            plan = planVoxelSize(program, planned);
        }
        u.compile = secondsSince(t);
        stop();
        t = Clock::now();
        if (!s.sampler)
            s.sampler = makeSampler(settings_.device);
        BakeOptions opt;
        opt.voxelSize = plan.voxelSize;
        opt.reuse = &s.cache;
        opt.interrupt = interrupt;
        const BakedGrids grids = bakeLevelSet(program, *s.sampler, opt);
        u.bake = secondsSince(t);
        u.voxelSize = plan.voxelSize;
        u.leaves = grids.stats.candidateLeaves;
        u.reusedLeaves = grids.stats.reusedLeaves;
        u.activeVoxels = grids.stats.activeVoxels;
        stop();
        t = Clock::now();
        const double aspect = double(settings_.width) / double(settings_.height);
        const Box bounds = activeWorldBounds(*grids.surface);
        if (!s.camera) {
            if (bounds.empty())
                throw InputError(fmt::format(
                    "{}: the surface is thinner than a voxel of {:g} everywhere: nothing to see "
                    "(use a smaller --voxel-size)",
                    settings_.input, plan.voxelSize));
            s.camera = parseCamera(settings_.camera, bounds, aspect);
        }
        RenderImage image;
        if (settings_.renderDevice == Device::Cpu) {
            image = renderLevelSetCpu(*grids.surface, grids.color.get(), *s.camera, settings_.width,
                                      settings_.height, settings_.spp);
        } else {
            if (s.marcher)
                s.marcher->load(*grids.surface, grids.color.get());
            else
                s.marcher = std::make_unique<OpenCLMarcher>(*grids.surface, grids.color.get());
            image = s.marcher->render(*s.camera, settings_.width, settings_.height, settings_.spp);
        }
        u.render = secondsSince(t);
        stop();
        t = Clock::now();
        writeImage(image, settings_.output);
        u.write = secondsSince(t);
        // Kept for the next pictures once one is written.
        s.voxelSize = plan.voxelSize;
        s.lastText = text;
        s.pictured = true;
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
    } catch (const std::exception& e) {
        u.outcome = PreviewUpdate::Outcome::Failed;
        u.error = e.what();
    }
    u.total = secondsSince(start);
    u.pictures = s.pictures;
    return u;
}

}  // namespace cambium
