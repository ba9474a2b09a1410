// cambium — the command-line tool.  A thin table of sub-commands: each parses
// its arguments and calls the library.
#include "bake/bake.h"
#include "bake/sequence.h"
#include "core/frames.h"
#include "bench/bake_bench.h"
#include "bench/growth_bench.h"
#include "bench/use_bench.h"
#include "blobtree/evaluator.h"
#include "blobtree/scene_io.h"
#include "blobtree/stats.h"
#include "core/error.h"
#include "core/files.h"
#include "core/versions.h"
#include "cl/runtime.h"
#include "model/growth.h"
#include "model/turtle.h"
#include "use/mesh.h"
#include "use/render.h"
#include "core/clock.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <openvdb/openvdb.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <mutex>
#include <string>
#include <unistd.h>

namespace {

using namespace cambium;

std::string vec(const glm::dvec3& v) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", v.x, v.y, v.z); }

/// Runs f in a fresh temporary directory for the benchmarks' generated
/// trees, removed afterwards (also when f throws).  Returns 0.
int withBenchDirectory(const std::function<void(const std::string&)>& f)
{
    char dir[] = "/tmp/cambium-bench-XXXXXX";
    if (!::mkdtemp(dir))
        throw std::runtime_error("cannot create a temporary directory");
    try {
        f(dir);
    } catch (...) {
        std::filesystem::remove_all(dir);
        throw;
    }
    std::filesystem::remove_all(dir);
    return 0;
}

int runInfo(const std::string& scenePath, const ModelOptions& model)
{
    const auto start = Clock::now();
    const BlobTree tree = loadModel(scenePath, model);
    const double seconds = secondsSince(start);
    const TreeStats s = computeStats(tree);
    fmt::print("scene      {}\n", scenePath);
    fmt::print("read       {:.3f} s (reading, deriving and building the BlobTree)\n", seconds);
    fmt::print("threshold  {}\n", tree.threshold());
    fmt::print("nodes      {}: {} primitive{}, {} operator{}, {} warp{}\n",
               s.primitives + s.operators + s.warps, s.primitives, s.primitives == 1 ? "" : "s",
               s.operators, s.operators == 1 ? "" : "s", s.warps, s.warps == 1 ? "" : "s");
    for (const auto& [type, count] : s.countByType)
        fmt::print("  {:<22} {}\n", typeName(type), count);
    fmt::print("depth      {}\n", s.depth);
    if (s.bounds.empty()) {
        fmt::print("bounds     empty (the field is nowhere positive: no surface)\n");
    } else {
        fmt::print("bounds     min {}  max {}\n", vec(s.bounds.lo), vec(s.bounds.hi));
        fmt::print("           size {}  (from primitive supports: the surface lies within)\n",
                   vec(s.bounds.size()));
    }
    return 0;
}

int runEval(const std::string& scenePath, const std::vector<double>& xyz)
{
    const glm::dvec3 p(xyz[0], xyz[1], xyz[2]);
    if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)))
        throw InputError(fmt::format("eval: the point {} must have finite coordinates", vec(p)));
    const BlobTree tree = loadModel(scenePath);
    const ReferenceEvaluator eval(tree);
    const FieldSample s = eval.sample(p);
    fmt::print("point     {}\n", vec(p));
    fmt::print("field     {:.9g}  ({} at threshold {})\n", s.value,
               s.value > tree.threshold() ? "inside" : (s.value < tree.threshold() ? "outside" : "on the surface"),
               tree.threshold());
    fmt::print("gradient  {}  |grad| {:.6g}\n", vec(s.gradient), glm::length(s.gradient));
    fmt::print("colour    {}\n", vec(s.color));
    return 0;
}

/// A progress bar on stderr when it is a terminal; silent otherwise.
class ProgressBar {
public:
    ProgressBar() : tty_(::isatty(2) != 0) {}
    ~ProgressBar() { clear(); }
    void operator()(const char* stage, double fraction)
    {
        if (!tty_)
            return;
        std::lock_guard<std::mutex> lock(mutex_);
        const int percent = int(100.0 * fraction);
        if (stage == stage_ && percent == percent_)
            return;
        stage_ = stage;
        percent_ = percent;
        const int filled = percent * 30 / 100;
        fmt::print(stderr, "\r{:<9} [{}{}] {:3d}%", stage_, std::string(size_t(filled), '#'),
                   std::string(size_t(30 - filled), ' '), percent);
        std::fflush(stderr);
        shown_ = true;
    }
    void clear()
    {
        if (shown_)
            fmt::print(stderr, "\r\033[K");
        shown_ = false;
    }

private:
    bool tty_;
    bool shown_ = false;
    std::mutex mutex_;
    std::string stage_;
    int percent_ = -1;
};

std::string count(size_t n)
{
    std::string s = std::to_string(n);
    for (int i = int(s.size()) - 3; i > 0; i -= 3)
        s.insert(size_t(i), ",");
    return s;
}

int runSequenceCommand(BakeRequest req)
{
    req.notice = [](const std::string& line) {
        fmt::print("note: {}\n", line);
        std::fflush(stdout);
    };
    const char* outcome[] = {"baked", "reused (its BlobTree is the previous frame's)", "kept (--resume)",
                             "empty (nothing a voxel thick yet)"};
    size_t doneFrames = 0, total = parseFrames(req.frames).size();
    const SequenceReport r = runBakeSequence(req, [&](const FrameReport& f) {
        ++doneFrames;
        fmt::print("[{}/{}] frame {} (year {:.3g}) {}: {}", doneFrames, total, f.frame, f.time, f.path,
                   outcome[int(f.outcome)]);
        if (f.outcome == FrameReport::Outcome::Baked) {
            fmt::print(", {} active voxels", count(f.stats.activeVoxels));
            if (f.stats.reusedLeaves)
                fmt::print(" ({} of {} leaves unchanged, not sampled)", count(f.stats.reusedLeaves),
                           count(f.stats.candidateLeaves));
        }
        fmt::print(", {:.2f} s\n", f.seconds);
        std::fflush(stdout);
    });
    size_t baked = 0, reused = 0, kept = 0, empty = 0;
    for (const FrameReport& f : r.frames)
        ++(f.outcome == FrameReport::Outcome::Baked    ? baked
           : f.outcome == FrameReport::Outcome::Reused ? reused
           : f.outcome == FrameReport::Outcome::Skipped ? kept
                                                        : empty);
    fmt::print("sequence {}: {} frames ({} baked, {} reused, {} kept, {} empty) in {:.1f} s, {} at once, voxel size "
               "{:g}{}, device {}, peak memory {:.0f} MB\n",
               req.output, r.frames.size(), baked, reused, kept, empty, r.seconds, r.jobs, r.voxelSize,
               r.autoVoxelSize ? " (auto: 512 voxels across the last frame)" : "", r.device, r.peakMemoryBytes / 1e6);
    return 0;
}

int runBakeCommand(BakeRequest req)
{
    if (!req.frames.empty())
        return runSequenceCommand(req);
    ProgressBar bar;
    req.progress = [&](const char* stage, double f) { bar(stage, f); };
    req.notice = [&](const std::string& line) {
        bar.clear();
        fmt::print("note: {}\n", line);
    };
    const BakeReport r = cambium::runBake(req);
    bar.clear();
    const BakeStats& s = r.stats;
    fmt::print("baked {}: {} leaves ({} sampled), {} active voxels, {:.2f} s ({:.3g} M voxels/s; topology {:.2f} s, "
               "sampling {:.2f} s, assembly {:.2f} s), peak memory {:.0f} MB, voxel size {:g}{}, "
               "device {}, {:.1f} instructions per leaf\n",
               req.output, count(s.activeLeaves), count(s.candidateLeaves), count(s.activeVoxels), s.seconds,
               double(s.activeVoxels) / s.seconds * 1e-6, s.topologySeconds, s.samplingSeconds,
               s.assemblySeconds, r.peakMemoryBytes / 1e6, s.voxelSize,
               r.autoVoxelSize ? fmt::format(" (auto: 512 voxels across {:.4g})", r.extent) : "",
               r.device, s.meanProgramLength);
    return 0;
}

int runVersion()
{
    fmt::print("cambium {}\n", version());
    for (const auto& [lib, v] : dependencyVersions())
        fmt::print("  {:<12} {}\n", lib, v);
    const auto devices = listOpenCLDevices();
    if (devices.empty())
        fmt::print("  {:<12} {}\n", "OpenCL", "no platform found");
    for (const auto& d : devices)
        fmt::print("  {:<12} {} / {} / {}\n", "OpenCL", d.platform, d.device, d.version);
    return 0;
}

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"cambium: bake BlobTree implicit models of growing plants into OpenVDB level sets"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("cambium ") + cambium::version());

    std::function<int()> action;

    std::string scene;
    ModelOptions model;
    bool noLeaves = false;
    double modelTime = 0.0;
    auto modelOptions = [&](CLI::App* cmd) {
        cmd->add_option("--junctions", model.junctions,
                        "L-systems and skeletons: pcm (the papers' junction rules, PCM between branches), smooth "
                        "(the rules, summation only) or blend (a cone per internode, summed); default pcm for "
                        "L-systems, blend for skeleton files");
        cmd->add_option("--bend", model.bendDegrees,
                        "Bend lateral internodes by this many degrees, keeping their ends (pcm, smooth)");
        cmd->add_option("--primitives", model.primitives,
                        "cone (papers 001/003), convolution (segments with linear density, paper 002) or mixed "
                        "(cone axes, convolution laterals, better blending between)")
            ->capture_default_str();
        cmd->add_option("--regrowth", model.regrowth,
                        "Callus over saw cuts, from 0 (a bare cut) to 1 (paper 002's regrowth bulge)");
        cmd->add_flag("--no-leaves", noLeaves, "Growth parameter files: leave the leaves out");
        return cmd->add_option("--time", modelTime,
                               "Growth parameter files: the tree at this time in years (default: the last)");
    };
    auto* info = app.add_subcommand("info", "Print a scene's node counts by type, depth and bounds");
    info->add_option("scene", scene,
                     "Scene (JSON, docs/scene-format.md), growth parameters (docs/growth-format.md), L-system (.l, "
                     "docs/lsystem-format.md) or skeleton (docs/skeleton-format.md)")
        ->required();
    CLI::Option* infoTime = modelOptions(info);
    info->callback([&] {
        model.leaves = !noLeaves;
        if (infoTime->count())
            model.time = modelTime;
        action = [&] { return runInfo(scene, model); };
    });

    std::vector<double> point;
    auto* eval = app.add_subcommand("eval", "Evaluate a scene's field, gradient and colour at a point "
                                            "(CPU reference evaluator)");
    eval->add_option("scene", scene, "Scene (JSON) or skeleton")->required();
    eval->add_option("point", point, "x y z")->required()->expected(3);
    eval->callback([&] { action = [&] { return runEval(scene, point); }; });

    BakeRequest bake;
    double voxelSize = 0.0;
    auto* bakeCmd = app.add_subcommand(
        "bake", "Bake a scene, L-system, skeleton or grown tree into a narrow-band OpenVDB level set (.vdb), or a "
                "growing tree into a sequence of them");
    bakeCmd->add_option("input", bake.input,
                        "Scene (.json), growth parameters (.json with \"curves\"), L-system (.l) or skeleton file")
        ->required();
    CLI::Option* timeOpt = modelOptions(bakeCmd);
    bakeCmd->add_option("-o,--output", bake.output, "Output .vdb file")->required();
    auto* voxelOpt = bakeCmd->add_option("--voxel-size", voxelSize,
                                         "Voxel size in world units (default: 512 voxels across the "
                                         "surface bounds)");
    bakeCmd->add_option("--half-width", bake.halfWidth, "Narrow-band half-width in voxels")
        ->capture_default_str();
    bakeCmd->add_option("--device", bake.device, "opencl or cpu")->capture_default_str();
    bakeCmd->add_flag("--fog", bake.fog, "Also write a `density` fog volume");
    bakeCmd->add_flag("--half", bake.half, "Store floats as 16-bit halves");
    bakeCmd->add_option("--threads", bake.threads, "Worker threads (default: all cores)")->check(CLI::Range(1, 4096));
    bakeCmd->add_option("--frames", bake.frames,
                        "Growth parameter files: bake frames FIRST-LAST[:STEP] into -o with a run of '#' "
                        "(out/populus.####.vdb), frame f at year f / fps-per-year")
        ->excludes(timeOpt);
    bakeCmd->add_option("--fps-per-year", bake.fpsPerYear, "Frames per year of growth")->capture_default_str();
    bakeCmd->add_flag("--resume", bake.resume, "Keep the frames an interrupted run of the same bake finished");
    bakeCmd->add_option("--jobs", bake.jobs, "Frames baked at once (default: as many as cores and memory allow)")
        ->check(CLI::Range(1, 4096));
    bakeCmd->callback([&] {
        if (voxelOpt->count())
            bake.voxelSize = voxelSize;
        model.leaves = !noLeaves;
        if (timeOpt->count())
            model.time = modelTime;
        bake.model = model;
        action = [&] { return runBakeCommand(bake); };
    });

    MeshRequest mesh;
    auto* meshCmd = app.add_subcommand("mesh", "Polygonise a baked level set (OpenVDB's volumeToMesh) into "
                                                "an OBJ or binary PLY mesh");
    meshCmd->add_option("input", mesh.input, "Input .vdb file")->required();
    meshCmd->add_option("-o,--output", mesh.output, "Output mesh (.obj or .ply)")->required();
    meshCmd->add_option("--adaptivity", mesh.adaptivity,
                        "0: uniform triangles; up to 1: fewer where the surface is flat")
        ->capture_default_str();
    meshCmd->add_option("--grid", mesh.grid, "Name of the level-set grid")->capture_default_str();
    meshCmd->add_option("--frames", mesh.frames,
                        "A sequence: frames FIRST-LAST[:STEP] of an input and output with a run of '#' "
                        "(tree.####.vdb)");
    meshCmd->callback([&] { action = [&] { return runMeshCommand(mesh); }; });

    RenderRequest render;
    auto* renderCmd = app.add_subcommand("render", "Ray-march a baked level set into a picture (.png) or "
                                                    "channels for tools (.exr)");
    renderCmd->add_option("input", render.input, "Input .vdb file");
    renderCmd->add_option("--mesh", render.mesh,
                          "Render this mesh (.obj or .ply) with Embree instead of a .vdb file");
    renderCmd->add_option("-o,--output", render.output, "Output image (.png or .exr)")->required();
    renderCmd->add_option("--width", render.width, "Image width in pixels")->capture_default_str();
    renderCmd->add_option("--height", render.height, "Image height in pixels")->capture_default_str();
    renderCmd->add_option("--spp", render.spp, "Samples per pixel (anti-aliasing)")->capture_default_str();
    renderCmd->add_option("--camera", render.camera, "auto (a three-quarter view), turntable:ANGLE or look:EX,EY,EZ:TX,TY,TZ[:FOV]")
        ->capture_default_str();
    renderCmd->add_option("--device", render.device,
                          "opencl (NanoVDB's HDDA in an OpenCL kernel) or cpu (OpenVDB's level-set ray intersector)")
        ->capture_default_str();
    renderCmd->add_option("--grid", render.grid, "Name of the level-set grid")->capture_default_str();
    renderCmd->add_flag("--via-mesh", render.viaMesh,
                        "Mesh the level set and trace the triangles with Embree (the cross-check)");
    renderCmd->add_option("--frames", render.frames,
                          "A sequence: frames FIRST-LAST[:STEP] of an input and output with a run of '#'");
    renderCmd->callback([&] { action = [&] { return runRenderCommand(render); }; });

    auto* bench = app.add_subcommand("bench", "Throughput benchmarks, side by side in one run");
    bench->require_subcommand(1);
    std::string generator = CAMBIUM_BENCH_GENERATOR;
    std::vector<std::string> benchCases = {"1000:0.01", "20000:0.005"};
    bool skipCpu = false;
    int repeats = 3;
    auto* benchBake = bench->add_subcommand(
        "bake", "cambium's bake (OpenCL and CPU) against a naive dense evaluation and OpenVDB's "
                "ParticlesToLevelSet, on trees from ../shared/bench/gen_skeleton.py");
    benchBake->add_option("--generator", generator, "gen_skeleton.py")->capture_default_str();
    benchBake->add_option("--case", benchCases, "INTERNODES:VOXEL_SIZE (repeatable)")->capture_default_str();
    benchBake->add_flag("--skip-cpu", skipCpu, "Leave out the CPU path");
    benchBake->add_option("--repeat", repeats, "Runs of each method, in turn; the table shows medians")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    benchBake->callback([&] {
        action = [&] {
            return withBenchDirectory([&](const std::string& dir) {
                std::vector<BakeBenchCase> cases;
                for (const std::string& c : benchCases) {
                    const auto colon = c.find(':');
                    if (colon == std::string::npos)
                        throw InputError(fmt::format("--case {}: expected INTERNODES:VOXEL_SIZE", c));
                    const int n = std::stoi(c.substr(0, colon));
                    BakeBenchCase bc;
                    bc.skeleton = generateSkeleton(generator, n, dir);
                    bc.label = fmt::format("tree of {} internodes", n);
                    bc.voxelSize = std::stod(c.substr(colon + 1));
                    cases.push_back(bc);
                }
                runBakeBench(cases, skipCpu, repeats);
            });
        };
    });

    int useInternodes = 1000, benchWidth = 768, benchHeight = 768;
    double useVoxel = 0.01;
    auto useBench = [&](CLI::App* cmd) {
        cmd->add_option("--generator", generator, "gen_skeleton.py")->capture_default_str();
        cmd->add_option("--internodes", useInternodes, "Internodes of the generated tree")->capture_default_str();
        cmd->add_option("--voxel-size", useVoxel, "Voxel size of the bake")->capture_default_str();
        cmd->add_option("--repeat", repeats, "Runs of each method; the table shows medians")
            ->capture_default_str()
            ->check(CLI::Range(1, 100));
    };
    auto withTree = [&](const std::function<void(const std::string&, const std::string&)>& f) {
        return withBenchDirectory([&](const std::string& dir) {
            f(generateSkeleton(generator, useInternodes, dir), fmt::format("tree of {} internodes", useInternodes));
        });
    };
    auto* benchMesh = bench->add_subcommand("mesh", "Meshing a baked benchmark tree, against paper 002's figure");
    useBench(benchMesh);
    benchMesh->callback([&] {
        action = [&] {
            return withTree([&](const std::string& s, const std::string& l) { runMeshBench(s, l, useVoxel, repeats); });
        };
    });
    auto* benchRender = bench->add_subcommand(
        "render", "Rendering a baked benchmark tree: the OpenCL and CPU level-set marches and Embree on its mesh, "
                  "against the papers' figures");
    useBench(benchRender);
    benchRender->add_option("--width", benchWidth, "Image width")->capture_default_str();
    benchRender->add_option("--height", benchHeight, "Image height")->capture_default_str();
    benchRender->callback([&] {
        action = [&] {
            return withTree([&](const std::string& s, const std::string& l) {
                runRenderBench(s, l, useVoxel, benchWidth, benchHeight, repeats);
            });
        };
    });

    GrowthBenchRequest growthBench;
    growthBench.parameters = CAMBIUM_SOURCE_DIR "/examples/populus/populus.json";
    auto* benchGrowth = bench->add_subcommand(
        "growth", "The growth model's tree by year (internodes, primitives, operators, bake time and memory) and a "
                  "whole sequence, against paper 000's year 27");
    benchGrowth->add_option("--parameters", growthBench.parameters, "Growth parameter file")->capture_default_str();
    benchGrowth->add_option("--years", growthBench.years, "Years to measure")->capture_default_str()->delimiter(',');
    benchGrowth->add_option("--voxel-size", growthBench.voxelSize, "Voxel size")->capture_default_str();
    benchGrowth->add_option("--fps-per-year", growthBench.fpsPerYear,
                            "Frame rate of the whole sequence (0: leave it out)")
        ->capture_default_str();
    benchGrowth->add_option("--device", growthBench.device, "opencl or cpu")->capture_default_str();
    benchGrowth->add_flag("--leaves", growthBench.leaves, "Grow leaves (frames at year ends have none)");
    benchGrowth->callback([&] {
        action = [&] { return withBenchDirectory([&](const std::string& dir) { runGrowthBench(growthBench, dir); }); };
    });

    LSystemRequest lsys;
    auto* lsCmd = app.add_subcommand("lsystem", "Derive an L-system (docs/lsystem-format.md) and print the string, "
                                                "its skeleton or a summary");
    lsCmd->add_option("input", lsys.input, "L-system file")->required();
    lsCmd->add_option("--steps", lsys.steps, "Derivation steps (default: the file's derivation length)")
        ->check(CLI::Range(0, kMaxSteps));
    lsCmd->add_option("--seed", lsys.seed, "Seed of stochastic productions (default: the file's seed:)")
        ->check(CLI::NonNegativeNumber);
    lsCmd->add_option("--max-modules", lsys.maxModules, "Refuse a derivation that makes more modules")
        ->capture_default_str()
        ->check(CLI::Range(size_t(1), kMaxModulesLimit));
    lsCmd->add_flag("--print-string", lsys.printString, "Print the derived string (one line, ABOP notation)");
    lsCmd->add_flag("--print-skeleton", lsys.printSkeleton,
                    "Print the internodes in the skeleton format, which cambium bake reads");
    lsCmd->callback([&] { action = [&] { return runLSystemCommand(lsys); }; });

    GrowthRequest growth;
    double growthYear = 0.0, growthTime = 0.0;
    auto* growthCmd = app.add_subcommand("growth", "Grow a tree from a growth parameter file (docs/growth-format.md) "
                                                    "and print its counts or skeleton at a time");
    growthCmd->add_option("input", growth.input, "Growth parameter file (.json)")->required();
    auto* yearOpt = growthCmd->add_option("--year", growthYear, "The end of this year (default: the last)");
    auto* growthTimeOpt = growthCmd->add_option("--time", growthTime, "Any time in years, e.g. 3.5 (mid-season of year 4)")
        ->excludes(yearOpt);
    growthCmd->add_option("--seed", growth.seed, "Seed of the stochastic orientation (default: the file's)")
        ->check(CLI::NonNegativeNumber);
    growthCmd->add_flag("--no-leaves", noLeaves, "Leave the leaves out");
    growthCmd->add_flag("--print-stats", growth.printStats,
                        "Branches and internodes by order, organs, BlobTree primitives and operators");
    growthCmd->add_flag("--print-skeleton", growth.printSkeleton, "Print the internodes (skeleton format)");
    growthCmd->callback([&] {
        if (yearOpt->count())
            growth.time = growthYear;
        if (growthTimeOpt->count())
            growth.time = growthTime;
        growth.leaves = !noLeaves;
        action = [&] { return runGrowthCommand(growth); };
    });

    auto* ver = app.add_subcommand("version", "Print the versions of cambium, its libraries and the "
                                              "OpenCL devices found");
    ver->callback([&] { action = [&] { return runVersion(); }; });

    // Exit status (docs/errors.md): 0 success; 2 a bad request, named before
    // any work (a farm must not retry); 1 a failure during the work.
    cambium::installCleanupOnSignals();
    std::string names;
    bool known = false;
    for (const CLI::App* c : app.get_subcommands({})) {
        names += (names.empty() ? "" : ", ") + c->get_name();
        known = known || (argc >= 2 && c->get_name() == argv[1]);
    }
    if (argc >= 2 && argv[1][0] != '-' && !known) {
        std::fprintf(stderr, "cambium: error: unknown command '%s' (the commands: %s)\n", argv[1], names.c_str());
        return 2;
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;  // --help and --version are not errors
    }
    openvdb::initialize();
    try {
        return action ? action() : 0;
    } catch (const cambium::InputError& e) {
        std::fprintf(stderr, "cambium: error: %s\n", e.what());  // never throws, whatever stderr is
        return 2;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "cambium: failed: out of memory\n");
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "cambium: failed: %s\n", e.what());
        return 1;
    }
}
