// cambium prepare — the OpenCL kernels built and run once, so that the
// first bake and render on this machine do not wait for a compiler.
#include "app/app.h"

#include "bake/levelset.h"
#include "bake/sampler.h"
#include "cl/runtime.h"
#include "core/clock.h"
#include "field/program.h"
#include "model/skeleton.h"
#include "use/render.h"

#include <fmt/format.h>

namespace cambium {

namespace {

int runPrepare()
{
    const auto t0 = Clock::now();
    // Every program the bake and the march build (kept by OpenCLContext::build
    // in cambium's cache), and each kernel launched with the local sizes the
    // commands use, on a small and on a large grid (kept by the driver: PoCL
    // compiles a kernel again at its first launch for each local size, and
    // apart for grids under and over 65,535 work-items).
    Skeleton twig;
    Internode n;
    n.p1 = {0.0, 1.0, 0.0};
    n.r0 = 0.2;
    n.r1 = 0.1;
    twig.internodes.push_back(n);
    const FieldProgram program = FieldProgram::compile(skeletonToBlend(twig));
    std::string device;
    withOpenCLHint("bake", [&] {
        auto sampler = makeOpenCLSampler();
        for (const double voxelSize : {0.05, 0.0012}) {  // about 3 and 150 thousand work-items
            BakeOptions options;
            options.voxelSize = voxelSize;
            const BakedGrids g = bakeLevelSet(program, *sampler, options);
            const int pixels = voxelSize > 0.01 ? 8 : 320;
            OpenCLMarcher marcher(*g.surface, g.color.get());
            marcher.render(framingCamera(activeWorldBounds(*g.surface), 1.0), pixels, pixels, 1);
            if (device.empty())
                device = marcher.deviceName();
        }
        return 0;
    });
    const std::string cache = programCacheDirectory();
    fmt::print("prepared the OpenCL kernels on {} in {:.1f} s (programs cached in {})\n", device,
               secondsSince(t0), cache.empty() ? "nowhere: CAMBIUM_CACHE_DIR is empty" : cache);
    return 0;
}

}  // namespace

void addPrepareCommand(CLI::App& app, Action& action)
{
    auto* cmd = app.add_subcommand(
        "prepare",
        "Build the OpenCL kernels now and run each once (into cambium's and the driver's "
        "caches), so that the first bake and render do not wait for a compiler; "
        "tools/setup.sh runs it after building");
    cmd->callback([&action] { action = [] { return runPrepare(); }; });
}

}  // namespace cambium
