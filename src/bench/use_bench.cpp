// cambium — mesh and render benchmarks.
#include "bench/use_bench.h"

#include "bake/bake.h"
#include "bake/levelset.h"
#include "bake/sampler.h"
#include "bench/median.h"
#include "field/program.h"
#include "use/mesh.h"
#include "use/render.h"
#include "core/clock.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <vector>

namespace cambium {

namespace {

BakedGrids bakeSkeleton(const Skeleton& skeleton, double h)
{
    const FieldProgram program = FieldProgram::compile(skeletonToBlend(skeleton));
    // (the bake's memory checked as bake checks it: a million internodes at
    // 1e-4 ran for a minute into the memory limit)
    checkBakeFits(program, h, "the benchmark tree");
    auto sampler = makeOpenCLSampler();
    BakeOptions opt;
    opt.voxelSize = h;
    return bakeLevelSet(program, *sampler, opt);
}

}  // namespace

MeshBenchResult runMeshBench(const Skeleton& skeleton, const std::string& label, double h,
                             int repeats)
{
    const BakedGrids g = bakeSkeleton(skeleton, h);
    std::vector<double> times;
    size_t triangles = 0;
    for (int r = 0; r < std::max(1, repeats); ++r) {
        const auto t = Clock::now();
        const TriangleMesh m = meshLevelSet(*g.surface, g.color.get());
        times.push_back(secondsSince(t));
        triangles = m.triangles.size();
    }
    return {label, h, g.stats.activeVoxels, int(times.size()), triangles, medianOf(times)};
}

RenderBenchResult runRenderBench(const Skeleton& skeleton, const std::string& label, double h,
                                 int width, int height, int repeats)
{
    const BakedGrids g = bakeSkeleton(skeleton, h);
    const Camera cam = framingCamera(activeWorldBounds(*g.surface), double(width) / double(height));
    auto tm = Clock::now();
    const TriangleMesh mesh = meshLevelSet(*g.surface, g.color.get());
    const double meshSeconds = secondsSince(tm);
    tm = Clock::now();
    const EmbreeMesh scene(mesh);
    const double bvhSeconds = secondsSince(tm);
    tm = Clock::now();
    const CpuMarcher cpu(*g.surface, g.color.get());
    const double cpuSetup = secondsSince(tm);
    tm = Clock::now();
    const OpenCLMarcher cl(*g.surface, g.color.get());
    const double clSetup = secondsSince(tm);
    std::vector<double> march, opencl, embree;
    double coverage = 0.0;
    for (int r = 0; r < std::max(1, repeats); ++r) {
        auto t = Clock::now();
        const RenderImage c = cl.render(cam, width, height, 1);
        opencl.push_back(secondsSince(t));
        t = Clock::now();
        const RenderImage a = cpu.render(cam, width, height, 1);
        march.push_back(secondsSince(t));
        t = Clock::now();
        const RenderImage b = scene.render(cam, width, height, 1);
        embree.push_back(secondsSince(t));
        size_t hit = 0;
        for (float v : a.alpha)
            hit += v > 0.0f;
        coverage = double(hit) / double(a.alpha.size());
    }
    RenderBenchResult r;
    r.label = label;
    r.voxelSize = h;
    r.activeVoxels = g.stats.activeVoxels;
    r.triangles = mesh.triangles.size();
    r.width = width;
    r.height = height;
    r.runs = int(march.size());
    r.coverage = coverage;
    r.opencl = medianOf(opencl);
    r.march = medianOf(march);
    r.embree = medianOf(embree);
    r.gridBytes = double(cl.gridBytes());
    r.openclSetup = clSetup;
    r.marchSetup = cpuSetup;
    r.meshSeconds = meshSeconds;
    r.bvhSeconds = bvhSeconds;
    return r;
}

}  // namespace cambium
