// cambium — growth frame sequences.
#include "bake/sequence.h"

#include "io/vdb.h"
#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "model/growth.h"
#include "core/clock.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <filesystem>
#include <mutex>
#include <thread>

namespace cambium {

namespace {


uint64_t fnv1a(const std::string& s, uint64_t h = 0xcbf29ce484222325ull)
{
    for (unsigned char c : s) {
        h ^= c;
        h *= 0x100000001b3ull;
    }
    return h;
}

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

}  // namespace

std::string sequenceKey(const BakeRequest& req, const std::string& text, double voxelSize)
{
    const std::string options = fmt::format("h={:.17g} w={:.17g} fps={:.17g} leaves={} fog={} half={}", voxelSize,
                                            req.halfWidth, req.fpsPerYear, req.model.leaves, req.fog, req.half);
    return fmt::format("{:016x}", fnv1a(options, fnv1a(text)));
}

SequenceReport runBakeSequence(const BakeRequest& req, const std::function<void(const FrameReport&)>& done)
{
    const auto start = Clock::now();
    SequenceReport report;
    checkBakeOptions(req);
    checkModelOptions(req.model);
    if (!isGrowthParameterFile(req.input))
        throw InputError(fmt::format("{}: --frames needs a growth parameter file (a .json with \"curves\", "
                                     "docs/growth-format.md)",
                                     req.input));
    checkGrowthOptions(req.input, req.model);
    if (!(std::isfinite(req.fpsPerYear) && req.fpsPerYear > 0.0 && req.fpsPerYear <= 1e6))
        throw InputError(fmt::format("--fps-per-year must be a positive number (got {})", req.fpsPerYear));
    if (!isFramePattern(req.output))
        throw InputError(fmt::format("-o {}: a sequence needs a run of '#' for the frame number, e.g. "
                                     "out/tree.####.vdb",
                                     req.output));
    const std::vector<long long> frames = parseFrames(req.frames);
    const std::string text = readTextFile(req.input, "growth parameter file");
    const GrowthModel model(parseGrowthParameters(text, req.input));
    const int years = model.params().years;
    std::vector<double> times;
    std::vector<std::string> paths;
    for (long long f : frames) {
        const double t = double(f) / req.fpsPerYear;
        if (!(t >= 0.0 && t <= years))
            throw InputError(fmt::format("frame {} is year {:g} at {:g} frames a year, outside the tree's 0 to {} "
                                         "years ({})",
                                         f, t, req.fpsPerYear, years, req.input));
        times.push_back(t);
        paths.push_back(framePath(req.output, f));
        checkOutputPath(paths.back(), paths.size() == 1);
    }

    // The last frame's tree (the largest) sets the voxel size, the same for
    // every frame, and the memory a bake needs.
    const TreeBuildOptions build = model.buildOptions();
    const Skeleton last = model.skeleton(times.back(), req.model.leaves);
    if (last.internodes.empty())
        throw InputError(fmt::format("{}: the tree has not begun to grow by year {:g} (the last frame): nothing "
                                     "to bake",
                                     req.input, times.back()));
    const FieldProgram lastProgram = FieldProgram::compile(buildTree(last, build));
    VoxelPlan plan = planVoxelSize(lastProgram, req);  // one frame must fit; --jobs is capped below
    if (req.model.leaves) {
        // Wood only grows, but leaves come and go within a year: the last
        // year's frames in leaf may need more than the last frame.
        BakeRequest fixed = req;
        fixed.voxelSize = plan.voxelSize;
        const int lastYear = growthYear(times.back());
        for (size_t i = 0; i + 1 < times.size(); ++i)
            if (growthYear(times[i]) == lastYear) {
                const Skeleton sk = model.skeleton(times[i], true);
                if (!sk.internodes.empty())
                    plan.bytes = std::max(plan.bytes,
                                          planVoxelSize(FieldProgram::compile(buildTree(sk, build)), fixed).bytes);
            }
    }
    report.voxelSize = plan.voxelSize;
    report.autoVoxelSize = plan.automatic;
    const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
    const int byMemory = int(std::max(1.0, std::floor(availableMemoryBytes() / std::max(plan.bytes, 1.0))));
    report.jobs = std::max(1, std::min({req.jobs > 0 ? req.jobs : cores, byMemory, int(frames.size())}));
    auto notice = [&](const std::string& line) {
        if (req.notice)
            req.notice(line);
    };

    // One run at a time writes a pattern; temporaries that killed runs left
    // (files appear by rename, so these were never frames) are removed.
    const OutputLock outputLock(req.output);
    for (const std::string& tmp : staleTemporaries(req.output))
        if (std::filesystem::remove(tmp))
            notice(fmt::format("removed {}, a temporary file left by an interrupted run", tmp));

    // Resuming: a finished frame is a whole file with this bake's key; one
    // from another bake is not overwritten silently, a damaged one is baked
    // again.
    const std::string key = sequenceKey(req, text, plan.voxelSize);
    std::vector<bool> finished(frames.size(), false);
    if (req.resume)
        for (size_t i = 0; i < frames.size(); ++i)
            if (std::filesystem::exists(paths[i])) {
                std::string found;
                try {
                    found = readSequenceKey(paths[i]);
                } catch (const InputError& e) {
                    notice(fmt::format("{} (baking it again)", e.what()));
                    continue;
                }
                if (found != key)
                    throw InputError(fmt::format("{} exists from another bake (other parameters or options): remove "
                                                 "it, or bake without --resume to overwrite it",
                                                 paths[i]));
                finished[i] = true;
            }

    const ThreadLimit threads(req.threads);
    report.frames.resize(frames.size());
    const std::vector<std::vector<size_t>> runs = yearRuns(times);
    // One sampler per worker, made here one after the other (making OpenCL
    // contexts from several threads at once fails in the ICD loader).
    std::vector<std::unique_ptr<FieldSampler>> samplers;
    if (std::find(finished.begin(), finished.end(), false) != finished.end())
        for (int k = 0; k < report.jobs; ++k)
            samplers.push_back(makeSampler(req.device));
    report.device = samplers.empty() ? req.device : samplers.front()->name();
    std::atomic<size_t> next{0};
    std::atomic<bool> failed{false};
    std::exception_ptr error;
    std::mutex mutex;
    auto worker = [&](int w) {
        try {
            FieldSampler* sampler = samplers.empty() ? nullptr : samplers[size_t(w)].get();
            LeafValueCache cache;  // the last baked frame's leaves: unchanged ones are not sampled again
            for (size_t r; !failed && (r = next++) < runs.size();) {
                std::optional<FieldProgram> previous;  // the last frame baked in this run
                BakedGrids grids;
                for (size_t i : runs[r]) {
                    if (failed)
                        return;
                    const auto t0 = Clock::now();
                    FrameReport& fr = report.frames[i];
                    fr.frame = frames[i];
                    fr.time = times[i];
                    fr.path = paths[i];
                    if (finished[i]) {
                        fr.outcome = FrameReport::Outcome::Skipped;
                        previous.reset();
                    } else {
                        const Skeleton sk = model.skeleton(times[i], req.model.leaves);
                        BakeOptions opt;
                        opt.voxelSize = plan.voxelSize;
                        opt.halfWidth = req.halfWidth;
                        opt.fog = req.fog;
                        opt.reuse = &cache;
                        if (sk.internodes.empty()) {
                            grids = emptyLevelSet(opt);
                            fr.outcome = FrameReport::Outcome::Empty;
                            previous.reset();
                        } else {
                            FieldProgram program = FieldProgram::compile(buildTree(sk, build));
                            if (previous && previous->identical(program)) {
                                fr.outcome = FrameReport::Outcome::Reused;
                            } else {
                                grids = bakeLevelSet(program, *sampler, opt);
                                fr.outcome = grids.stats.activeVoxels ? FrameReport::Outcome::Baked
                                                                      : FrameReport::Outcome::Empty;
                                previous = std::move(program);
                            }
                        }
                        fr.stats = grids.stats;
                        VdbFileInfo info;
                        info.scene = req.input;
                        info.threshold = lastProgram.threshold();
                        info.halfWidth = req.halfWidth;
                        info.frame = frames[i];
                        info.time = times[i];
                        info.half = req.half;
                        info.sequence = key;
                        writeVdb(grids, paths[i], info);
                    }
                    fr.seconds = secondsSince(t0);
                    if (done) {
                        std::lock_guard<std::mutex> lock(mutex);
                        done(fr);
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

}  // namespace cambium
