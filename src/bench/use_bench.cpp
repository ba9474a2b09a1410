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


BakedGrids bakeSkeleton(const std::string& skeleton, double h)
{
    const FieldProgram program = FieldProgram::compile(loadModel(skeleton));
    auto sampler = makeOpenCLSampler();
    BakeOptions opt;
    opt.voxelSize = h;
    return bakeLevelSet(program, *sampler, opt);
}

}  // namespace

void runMeshBench(const std::string& skeleton, const std::string& label, double h, int repeats)
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
    const double s = medianOf(times), perMillion = s / (double(triangles) * 1e-6);
    fmt::print("\n{} at voxel size {:g} ({} active voxels): meshing, median of {} runs\n", label, h,
               g.stats.activeVoxels, times.size());
    fmt::print("{:<52} {:>12} {:>10} {:>14} {:>16}\n", "method", "triangles", "seconds", "M triangles/s",
               "s per M tri");
    fmt::print("{:<52} {:>12} {:>10.3g} {:>14.3g} {:>16.3g}\n",
               "cambium mesh (volumeToMesh, normals, Cd colours)", triangles, s, double(triangles) / s * 1e-6,
               perMillion);
    fmt::print("{:<52} {:>12} {:>10} {:>14} {:>16.4g}\n", "paper 002, table 1 (a million triangles)", "1,000,000",
               "347.8", "0.00288", 347.8);
    fmt::print("paper's time per million triangles over cambium's: {:.0f}\n", 347.8 / perMillion);
}

void runRenderBench(const std::string& skeleton, const std::string& label, double h, int width, int height,
                    int repeats)
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
    const double rays = double(width) * double(height);
    fmt::print("\n{} at voxel size {:g} ({} active voxels, {} triangles): a {} x {} image, 1 sample per pixel, "
               "{:.1f} % of rays hit; median of {} runs\n",
               label, h, g.stats.activeVoxels, mesh.triangles.size(), width, height, 100.0 * coverage, march.size());
    fmt::print("{:<58} {:>10} {:>10} {:>14} {:>16}\n", "method", "seconds", "M rays/s", "768x768 (s)",
               "1536x2048x9 (s)");
    auto row = [&](const std::string& name, double s) {
        const double rate = rays / s;
        fmt::print("{:<58} {:>10.3g} {:>10.3g} {:>14.3g} {:>16.3g}\n", name, s, rate * 1e-6, 768.0 * 768.0 / rate,
                   1536.0 * 2048.0 * 9.0 / rate);
    };
    row("OpenCL NanoVDB HDDA march (PoCL)", medianOf(opencl));
    row("CPU level-set march (OpenVDB LevelSetRayIntersector, TBB)", medianOf(march));
    row("Embree 3 on the volumeToMesh triangles (streams, TBB)", medianOf(embree));
    fmt::print("{:<58} {:>10} {:>10} {:>14} {:>16}\n", "papers 000/003 (their renderer)", "-", "-", "430", "~3600");
    fmt::print("OpenCL march over CPU intersector: {:.2f}x\n", medianOf(march) / medianOf(opencl));
    fmt::print("(Not counted above: the NanoVDB copy ({:.0f} MB) and kernel build took {:.3g} s, the intersector's "
               "set-up {:.3g} s, Embree's mesh {:.3g} s and its BVH {:.3g} s.)\n",
               double(cl.gridBytes()) * 1e-6, clSetup, cpuSetup, meshSeconds, bvhSeconds);
}

}  // namespace cambium
