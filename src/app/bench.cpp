// cambium bench — throughput benchmarks, side by side in one run: the bake
// against the ways a user would do it today, meshing, rendering, growth.
#include "app/app.h"

#include "bench/bake_bench.h"
#include "bench/growth_bench.h"
#include "bench/read_bench.h"
#include "bench/shape_bench.h"
#include "bench/tree_generator.h"
#include "bake/bake.h"
#include "bake/options.h"
#include "bench/use_bench.h"
#include "core/error.h"
#include "core/files.h"
#include "core/math.h"
#include "core/system.h"
#include "field/program.h"
#include "model/growth_params.h"
#include "model/skeleton.h"
#include "preview/preview_bench.h"
#include "use/render.h"

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <thread>

namespace cambium {

namespace {

/// The benchmark tree of `internodes` internodes (bench/tree_generator.h):
/// its skeleton file's text and the skeleton read from it.
struct BenchTree {
    std::string text;
    Skeleton skeleton;
};

/// The largest generated tree a benchmark takes (the generator's trees of a
/// million internodes bake in minutes).
constexpr int kMaxBenchInternodes = 1000000;

BenchTree benchTree(int internodes)
{
    TreeGeneratorOptions o;
    o.internodes = internodes;
    BenchTree t;
    t.text = generateBenchSkeleton(o);
    t.skeleton = parseSkeleton(t.text, fmt::format("benchmark tree of {} internodes", internodes));
    return t;
}

void printBakeTable(const BakeBenchResult& c)
{
    fmt::print(
        "\n{}: {} primitives, voxel size {:g}, half-width {:g}, bounding box {} voxels; "
        "median of {} runs\n",
        c.label, formatCount(double(c.primitives)), c.voxelSize, c.halfWidth,
        formatCount(c.boxVoxels), c.repeats);
    fmt::print("{:<48} {:>10} {:>15} {:>12} {:>10} {:>10}\n", "method", "seconds", "active voxels",
               "M voxels/s", "peak MB", "time/(a)");
    for (const BakeBenchRow& r : c.rows) {
        const bool dense = r.estimated;  // (c): extrapolated over the dense box
        fmt::print(
            "{:<48} {:>10} {:>15} {:>12} {:>10.0f} {:>10.2f}\n", r.method,
            fmt::format("{}{:.3g}", r.estimated ? "~" : "", r.seconds),
            dense ? "(dense)" : formatCount(r.activeVoxels),
            dense ? std::string("-") : fmt::format("{:.3g}", r.activeVoxels / r.seconds * 1e-6),
            r.peakBytes / 1e6, r.seconds / c.rows[0].seconds);
    }
    fmt::print(
        "writing (a)'s grids ({:.0f} MB file, Blosc), medians: cambium's leaves on all cores "
        "{:.3f} s, OpenVDB's serial writer {:.3f} s in memory ({:.2f}x); cambium's whole "
        "checked write (fsync, rename) {:.3f} s, io::File::write {:.3f} s ({:.2f}x)\n",
        c.fileBytes / 1e6, c.encodeParallel, c.encodeSerial, c.encodeSerial / c.encodeParallel,
        c.writeVdbSeconds, c.fileWrite, c.fileWrite / c.writeVdbSeconds);
    fmt::print(
        "Eikonal check (checkLevelSet test 9: zero-crossing voxels with |grad|^2 outside "
        "[0.5, 1.5]): (a) {:.3f} % of {}, (d) {:.3f} % of {}\n",
        100.0 * c.eikonal.fraction(), formatCount(double(c.eikonal.crossing)),
        100.0 * c.peerEikonal.fraction(), formatCount(double(c.peerEikonal.crossing)));
    if (c.process.seconds > 0.0) {
        fmt::print("whole processes, file written, in turn; median (fastest-slowest) of {} runs\n",
                   c.repeats);
        fmt::print("{:<48} {:>20} {:>10} {:>10} {:>10}\n", "command", "seconds", "peak MB",
                   "file MB", "time/ours");
        auto row = [&](const char* name, const ProcessSummary& p) {
            fmt::print("{:<48} {:>20} {:>10.0f} {:>10.0f} {:>10.2f}\n", name,
                       fmt::format("{:.2f} ({:.2f}-{:.2f})", p.seconds, p.minSeconds, p.maxSeconds),
                       p.peakBytes / 1e6, p.fileBytes / 1e6, p.seconds / c.process.seconds);
        };
        row("cambium bake (OpenCL)", c.process);
        row("cambium-ptls (ParticlesToLevelSet, File::write)", c.peerProcess);
        fmt::print(
            "peer's time over cambium's {:.2f}x (goal 1.5x), cambium's peak memory over the "
            "peer's {:.2f}x (goal <= 1)\n",
            c.peerProcess.seconds / c.process.seconds,
            c.process.peakBytes / c.peerProcess.peakBytes);
    }
}

void printMeshTable(const MeshBenchResult& r)
{
    const double perMillion = r.seconds / (double(r.triangles) * 1e-6);
    fmt::print("\n{} at voxel size {:g} ({} active voxels): meshing, median of {} runs\n", r.label,
               r.voxelSize, r.activeVoxels, r.runs);
    fmt::print("{:<52} {:>12} {:>10} {:>14} {:>16}\n", "method", "triangles", "seconds",
               "M triangles/s", "s per M tri");
    fmt::print("{:<52} {:>12} {:>10.3g} {:>14.3g} {:>16.3g}\n",
               "cambium mesh (volumeToMesh, normals, Cd colours)", r.triangles, r.seconds,
               double(r.triangles) / r.seconds * 1e-6, perMillion);
    fmt::print("{:<52} {:>12} {:>10} {:>14} {:>16.4g}\n",
               "paper 002, table 1 (a million triangles)", "1,000,000", "347.8", "0.00288", 347.8);
    fmt::print("paper's time per million triangles over cambium's: {:.0f}\n", 347.8 / perMillion);
}

void printRenderTable(const RenderBenchResult& r)
{
    const double rays = double(r.width) * double(r.height);
    fmt::print(
        "\n{} at voxel size {:g} ({} active voxels, {} triangles): a {} x {} image, 1 sample per "
        "pixel, "
        "{:.1f} % of rays hit; median of {} runs\n",
        r.label, r.voxelSize, r.activeVoxels, r.triangles, r.width, r.height, 100.0 * r.coverage,
        r.runs);
    fmt::print("{:<58} {:>10} {:>10} {:>14} {:>16}\n", "method", "seconds", "M rays/s",
               "768x768 (s)", "1536x2048x9 (s)");
    auto row = [&](const std::string& name, double s) {
        const double rate = rays / s;
        fmt::print("{:<58} {:>10.3g} {:>10.3g} {:>14.3g} {:>16.3g}\n", name, s, rate * 1e-6,
                   768.0 * 768.0 / rate, 1536.0 * 2048.0 * 9.0 / rate);
    };
    row("OpenCL NanoVDB HDDA march (PoCL)", r.opencl);
    row("CPU level-set march (OpenVDB LevelSetRayIntersector, TBB)", r.march);
    row("Embree 3 on the volumeToMesh triangles (streams, TBB)", r.embree);
    fmt::print("{:<58} {:>10} {:>10} {:>14} {:>16}\n", "papers 000/003 (their renderer)", "-", "-",
               "430", "~3600");
    fmt::print("OpenCL march over CPU intersector: {:.2f}x\n", r.march / r.opencl);
    fmt::print(
        "(Not counted above: the NanoVDB copy ({:.0f} MB) and kernel build took {:.3g} s, the "
        "intersector's "
        "set-up {:.3g} s, Embree's mesh {:.3g} s and its BVH {:.3g} s.)\n",
        r.gridBytes * 1e-6, r.openclSetup, r.marchSetup, r.meshSeconds, r.bvhSeconds);
}

void printShapeTable(const ShapeBenchResult& r)
{
    const double v = double(r.vertices);
    const double osd = r.osdTopology + r.osdInterpolate;
    fmt::print("\nrock cube-sphere, {} levels: {} finest vertices, {} quads\n\n", r.levels,
               r.vertices, r.faces);
    fmt::print(
        "| step | seconds (median) | finest vertices/s | vs OpenSubdiv |\n"
        "|---|---:|---:|---:|\n");
    fmt::print("| OpenSubdiv: refiner (topology) | {:.3f} | | |\n", r.osdTopology);
    fmt::print("| OpenSubdiv: points refined (Interpolate, double) | {:.3f} | | |\n",
               r.osdInterpolate);
    fmt::print("| OpenSubdiv: uniform refinement, both | {:.3f} | {:.2f} M | 1.00 |\n", osd,
               v / osd * 1e-6);
    fmt::print("| cambium: set-up (topology, the sphere fitted) | {:.3f} | | |\n", r.setup);
    fmt::print(
        "| cambium: re-synthesis of the details as stored (no procedure) | {:.3f} | {:.2f} M | "
        "{:.2f} |\n",
        r.plainSynthesis, v / r.plainSynthesis * 1e-6, r.plainSynthesis / osd);
    fmt::print(
        "| **cambium: synthesis with the rock** | **{:.3f}** | **{:.2f} M** | **{:.2f}** |\n",
        r.synthesis, v / r.synthesis * 1e-6, r.synthesis / osd);
    fmt::print("| cambium: an edit of level {} ({} vertices) re-synthesised | {:.4f} | | |\n",
               r.editLevel, r.editVertices, r.edit);
    const double alone = r.aloneSynthesis + r.plainMesh, both = r.blendSynthesis + r.shadedMesh;
    fmt::print(
        "\nblending (a second rock across a plane) and the terrain shader, synthesis and the "
        "coloured mesh of a surface made once (as a sequence's frames):\n\n"
        "| shape | synthesis | mesh with colours | both | vs the rock alone |\n"
        "|---|---:|---:|---:|---:|\n"
        "| the rock alone | {:.3f} | {:.3f} | {:.3f} | 1.00 |\n"
        "| **blended and shaded** | {:.3f} | {:.3f} | **{:.3f}** | **{:.2f}** |\n",
        r.aloneSynthesis, r.plainMesh, alone, r.blendSynthesis, r.shadedMesh, both, both / alone);
    fmt::print("\nmesh -> level set at voxel size {:g} (half-width 3):\n\n", r.voxelSize);
    fmt::print(
        "| method | seconds (median) | active voxels | M voxels/s | vs OpenVDB |\n"
        "|---|---:|---:|---:|---:|\n");
    const double ov = double(r.openvdbVoxels) / r.openvdbBake,
                 cv = double(r.cambiumVoxels) / r.cambiumBake;
    fmt::print("| OpenVDB meshToLevelSet | {:.3f} | {} | {:.2f} | 1.00 |\n", r.openvdbBake,
               r.openvdbVoxels, ov * 1e-6);
    fmt::print("| **cambium bakeMeshLevelSet** | **{:.3f}** | {} | **{:.2f}** | **{:.2f}** |\n",
               r.cambiumBake, r.cambiumVoxels, cv * 1e-6, cv / ov);
    fmt::print(
        "\nwithin a voxel of the surface, {} voxels compared: {} ({:.2f} %) differ from "
        "meshToLevelSet by more than 0.05 voxel (at most {:.3f} voxel); of {} of those "
        "measured against every triangle, cambium has {} and meshToLevelSet {} within "
        "0.001 voxel\n",
        r.compared, r.beyondTolerance,
        100.0 * double(r.beyondTolerance) / double(std::max<size_t>(r.compared, 1)),
        r.largestDifference, r.bruteChecked, r.bruteCambium, r.bruteOpenVdb);
}

int runPreviewBenchCommand(const PreviewBenchRequest& req)
{
    checkPreviewBench(req);  // (before the table's header)
    fmt::print(
        "{}: the live preview, {} x {}, device {}; {} edits a year as the page makes them (a point "
        "of Gs2 sent to the page server), medians [min-max] in seconds\n\n",
        req.parameters, req.width, req.height, req.device == Device::OpenCL ? "opencl" : "cpu",
        req.edits);
    fmt::print(
        "| year | voxel size | leaves (reused) | first picture: command (peak MB) | in process | "
        "read and grow | compile | bake | render | write | push | edit to picture |\n"
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    std::fflush(stdout);
    auto stage = [](const PreviewBenchStage& s) {
        return fmt::format("{:.3f} [{:.3f}-{:.3f}]", s.median, s.min, s.max);
    };
    runPreviewBench(req, [&](const PreviewBenchYear& y) {
        fmt::print(
            "| {} | {:.4g} | {} ({}) | {:.2f} ({:.0f}) | {:.2f} | {} | {} | {} | {} | {} | {} | "
            "{} |\n",
            y.year, y.voxelSize, y.leaves, y.reusedLeaves, y.firstCommandSeconds,
            y.firstCommandPeakBytes / 1e6, y.firstInProcessSeconds, stage(y.read), stage(y.compile),
            stage(y.bake), stage(y.render), stage(y.write), stage(y.push), stage(y.editToPicture));
        std::fflush(stdout);
    });
    fmt::print(
        "\ngoals (issue 18): edit to picture <= 1 s at year 10 and <= 2 s at year 27; the first "
        "picture <= 3 s with a warm kernel cache\n");
    return 0;
}

/// The growth benchmarks' default parameter file: the bundled Populus.
const char* const kPopulus = CAMBIUM_SOURCE_DIR "/examples/populus/populus.json";

int runReadBenchCommand(const ReadBenchRequest& req)
{
    runReadBench(
        req,
        [&] {
            fmt::print(
                "Opening a baked frame, whole processes side by side ({} rounds, medians "
                "[min-max]; peak memory medians)\n",
                req.repeats);
            std::fflush(stdout);
        },
        [](const ReadBenchFile& f) {
            fmt::print("\n{} ({}, {:.0f} MB)\n\n| what | seconds | peak MB |\n|---|---:|---:|\n",
                       f.label, f.path, f.bytes / 1e6);
            for (const ReadBenchFile::Row& r : f.rows)
                fmt::print("| {} | {:.2f} [{:.2f}-{:.2f}] | {:.0f} |\n", r.what, r.run.seconds,
                           r.run.minSeconds, r.run.maxSeconds, r.run.peakBytes / 1e6);
            const ProcessSummary &all = f.rows[0].run, &surface = f.rows[1].run,
                                 &peer = f.rows[2].run, &render = f.rows[4].run,
                                 &mesh = f.rows[5].run;
            fmt::print(
                "\nratios (issue 30's goals): every grid / surface alone {:.2f} (<= 1.5); render / "
                "io::File every grid {:.2f} s (<= 0.6) and {:.2f} memory (<= 0.75); mesh / "
                "(io::File "
                "+ volumeToMesh) {:.2f} (<= 1.5); info {:.2f} s (<= 1)\n",
                all.seconds / surface.seconds, render.seconds / all.seconds,
                render.peakBytes / all.peakBytes, mesh.seconds / peer.seconds,
                f.rows[6].run.seconds);
            std::fflush(stdout);
        });
    return 0;
}

int runGrowthBenchCommand(const GrowthBenchRequest& req)
{
    checkGrowthYears(req.years, loadGrowthParameters(req.parameters), req.parameters);
    const int lastYear = *std::max_element(req.years.begin(), req.years.end());
    const char* paper =
        "\npaper 000, year 27: 181,692 primitives, 22,220 operators, 1.4 GB to ray trace the last "
        "frame\n";
    bool paperShown = false;
    GrowthBenchCallbacks callbacks;
    callbacks.setup = [&](const GrowthBenchSetup& s) {
        fmt::print(
            "{}: {} branches grown over {} years (global phase {:.3f} s); voxel size {:g}, {}, "
            "device {}\n\n",
            req.parameters, s.branches, s.years, s.globalSeconds, req.voxelSize,
            req.leaves ? "with leaves" : "no leaves", s.device);
        fmt::print(
            "| year | internodes | primitives | operators | model s | bake s | write s | active "
            "voxels | "
            "file MB | peak MB |\n|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
        std::fflush(stdout);  // (a log saw nothing while the first year baked)
    };
    callbacks.year = [&](const GrowthBenchYear& y) {
        fmt::print("| {} | {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {} | {:.0f} | {:.0f} |\n",
                   y.year, y.internodes, y.primitives, y.operators, y.modelSeconds, y.bakeSeconds,
                   y.writeSeconds, y.activeVoxels, y.fileBytes / 1e6, y.peakBytes / 1e6);
        if (y.year == lastYear && !paperShown)
            fmt::print("{}", paper);
        paperShown = paperShown || y.year == lastYear;
        std::fflush(stdout);
    };
    callbacks.bark = [&](const GrowthBenchBark& b) {
        fmt::print(
            "\nbark furrows (year {}, {} cones with bark), bake medians of 3 in turn: {:.2f} s "
            "with, {:.2f} s without ({:.2f}x); {} vs {} active voxels; grids {:.0f} vs {:.0f} MB "
            "({:.2f}x)\n",
            b.year, b.barkCones, b.withSeconds, b.withoutSeconds, b.withSeconds / b.withoutSeconds,
            b.withVoxels, b.withoutVoxels, b.withGridBytes / 1e6, b.withoutGridBytes / 1e6,
            b.withGridBytes / b.withoutGridBytes);
        std::fflush(stdout);
    };
    callbacks.sequence = [&](const GrowthBenchSequence& q) {
        fmt::print(
            "\nwhole sequence: {} frames ({:g} a year, {} reused whole; of the baked frames' {} "
            "leaves {:.0f} % "
            "unchanged, not sampled) in {:.1f} s, {} at once, {:.0f} MB of files, peak memory "
            "{:.0f} MB\n",
            q.frames, req.fpsPerYear, q.reused, q.leaves,
            100.0 * double(q.reusedLeaves) / double(std::max<size_t>(q.leaves, 1)), q.seconds,
            q.jobs, q.fileBytes / 1e6, q.peakBytes / 1e6);
    };
    const ScratchDirectory scratch(ScratchDirectory::temporaryPath("bench_growth"));
    runGrowthBench(req, scratch.path(), callbacks);
    return 0;
}

/// What the bench subcommands' options set.
struct BenchOptions {
    std::vector<std::string> cases = {"1000:0.01", "20000:0.005"};
    bool skipCpu = false;
    int repeats = 3;
    int internodes = 1000, width = 768, height = 768;
    double voxelSize = 0.01;
    GrowthBenchRequest growth;
    std::string growthDevice = "opencl";
    PreviewBenchRequest preview;
    ReadBenchRequest read;
    std::string previewDevice = "opencl";
};

/// bench bake: cambium against the dense evaluation and ParticlesToLevelSet.
void addBakeBench(CLI::App* bench, const std::shared_ptr<BenchOptions>& o, Action& action)
{
    auto* bake = bench->add_subcommand(
        "bake",
        "cambium's bake (OpenCL and CPU) against a naive dense evaluation and OpenVDB's "
        "ParticlesToLevelSet, on generated trees (the statistics of the "
        "benchmark generator, src/bench/tree_generator.cpp)");
    bake->add_option("--case", o->cases, "INTERNODES:VOXEL_SIZE (repeatable)")
        ->capture_default_str();
    bake->add_flag("--skip-cpu", o->skipCpu, "Leave out the CPU path");
    bake->add_option("--repeat", o->repeats,
                     "Runs of each method, in turn; the table shows medians")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    bake->callback([o, &action] {
        action = [o] {
            std::vector<BakeBenchCase> cases;
            // Every case checked before any is run (a voxel size of 0 ended
            // the process with an abort mid-table; stoi read "1e3" as 1).
            std::vector<std::pair<int, double>> parsed;
            for (const std::string& c : o->cases) {
                const auto colon = c.find(':');
                const std::string count = c.substr(0, colon),
                                  size = colon == std::string::npos ? "" : c.substr(colon + 1);
                char* end = nullptr;
                const double h = std::strtod(size.c_str(), &end);
                const long n = allDigits(count, 7) ? std::stol(count) : 0;
                if (colon == std::string::npos || n < 1 || n > kMaxBenchInternodes ||
                    size.empty() || *end != '\0' || writtenInHex(size.c_str(), end))
                    throw InputError(fmt::format(
                        "--case {}: expected INTERNODES:VOXEL_SIZE, a whole number from 1 to {} "
                        "and a decimal number",
                        c, kMaxBenchInternodes));
                checkVoxelSize(h, fmt::format("--case {}: the voxel size", c));
                parsed.emplace_back(int(n), h);
            }
            constexpr double kBakesPerRepeat = 5.0;
            const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
            double seconds = 0.0;
            for (const auto& [n, h] : parsed) {
                BakeBenchCase bc;
                BenchTree tree = benchTree(n);
                bc.text = std::move(tree.text);
                bc.skeleton = std::move(tree.skeleton);
                bc.label = fmt::format("tree of {} internodes", n);
                bc.voxelSize = h;
                // (cambium's last grids, the bake in flight and the peer's
                // rasterisation, counted as two, held at once: a case past
                // memory ran silently to 5.6 GB and on)
                const VoxelPlan plan = checkBakeFits(
                    FieldProgram::compile(skeletonToBlend(bc.skeleton)), h, bc.label, 4.0);
                seconds += estimateBakeSeconds(plan.bandVoxels, cores) * kBakesPerRepeat *
                           double(o->repeats);
                cases.push_back(std::move(bc));
            }
            // Each case's bakes in turn, in process (two of cambium's, the
            // peer's) and as whole processes (cambium's and the peer's).
            if (seconds > 10.0)
                printNotice(fmt::format("the {} case{} bake about {} times each: roughly {} here",
                                        cases.size(), cases.size() == 1 ? "" : "s",
                                        int(kBakesPerRepeat) * o->repeats,
                                        formatDuration(seconds)));
            runBakeBench(cases, o->skipCpu, o->repeats, printBakeTable);
            return 0;
        };
    });
}

/// bench mesh and bench render, on a baked benchmark tree.
void addUseBenches(CLI::App* bench, const std::shared_ptr<BenchOptions>& o, Action& action)
{
    auto useOptions = [o](CLI::App* cmd) {
        cmd->add_option("--internodes", o->internodes, "Internodes of the generated tree")
            ->capture_default_str()
            ->check(CLI::Range(1, kMaxBenchInternodes));
        cmd->add_option("--voxel-size", o->voxelSize, "Voxel size of the bake")
            ->capture_default_str()
            ->check(CLI::Range(kMinVoxelSize, kMaxVoxelSize));
        cmd->add_option("--repeat", o->repeats, "Runs of each method; the table shows medians")
            ->capture_default_str()
            ->check(CLI::Range(1, 100));
    };
    auto label = [](int n) { return fmt::format("tree of {} internodes", n); };
    auto* mesh =
        bench->add_subcommand("mesh", "Meshing a baked benchmark tree, against paper 002's figure");
    useOptions(mesh);
    mesh->callback([o, label, &action] {
        action = [o, label] {
            printMeshTable(runMeshBench(benchTree(o->internodes).skeleton, label(o->internodes),
                                        o->voxelSize, o->repeats));
            return 0;
        };
    });
    auto* render = bench->add_subcommand("render",
                                         "Rendering a baked benchmark tree: the OpenCL and CPU "
                                         "level-set marches and Embree on its mesh, "
                                         "against the papers' figures");
    useOptions(render);
    render->add_option("--width", o->width, "Image width")
        ->capture_default_str()
        ->check(CLI::Range(1, 16384));
    render->add_option("--height", o->height, "Image height")
        ->capture_default_str()
        ->check(CLI::Range(1, 16384));
    render->callback([o, label, &action] {
        action = [o, label] {
            checkPicture(o->width, o->height, 1);  // (16384^2 ran into the memory limit)
            printRenderTable(runRenderBench(benchTree(o->internodes).skeleton, label(o->internodes),
                                            o->voxelSize, o->width, o->height, o->repeats));
            return 0;
        };
    });
}

/// bench shape: paper 004's synthesis and mesh -> level set.
void addShapeBench(CLI::App* bench, Action& action)
{
    auto shapeRequest = std::make_shared<ShapeBenchRequest>();
    auto* shape = bench->add_subcommand(
        "shape",
        "Multi-scale shape synthesis (paper 004) against OpenSubdiv's uniform "
        "refinement, and cambium's mesh -> level set against OpenVDB's meshToLevelSet");
    shape->add_option("--levels", shapeRequest->levels, "Levels of the rock cube-sphere")
        ->capture_default_str()
        ->check(CLI::Range(1, 10));
    shape
        ->add_option("--edit-level", shapeRequest->editLevel,
                     "Level of the edit re-synthesised (on a shape of that many levels)")
        ->capture_default_str()
        ->check(CLI::Range(1, 10));
    shape->add_option("--voxel-size", shapeRequest->voxelSize, "Voxel size of the level sets")
        ->capture_default_str()
        ->check(CLI::Range(1e-4, 1.0));
    shape
        ->add_option("--repeat", shapeRequest->repeats,
                     "Runs of each method, in turn; the table shows medians")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    shape->callback([shapeRequest, &action] {
        action = [shapeRequest] {
            printShapeTable(runShapeBench(*shapeRequest, [](const std::string& step) {
                fmt::print(stderr, "  {}\n", step);
            }));
            return 0;
        };
    });
}

/// bench growth: the growth model year by year and a whole sequence.
void addGrowthBench(CLI::App* bench, const std::shared_ptr<BenchOptions>& o, Action& action)
{
    GrowthBenchRequest& g = o->growth;
    g.parameters = kPopulus;
    auto* growth = bench->add_subcommand("growth",
                                         "The growth model's tree by year (internodes, primitives, "
                                         "operators, bake time and memory) and a "
                                         "whole sequence, against paper 000's year 27");
    growth->add_option("--parameters", g.parameters, "Growth parameter file")
        ->capture_default_str();
    growth->add_option("--years", g.years, "Years to measure")
        ->capture_default_str()
        ->delimiter(',');
    growth->add_option("--voxel-size", g.voxelSize, "Voxel size")
        ->capture_default_str()
        ->check(CLI::Range(kMinVoxelSize, kMaxVoxelSize));
    growth
        ->add_option("--fps-per-year", g.fpsPerYear,
                     "Frame rate of the whole sequence (0: leave it out)")
        ->capture_default_str();
    growth->add_option("--device", o->growthDevice, "opencl or cpu")->capture_default_str();
    growth->add_flag("--leaves", g.leaves, "Grow leaves (frames at year ends have none)");
    growth->callback([o, &action] {
        action = [o] {
            o->growth.device = parseDevice(o->growthDevice);
            return runGrowthBenchCommand(o->growth);
        };
    });
}

/// bench read: opening a baked frame, by OpenVDB and by cambium's commands.
void addReadBench(CLI::App* bench, const std::shared_ptr<BenchOptions>& o, Action& action)
{
    ReadBenchRequest& rb = o->read;
    rb.parameters = kPopulus;
    auto* read = bench->add_subcommand(
        "read",
        "Opening a baked frame: OpenVDB's io::File (every grid, the surface, with volumeToMesh) "
        "against cambium's reader, render, mesh and info, as whole processes");
    read->add_option("--file", rb.files,
                     "A .vdb to measure (repeatable; default: the Populus "
                     "baked with its colour on the band and on the shell)");
    read->add_option("--parameters", rb.parameters, "Growth parameter file of the default frame")
        ->capture_default_str();
    read->add_option("--year", rb.year, "Year of the default frame")->capture_default_str();
    read->add_option("--voxel-size", rb.voxelSize, "Voxel size of the default frame")
        ->capture_default_str()
        ->check(CLI::Range(kMinVoxelSize, kMaxVoxelSize));
    read->add_option("--repeat", rb.repeats, "Rounds of every command")
        ->capture_default_str()
        ->check(CLI::Range(1, 100));
    read->callback([o, &action] { action = [o] { return runReadBenchCommand(o->read); }; });
}

/// bench preview: the live preview's first picture and edits.
void addPreviewBench(CLI::App* bench, const std::shared_ptr<BenchOptions>& o, Action& action)
{
    PreviewBenchRequest& pv = o->preview;
    pv.parameters = kPopulus;
    auto* preview = bench->add_subcommand(
        "preview",
        "The live preview (docs/preview.md): the first picture of a whole command, then edits "
        "made as its page makes them, stage by stage, against issue 18's goals");
    preview->add_option("--parameters", pv.parameters, "Growth parameter file")
        ->capture_default_str();
    preview->add_option("--years", pv.years, "Years to measure")
        ->capture_default_str()
        ->delimiter(',');
    preview->add_option("--edits", pv.edits, "Edits a year")->capture_default_str();
    preview->add_option("--width", pv.width, "Picture width")->capture_default_str();
    preview->add_option("--height", pv.height, "Picture height")->capture_default_str();
    preview->add_option("--device", o->previewDevice, "The bake's device: opencl or cpu")
        ->capture_default_str();
    preview->callback([o, &action] {
        action = [o] {
            o->preview.device = parseDevice(o->previewDevice);
            return runPreviewBenchCommand(o->preview);
        };
    });
}

}  // namespace

void addBenchCommand(CLI::App& app, Action& action)
{
    auto o = std::make_shared<BenchOptions>();
    auto* bench = app.add_subcommand("bench", "Throughput benchmarks, side by side in one run");
    bench->require_subcommand(1);
    addBakeBench(bench, o, action);
    addUseBenches(bench, o, action);
    addShapeBench(bench, action);
    addGrowthBench(bench, o, action);
    addReadBench(bench, o, action);
    addPreviewBench(bench, o, action);
}

}  // namespace cambium
