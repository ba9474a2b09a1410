// cambium — growth benchmarks.
#include "bench/growth_bench.h"

#include "bake/bake.h"
#include "bake/levelset.h"
#include "cl/runtime.h"
#include "bake/sequence.h"
#include "io/vdb.h"
#include "bench/median.h"
#include "blobtree/stats.h"
#include "core/error.h"
#include "model/growth.h"
#include "model/tree_builder.h"
#include "core/clock.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <filesystem>

namespace cambium {

void runGrowthBench(const GrowthBenchRequest& req, const std::string& dir,
                    const GrowthBenchCallbacks& callbacks)
{
    // (a bad --fps-per-year was refused after the year table was printed)
    if (req.fpsPerYear != 0.0)
        checkFpsPerYear(req.fpsPerYear);
    std::vector<int> years = req.years;
    std::sort(years.begin(), years.end());
    auto t0 = Clock::now();
    const GrowthModel model(loadGrowthParameters(req.parameters));
    const double global = secondsSince(t0);
    checkGrowthYears(years, model.params(), req.parameters);
    // (the largest year's bake checked before any: a voxel size of 5e-4 ran
    // silently for minutes, 1e-4 into the memory limit)
    if (!years.empty())
        checkBakeFits(FieldProgram::compile(buildTree(model.skeleton(years.back(), req.leaves),
                                                      model.buildOptions())),
                      req.voxelSize, fmt::format("{} year {}", req.parameters, years.back()));
    std::unique_ptr<FieldSampler> sampler = makeSampler(req.device);
    if (callbacks.setup)
        callbacks.setup({model.branches().size(), model.params().years, global, sampler->name()});
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
        if (callbacks.year)
            callbacks.year({y, sk.internodes.size(), ts.primitives, ts.operators,
                            grids.stats.activeVoxels, modelSeconds, bakeSeconds, writeSeconds,
                            double(std::filesystem::file_size(path)), peakMemoryBytes()});
        std::filesystem::remove(path);
    }
    if (model.params().barkDetail.depth > 0.0 && callbacks.bark) {
        // The bark's cost: the last year with and without furrows, in turn.
        GrowthBenchBark b;
        b.year = years.back();
        const Skeleton sk = model.skeleton(b.year, req.leaves);
        TreeBuildOptions plain = model.buildOptions();
        plain.barkDetail.depth = 0.0;
        const FieldProgram with = FieldProgram::compile(buildTree(sk, model.buildOptions()));
        const FieldProgram without = FieldProgram::compile(buildTree(sk, plain));
        b.barkCones = with.barkCount();
        BakeOptions opt;
        opt.voxelSize = req.voxelSize;
        std::vector<double> a, c;
        for (int run = 0; run < 3; ++run)
            for (int k = 0; k < 2; ++k) {
                t0 = Clock::now();
                const BakedGrids g = bakeLevelSet(k ? without : with, *sampler, opt);
                (k ? c : a).push_back(secondsSince(t0));
                (k ? b.withoutVoxels : b.withVoxels) = g.stats.activeVoxels;
                (k ? b.withoutGridBytes : b.withGridBytes) =
                    double(g.surface->memUsage() + g.color->memUsage());
            }
        b.withSeconds = medianOf(a);
        b.withoutSeconds = medianOf(c);
        callbacks.bark(b);
    }
    if (req.fpsPerYear <= 0.0)
        return;
    sampler.reset();
    SequenceRequest seq;
    seq.bake.input = req.parameters;
    seq.bake.output = dir + "/populus.####.vdb";
    const int last = int(std::lround(model.params().years * req.fpsPerYear));
    seq.frames = fmt::format("1-{}", last);
    seq.fpsPerYear = req.fpsPerYear;
    seq.bake.voxelSize = req.voxelSize;
    seq.bake.device = req.device;
    seq.bake.model.leaves = req.leaves;
    const SequenceReport r = bakeSequence(seq);
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
    if (callbacks.sequence)
        callbacks.sequence({r.frames.size(), reused, leaves, reusedLeaves, r.seconds, bytes,
                            r.peakMemoryBytes, r.jobs});
}

}  // namespace cambium
