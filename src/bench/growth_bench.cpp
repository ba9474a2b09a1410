// cambium — growth benchmarks.
#include "bench/growth_bench.h"

#include "bake/bake.h"
#include "cl/runtime.h"
#include "bake/sequence.h"
#include "io/vdb.h"
#include "blobtree/stats.h"
#include "core/error.h"
#include "model/growth.h"
#include "core/clock.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>

namespace cambium {

void runGrowthBench(const GrowthBenchRequest& req, const std::string& dir)
{
    checkDeviceOption(req.device);
    std::vector<int> years = req.years;
    std::sort(years.begin(), years.end());
    auto t0 = Clock::now();
    const GrowthModel model(loadGrowthParameters(req.parameters));
    const double global = secondsSince(t0);
    for (int y : years)
        if (y < 1 || y > model.params().years)
            throw InputError(fmt::format("--years: {} is outside the tree's 1 to {} years", y, model.params().years));
    std::unique_ptr<FieldSampler> sampler = makeSampler(req.device);
    fmt::print("{}: {} branches grown over {} years (global phase {:.3f} s); voxel size {:g}, {}, device {}\n\n",
               req.parameters, model.branches().size(), model.params().years, global, req.voxelSize,
               req.leaves ? "with leaves" : "no leaves", sampler->name());
    fmt::print("| year | internodes | primitives | operators | model s | bake s | write s | active voxels | file MB | "
               "peak MB |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int y : years) {
        t0 = Clock::now();
        const Skeleton sk = model.skeleton(y, req.leaves);
        const BlobTree tree = buildTree(sk, model.buildOptions());
        const FieldProgram program = FieldProgram::compile(tree);
        const double modelSeconds = secondsSince(t0);
        const TreeStats ts = computeStats(tree);
        BakeOptions opt;
        opt.voxelSize = req.voxelSize;
        t0 = Clock::now();
        const BakedGrids grids = bakeLevelSet(program, *sampler, opt);
        const double bakeSeconds = secondsSince(t0);
        const std::string path = fmt::format("{}/year{}.vdb", dir, y);
        VdbFileInfo info;
        info.scene = req.parameters;
        info.time = y;
        t0 = Clock::now();
        writeVdb(grids, path, info);
        const double writeSeconds = secondsSince(t0);
        fmt::print("| {} | {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {} | {:.0f} | {:.0f} |\n", y, sk.internodes.size(),
                   ts.primitives, ts.operators, modelSeconds, bakeSeconds, writeSeconds, grids.stats.activeVoxels,
                   double(std::filesystem::file_size(path)) / 1e6, peakMemoryBytes() / 1e6);
        std::filesystem::remove(path);
    }
    fmt::print("\npaper 000, year 27: 181,692 primitives, 22,220 operators, 1.4 GB to ray trace the last frame\n");
    if (req.fpsPerYear <= 0.0)
        return;
    sampler.reset();
    BakeRequest seq;
    seq.input = req.parameters;
    seq.output = dir + "/populus.####.vdb";
    const int last = int(std::lround(model.params().years * req.fpsPerYear));
    seq.frames = fmt::format("1-{}", last);
    seq.fpsPerYear = req.fpsPerYear;
    seq.voxelSize = req.voxelSize;
    seq.device = req.device;
    seq.model.leaves = req.leaves;
    const SequenceReport r = runBakeSequence(seq);
    size_t reused = 0, leaves = 0, reusedLeaves = 0;
    double bytes = 0.0;
    for (const FrameReport& f : r.frames) {
        reused += f.outcome == FrameReport::Outcome::Reused;
        if (f.outcome == FrameReport::Outcome::Baked) {
            leaves += f.stats.candidateLeaves;
            reusedLeaves += f.stats.reusedLeaves;
        }
        bytes += double(std::filesystem::file_size(f.path));
    }
    fmt::print("\nwhole sequence: {} frames ({:g} a year, {} reused whole; of the baked frames' {} leaves {:.0f} % "
               "unchanged, not sampled) in {:.1f} s, {} at once, {:.0f} MB of files, peak memory {:.0f} MB\n",
               r.frames.size(), req.fpsPerYear, reused, leaves, 100.0 * double(reusedLeaves) / double(std::max<size_t>(leaves, 1)),
               r.seconds, r.jobs, bytes / 1e6, r.peakMemoryBytes / 1e6);
}

}  // namespace cambium
