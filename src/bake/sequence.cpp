// cambium — growth frame sequences.
#include "bake/sequence.h"

#include "bake/levelset.h"
#include "core/hash.h"
#include "core/system.h"
#include "io/vdb.h"
#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "model/growth.h"
#include "model/growth_params.h"
#include "core/clock.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <filesystem>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

namespace cambium {

void checkFpsPerYear(double fpsPerYear)
{
    if (!(std::isfinite(fpsPerYear) && fpsPerYear > 0.0 && fpsPerYear <= 1e6))
        throw InputError(fmt::format(
            "--fps-per-year must be a positive number of at most 1e6 (got {})", fpsPerYear));
}

namespace {

/// Frames in runs of one growth year: a worker takes a run and bakes it in
/// order, so that a dormant frame finds its predecessor's grids.
std::vector<std::vector<size_t>> yearRuns(const std::vector<double>& times)
{
    std::vector<std::vector<size_t>> runs;
    int year = -1;
    for (size_t i = 0; i < times.size(); ++i) {
        const int y = growthYear(times[i]);
        if (runs.empty() || y != year)
            runs.emplace_back();
        runs.back().push_back(i);
        year = y;
    }
    return runs;
}

/// Frames the plan estimates at most (memory of the last year's, files).
constexpr size_t kSampledFrames = 64;

/// The sum over the frames from at.front() to at.back() of a value known at
/// the sorted indices `at`, linear between them.
double sumOverFrames(const std::vector<size_t>& at, const std::vector<double>& values)
{
    if (at.empty())
        return 0.0;
    double sum = values.front();
    for (size_t k = 1; k < at.size(); ++k) {
        const double span = double(at[k] - at[k - 1]);
        // (the frames after at[k-1] up to at[k]: a trapezoid's share)
        sum += span * 0.5 * (values[k - 1] + values[k]) + 0.5 * (values[k] - values[k - 1]);
    }
    return sum;
}

}  // namespace

std::vector<std::string> sequencePaths(const std::string& pattern,
                                       const std::vector<long long>& frames, const char* example,
                                       const std::vector<std::string>& inputs)
{
    if (!isFramePattern(pattern))
        throw InputError(
            fmt::format("-o {}: a sequence needs a run of '#' for the frame number, e.g. {}",
                        pattern, example));
    std::vector<std::string> paths;
    for (long long f : frames) {
        paths.push_back(framePath(pattern, f));
        checkOutputPath(paths.back(), paths.size() == 1);
    }
    checkSequenceTargets(paths, inputs);
    return paths;
}

std::string sequenceKeyOf(const std::string& text, const std::string& options,
                          const std::vector<std::string>& files)
{
    return fmt::format("{:016x}", fnv1a64(filesContentKey(files), fnv1a64(options, fnv1a64(text))));
}

std::string sequenceKey(const SequenceRequest& req, const std::string& text, double voxelSize)
{
    const std::string options = fmt::format(
        "h={:.17g} w={:.17g} fps={:.17g} leaves={} fog={} half={} photo={} coherent={} colour={}"
        " min_radius={:.17g}",
        voxelSize, req.bake.halfWidth, req.fpsPerYear, req.bake.model.leaves, req.bake.fog,
        req.bake.half, req.bake.barkPhoto, req.bake.barkCoherent ? int(*req.bake.barkCoherent) : -1,
        colourExtentName(req.bake.colour), req.bake.minRadius);
    // (the photos' bytes too: a repainted photo makes other frames)
    return sequenceKeyOf(text, options,
                         {req.bake.barkPhoto, loadGrowthParameters(req.bake.input).barkPhoto});
}

BlobTree frameTree(const GrowthModel& model, const Skeleton& sk, double minRadius, double voxelSize)
{
    BlobTree tree = buildTree(sk, model.buildOptions());
    thickenThinParts(tree, minRadius * voxelSize);
    return tree;
}

SequencePlan planSequence(const SequenceRequest& request)
{
    SequencePlan plan;
    plan.request = request;
    const BakeRequest& req = request.bake;
    checkBakeOptions(req);
    checkModelOptions(req.model);
    if (!isGrowthParameterFile(req.input))
        throw InputError(
            fmt::format("{}: --frames needs a growth parameter file (a .json with \"curves\", "
                        "docs/growth-format.md)",
                        req.input));
    checkGrowthOptions(req.input, req.model);
    checkFpsPerYear(request.fpsPerYear);
    plan.frames = parseFrames(request.frames);
    plan.paths = sequencePaths(req.output, plan.frames, "out/tree.####.vdb", bakeInputFiles(req));
    const std::string text = readTextFile(req.input, "growth parameter file");
    plan.model = std::make_shared<const GrowthModel>(parseGrowthParameters(text, req.input));
    const GrowthModel& model = *plan.model;
    const int years = model.params().years;
    for (long long f : plan.frames) {
        const double t = double(f) / request.fpsPerYear;
        if (!(t >= 0.0 && t <= years))
            throw InputError(fmt::format(
                "frame {} is year {:g} at {:g} frames a year, outside the tree's 0 to {} "
                "years ({})",
                f, t, request.fpsPerYear, years, req.input));
        plan.times.push_back(t);
    }

    // The last frame's tree (the largest) sets the voxel size, the same for
    // every frame, and the memory a bake needs.
    const TreeBuildOptions build = model.buildOptions();
    const Skeleton last = model.skeleton(plan.times.back(), req.model.leaves);
    if (last.internodes.empty())
        throw InputError(
            fmt::format("{}: the tree has not begun to grow by year {:g} (the last frame): nothing "
                        "to bake",
                        req.input, plan.times.back()));
    BlobTree lastTree = buildTree(last, build);
    plan.paint = barkPaint(req, lastTree);
    PlannedModel planned =
        planModel(lastTree, req);  // one frame must fit; --jobs is capped by memory
    const FieldProgram& lastProgram = planned.program;
    VoxelPlan& voxels = planned.plan;
    BakeRequest fixed = req;
    fixed.voxelSize = voxels.voxelSize;
    // Every frame's tree as a frame's bake makes it (its thin parts thickened).
    const auto frameProgram = [&](const Skeleton& sk) {
        return FieldProgram::compile(frameTree(model, sk, req.minRadius, voxels.voxelSize),
                                     req.input);
    };
    if (req.model.leaves) {
        // Wood only grows, but leaves come and go within a year: the last
        // year's frames in leaf may need more than the last frame.  (At
        // most kSampledFrames of them, evenly spread: a million frames a
        // year must not make the plan take minutes.)
        const int lastYear = growthYear(plan.times.back());
        std::vector<size_t> lastYears;
        for (size_t i = 0; i + 1 < plan.times.size(); ++i)
            if (growthYear(plan.times[i]) == lastYear)
                lastYears.push_back(i);
        for (size_t i : spreadIndices(lastYears.size(), kSampledFrames)) {
            const Skeleton sk = model.skeleton(plan.times[lastYears[i]], true);
            if (!sk.internodes.empty())
                voxels.bytes = std::max(voxels.bytes, planVoxelSize(frameProgram(sk), fixed).bytes);
        }
    }
    // The files: estimated at up to kSampledFrames frames spread over the
    // sequence, linear between them; all must fit on the output's disk.
    const std::vector<size_t> sampled = spreadIndices(plan.times.size(), kSampledFrames);
    std::vector<double> fileAt, bandAt;
    for (size_t i : sampled) {
        const Skeleton sk = model.skeleton(plan.times[i], req.model.leaves);
        if (sk.internodes.empty()) {
            fileAt.push_back(4096.0);  // (an empty grid's file)
            bandAt.push_back(0.0);
            continue;
        }
        const FieldProgram p = frameProgram(sk);
        fileAt.push_back(
            estimateFileBytes(p, voxels.voxelSize, req.halfWidth, req.colour, req.half, req.fog));
        bandAt.push_back(estimateBandVoxels(p, voxels.voxelSize, req.halfWidth));
    }
    plan.fileBytes = sumOverFrames(sampled, fileAt);
    plan.bandVoxels = sumOverFrames(sampled, bandAt);
    const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
    checkDiskSpace(req.output, plan.fileBytes,
                   fmt::format("{} frames of {} (roughly {} of baking here)",
                               formatCount(double(plan.frames.size())), req.output,
                               formatDuration(estimateBakeSeconds(plan.bandVoxels, cores))));
    plan.voxelSize = voxels.voxelSize;
    plan.autoVoxelSize = voxels.automatic;
    plan.bytesPerFrame =  // each worker also holds the caches of unchanged leaves' values
        voxels.bytes + estimateReuseBytes(lastProgram, voxels.voxelSize, req.halfWidth);
    plan.threshold = lastProgram.threshold();
    plan.groups = yearRuns(plan.times);
    plan.key = sequenceKey(request, text, plan.voxelSize);
    return plan;
}

SequenceOutput::SequenceOutput(const std::string& pattern, const std::vector<long long>& frames,
                               const std::vector<std::string>& paths, size_t first, size_t last,
                               const std::string& key, bool resume,
                               const std::function<void(const std::string&)>& notice)
    : lock_(pattern, frames[first], frames[last - 1]),
      finished_(paths.size(), false),
      first_(first),
      last_(last)
{
    // Temporaries that killed runs left (files appear by rename, so these
    // were never frames), only the range's own: another range's may be in
    // flight in another process (or thread).
    std::set<std::string> range;  // the frames' file names (all in the pattern's directory)
    for (size_t i = first; i < last; ++i)
        range.insert(std::filesystem::path(paths[i]).filename().string());
    for (const std::string& tmp : staleTemporaries(pattern)) {
        const std::string name = std::filesystem::path(tmp).filename().string();
        if (range.count(temporaryTarget(name)) && std::filesystem::remove(tmp))
            notice(fmt::format("removed {}, a temporary file left by an interrupted run", tmp));
    }
    // With --resume: a whole file with this sequence's key, every byte as
    // its checksum says, is finished; one from another bake is not
    // overwritten silently, a damaged one is baked again.
    if (!resume)
        return;
    for (size_t i = first; i < last; ++i)
        if (std::filesystem::exists(paths[i])) {
            FileStamp found;
            try {
                found = readFileStamp(paths[i]);
            } catch (const InputError& e) {
                notice(fmt::format("{} (baking it again)", e.what()));
                continue;
            }
            if (found.key != key)
                throw InputError(
                    fmt::format("{} exists from another bake (other parameters or options): remove "
                                "it, or bake without --resume to overwrite it",
                                paths[i]));
            if (!found.part.empty() && found.part != framePart(frames[i])) {
                // (This sequence's file, but another frame's: copied over it.)
                notice(fmt::format("{} holds {} of this sequence, not frame {} (baking it again)",
                                   paths[i], found.part, frames[i]));
                continue;
            }
            // Its bytes, once it is this frame's (a frame with one byte
            // changed was kept through every retry of a farm, sweep 20).
            try {
                readFileStamp(paths[i], /*verify=*/true);
            } catch (const InputError& e) {
                notice(fmt::format("{} (baking it again)", e.what()));
                continue;
            }
            finished_[i] = true;
        }
}

bool SequenceOutput::allFinished() const
{
    for (size_t i = first_; i < last_; ++i)
        if (!finished_[i])
            return false;
    return true;
}

namespace {

/// One worker's state between the frames of a reuse group.
struct FrameBaker {
    const SequencePlan& plan;
    FieldSampler* sampler;
    LeafValueCache cache;  // the last baked frame's leaves: unchanged ones are not sampled again
    std::optional<FieldProgram> previous;  // the last frame baked in this group
    BakedGrids grids;

    /// Bakes (or reuses) frame i and writes its file.
    void bake(size_t i, FrameReport& fr)
    {
        const BakeRequest& req = plan.request.bake;
        const Skeleton sk = plan.model->skeleton(plan.times[i], req.model.leaves);
        BakeOptions opt;
        opt.source = req.input;
        opt.voxelSize = plan.voxelSize;
        opt.halfWidth = req.halfWidth;
        opt.fog = req.fog;
        opt.colour = req.colour;
        opt.pack = packs(req) && !plan.paint.histogram;
        opt.half = req.half;
        opt.reuse = &cache;
        if (sk.internodes.empty()) {
            grids = emptyLevelSet(opt);
            fr.outcome = FrameReport::Outcome::Empty;
            previous.reset();
        } else {
            const BlobTree tree = frameTree(*plan.model, sk, req.minRadius, plan.voxelSize);
            FieldProgram program = FieldProgram::compile(tree);
            if (previous && previous->identical(program)) {
                fr.outcome = FrameReport::Outcome::Reused;
            } else {
                grids = bakeLevelSet(program, *sampler, opt);
                paintBark(grids, tree, plan.paint, req.colour);
                fr.outcome = grids.stats.activeVoxels ? FrameReport::Outcome::Baked
                                                      : FrameReport::Outcome::Empty;
                previous = std::move(program);
            }
        }
        fr.stats = grids.stats;
        VdbFileInfo info = bakeFileInfo(req, plan.threshold, plan.times[i]);
        info.frame = plan.frames[i];
        info.sequence = plan.key;
        info.part = framePart(plan.frames[i]);
        writeVdb(grids, plan.paths[i], info);
    }
};

}  // namespace

int sequenceJobs(const SequencePlan& plan, size_t frames)
{
    const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
    const int byMemory =
        int(std::max(1.0, std::floor(availableMemoryBytes() / std::max(plan.bytesPerFrame, 1.0))));
    const int asked = plan.request.jobs > 0 ? plan.request.jobs : cores;
    return std::max(1, int(std::min<size_t>(size_t(std::min(asked, byMemory)), frames)));
}

SequenceReport runSequence(const SequencePlan& plan, size_t first, size_t last,
                           const SequenceCallbacks& callbacks)
{
    const auto start = Clock::now();
    if (!(first < last && last <= plan.frames.size()))
        throw InputError(fmt::format("frames [{}, {}) are not a range of the plan's {} frames",
                                     first, last, plan.frames.size()));
    const SequenceRequest& request = plan.request;
    const BakeRequest& req = request.bake;
    SequenceReport report;
    report.voxelSize = plan.voxelSize;
    report.autoVoxelSize = plan.autoVoxelSize;
    report.jobs = sequenceJobs(plan, last - first);
    auto notice = [&](const std::string& line) {
        if (callbacks.notice)
            callbacks.notice(line);
    };

    const SequenceOutput output(req.output, plan.frames, plan.paths, first, last, plan.key,
                                request.resume, notice);
    const ThreadLimit threads(req.threads);
    report.frames.resize(last - first);
    std::vector<std::vector<size_t>> groups;  // the plan's groups within the range
    for (const std::vector<size_t>& g : plan.groups) {
        std::vector<size_t> in;
        for (size_t i : g)
            if (i >= first && i < last)
                in.push_back(i);
        if (!in.empty())
            groups.push_back(std::move(in));
    }
    // One sampler per worker, made here one after the other (making OpenCL
    // contexts from several threads at once fails in the ICD loader).
    std::vector<std::unique_ptr<FieldSampler>> samplers;
    if (!output.allFinished())
        for (int k = 0; k < report.jobs; ++k)
            samplers.push_back(makeSampler(req.device));
    report.device = samplers.empty() ? deviceName(req.device) : samplers.front()->name();
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    std::exception_ptr error;
    std::mutex mutex;
    auto worker = [&](int w) {
        try {
            FrameBaker baker{
                plan, samplers.empty() ? nullptr : samplers[size_t(w)].get(), {}, {}, {}};
            for (size_t r; !failed && (r = next++) < groups.size();) {
                baker.previous.reset();
                baker.grids = {};  // (the last group's grids are not kept through this one)
                for (size_t i : groups[r]) {
                    if (failed)
                        return;
                    const auto t0 = Clock::now();
                    FrameReport& fr = report.frames[i - first];
                    fr.frame = plan.frames[i];
                    fr.time = plan.times[i];
                    fr.path = plan.paths[i];
                    if (output.finished(i)) {
                        fr.outcome = FrameReport::Outcome::Skipped;
                        baker.previous.reset();
                    } else {
                        baker.bake(i, fr);
                    }
                    fr.seconds = secondsSince(t0);
                    if (callbacks.done) {
                        std::lock_guard<std::mutex> lock(mutex);
                        callbacks.done(fr);
                    }
                }
            }
        } catch (...) {
            std::lock_guard<std::mutex> lock(mutex);
            if (!error)
                error = std::current_exception();
            failed = true;
        }
    };
    std::vector<std::thread> pool;
    for (int k = 1; k < report.jobs; ++k)
        pool.emplace_back(worker, k);
    worker(0);
    for (std::thread& th : pool)
        th.join();
    if (error)
        std::rethrow_exception(error);
    report.seconds = secondsSince(start);
    report.peakMemoryBytes = peakMemoryBytes();
    return report;
}

SequenceReport bakeSequence(const SequenceRequest& request, const SequenceCallbacks& callbacks)
{
    const auto start = Clock::now();
    const SequencePlan plan = planSequence(request);
    SequenceReport report = runSequence(plan, 0, plan.frames.size(), callbacks);
    report.seconds = secondsSince(start);
    return report;
}

}  // namespace cambium
