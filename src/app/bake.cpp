// cambium bake — a model into a narrow-band level set (.vdb), or a growth
// model into a frame sequence (--frames; app/sequence.cpp reports it).
#include "app/app.h"

#include "core/error.h"

#include "bake/bake.h"
#include "bake/sequence.h"
#include "farm/slurm.h"
#include "core/files.h"
#include "core/frames.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <thread>

namespace cambium {

int runBakeCommand(const BakeRequest& req, bool timings)
{
    ProgressBar bar;
    BakeCallbacks callbacks;
    callbacks.progress = [&](const char* stage, double f) { bar(stage, f); };
    callbacks.notice = [&](const std::string& line) {
        bar.clear();
        printNotice(line);
    };
    const BakeReport r = runBake(req, callbacks);
    bar.clear();
    const BakeStats& s = r.stats;
    fmt::print(
        "baked {}: {} leaves ({} sampled), {} active voxels, {:.2f} s ({:.3g} M voxels/s; topology "
        "{:.2f} s, "
        "sampling {:.2f} s, assembly {:.2f} s), peak memory {:.0f} MB, voxel size {:g}{}, "
        "device {}, {:.1f} instructions per leaf\n",
        req.output, formatCount(double(s.activeLeaves)), formatCount(double(s.candidateLeaves)),
        formatCount(double(s.activeVoxels)), s.seconds, double(s.activeVoxels) / s.seconds * 1e-6,
        s.topologySeconds, s.samplingSeconds, s.assemblySeconds, r.peakMemoryBytes / 1e6,
        s.voxelSize,
        r.autoVoxelSize ? fmt::format(" (auto: 512 voxels across {:.4g})", r.extent) : "", r.device,
        s.meanProgramLength);
    if (timings)
        printTimings(s);
    return 0;
}

namespace {

/// The lines of --dry-run that every plan has: time, memory and disk.
void printResources(double bandVoxels, double memory, int atOnce, double file,
                    const std::string& output)
{
    const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
    fmt::print("  time: roughly {} of baking on this machine's {} cores\n",
               formatDuration(estimateBakeSeconds(bandVoxels, cores)), cores);
    fmt::print("  memory: about {} a bake{}, of {} available\n", formatBytes(memory),
               atOnce > 1 ? fmt::format(", {} at once", atOnce) : std::string(),
               formatBytes(availableMemoryBytes()));
    const double free = freeDiskBytes(output);
    fmt::print(
        "  disk: at least about {}{}\n", formatBytes(file),
        std::isfinite(free) ? fmt::format(", of {} free", formatBytes(free)) : std::string());
    fmt::print("nothing baked or written (--dry-run)\n");
}

std::string voxelLine(double h, bool automatic, const std::string& across)
{
    return fmt::format(
        "  voxel size {:g}{}\n", h,
        automatic ? fmt::format(" (auto: 512 voxels across {})", across) : std::string());
}

int printBakePlan(const BakeRequest& req, const VoxelPlan& plan)
{
    fmt::print("plan: bake {} into {}\n{}", req.input, req.output,
               voxelLine(plan.voxelSize, plan.automatic, fmt::format("{:.4g}", plan.extent)));
    fmt::print("  band: about {} voxels (from the primitives' areas)\n",
               formatCount(plan.bandVoxels));
    printResources(plan.bandVoxels, plan.bytes, 1, plan.fileBytes, req.output);
    return 0;
}

int printSequencePlan(const SequencePlan& plan)
{
    const BakeRequest& req = plan.request.bake;
    fmt::print("plan: bake {} frames of {} ({} to {}, years {:g} to {:g}) into {} ({} to {})\n",
               formatCount(double(plan.frames.size())), req.input, plan.frames.front(),
               plan.frames.back(), plan.times.front(), plan.times.back(), req.output,
               plan.paths.front(), plan.paths.back());
    fmt::print("{}", voxelLine(plan.voxelSize, plan.autoVoxelSize, "the last frame"));
    fmt::print("  band: about {} voxels in all frames\n", formatCount(plan.bandVoxels));
    printResources(plan.bandVoxels, plan.bytesPerFrame, sequenceJobs(plan, plan.frames.size()),
                   plan.fileBytes, req.output);
    return 0;
}

int printTilePlan(const BakeRequest& req, const TilePlan& plan)
{
    // (one tile: the bake runs as a plain one, as the dry run says)
    if (plan.tiles == 1)
        fmt::print(
            "plan: bake {} into {} as one bake (the frame's estimate is within "
            "--max-memory)\n",
            req.input, req.output);
    else
        fmt::print("plan: bake {} into {} as {} tiles, merged\n", req.input, req.output,
                   plan.tiles);
    fmt::print("  voxel size {:g}; the frame's memory about {}\n", plan.voxelSize,
               formatBytes(plan.frameBytes));
    printResources(plan.bandVoxels, plan.tileBytes, 1, plan.fileBytes, req.output);
    return 0;
}

/// What bake's options set.
struct BakeCommandOptions {
    SequenceRequest sequence;  // .bake: a single bake's request
    ModelFlags model;
    double voxelSize = 0.0;
    std::string device = "opencl";
    bool timings = false;
    std::string colouring, colour = "shell";
    SlurmFlags slurm;
    int tiles = 0;
    std::string tile, maxMemory;
};

/// --tile K/N: tile K - 1 of N.
BandTile parseTileOption(const std::string& t)
{
    const size_t slash = t.find('/');
    int k = 0, count = 0;
    auto whole = [&](size_t from, size_t to, int& v) {
        const auto r = std::from_chars(t.data() + from, t.data() + to, v);
        return from < to && r.ec == std::errc() && r.ptr == t.data() + to;
    };
    if (slash == std::string::npos || !whole(0, slash, k) || !whole(slash + 1, t.size(), count) ||
        count < 1 || count > 4096 || k < 1 || k > count)
        throw InputError(fmt::format("--tile must be K/N with 1 <= K <= N <= 4096 (got '{}')", t));
    return {k - 1, count};
}

/// The bake command once its options are parsed: checks them, then bakes,
/// plans or submits what they ask for.
int runBakeOptions(const std::shared_ptr<BakeCommandOptions>& o, bool voxelGiven)
{
    SequenceRequest& request = o->sequence;
    BakeRequest& req = request.bake;
    if (voxelGiven)
        req.voxelSize = o->voxelSize;
    // In the order the checks ran before the commands parsed options:
    // frames, half-width, device, output, the model options.
    const bool sequence = !request.frames.empty();
    const size_t frames = sequence ? parseFrames(request.frames).size() : 0;
    notePlanning(frames);  // (up to 64 of the frames' trees built for the disk estimate)
    const bool tiled = o->tiles > 0 || !o->maxMemory.empty();
    if (o->slurm.slurm && !sequence && !tiled)
        throw InputError(
            "--slurm bakes a sequence (--frames) or one frame's tiles (--tiles or "
            "--max-memory): it needs one of them");
    if (sequence && (tiled || !o->tile.empty()))
        throw InputError("--tiles, --tile and --max-memory bake one frame: not with --frames");
    const double maxMemory =
        o->maxMemory.empty() ? 0.0 : parseByteSize(o->maxMemory, "--max-memory");
    if (!o->tile.empty())
        req.tile = parseTileOption(o->tile);
    checkBakeOptions(req);
    req.colour = parseColourExtent(o->colour);
    if (!o->colouring.empty())  // (kBarkColourings: coherent first)
        req.barkCoherent = optionChoice(o->colouring, kBarkColourings, "--bark-colouring") == 0;
    if (!req.barkPhoto.empty())
        checkInputFile(req.barkPhoto, "bark photo");
    req.device = parseDevice(o->device);
    if (!sequence)
        checkOutputPath(req.output);
    if (req.tile.count > 0)  // (a farm's tile: sweep 26)
        checkPartIsNoLink(req.output, "tile of a farm");
    fileFormat(req.output, {"vdb"}, "output");
    checkOutputIsNoInput(req.output, bakeInputFiles(req));
    req.model = o->model.options();
    const bool timings = timingsAsked(o->timings);
    if (req.tile.count > 0)  // (what a farm's final job checks the tile by)
        req.key = tileFarmKey(req, req.tile.count);
    if (o->slurm.slurm && tiled && o->slurm.chunk != 1)
        throw InputError("--chunk counts frames: a frame's tiles are a task each");
    if (o->slurm.dryRun && !o->slurm.slurm) {
        if (tiled)
            return printTilePlan(req, planTiles(req, o->tiles, maxMemory, true));
        return sequence ? printSequencePlan(planSequence(request))
                        : printBakePlan(req, planBake(req));
    }
    if (o->slurm.slurm && tiled)
        return runTileFarmCommand(req, planTiles(req, o->tiles, maxMemory, false), o->slurm);
    if (o->slurm.slurm)
        return runSlurmCommand(request, o->slurm);
    if (tiled)
        return runTiledBakeCommand(req, o->tiles, maxMemory, timings);
    return sequence ? runSequenceCommand(request, timings) : runBakeCommand(req, timings);
}

}  // namespace

void addBakeCommand(CLI::App& app, Action& action)
{
    auto o = std::make_shared<BakeCommandOptions>();
    BakeRequest& bake = o->sequence.bake;
    auto* cmd = app.add_subcommand("bake",
                                   "Bake a scene, L-system, skeleton or grown tree into a "
                                   "narrow-band OpenVDB level set (.vdb), or a "
                                   "growing tree into a sequence of them");
    cmd->add_option("input", bake.input,
                    "Scene (.json), growth parameters (.json with \"curves\"), L-system (.l) or "
                    "skeleton file")
        ->required();
    addModelFlags(cmd, o->model);
    cmd->add_option("-o,--output", bake.output, "Output .vdb file")->required();
    auto* voxelOpt = cmd->add_option("--voxel-size", o->voxelSize,
                                     "Voxel size in world units (default: 512 voxels across the "
                                     "surface bounds)");
    cmd->add_option("--half-width", bake.halfWidth, "Narrow-band half-width in voxels")
        ->capture_default_str();
    addMinRadiusFlag(cmd, bake.minRadius);
    cmd->add_option("--device", o->device, "opencl or cpu")->capture_default_str();
    cmd->add_flag("--fog", bake.fog, "Also write a `density` fog volume");
    cmd->add_flag("--half", bake.half, "Store floats as 16-bit halves");
    cmd->add_option("--colour", o->colour,
                    "Where the colour grid Cd is kept: shell (the voxels a lookup on the surface "
                    "reads, leaves of one colour as tiles), band (every band voxel) or none")
        ->capture_default_str();
    cmd->add_option("--threads", bake.threads, "Worker threads (default: all cores)")
        ->check(CLI::Range(1, 4096));
    cmd->add_option("--bark-photo", bake.barkPhoto,
                    "A photo (any format OpenImageIO reads) whose colour histogram colours the "
                    "bark (paper 002 section 3.5); default: the model's \"bark.photo\"");
    cmd->add_option("--bark-colouring", o->colouring,
                    "coherent (smooth patches that follow the bark) or random (each voxel drawn "
                    "alone, as paper 002); default: the model's, else coherent");
    cmd->add_flag(
        "--timings", o->timings,
        "Print the time of each stage of the bake on stderr (also with CAMBIUM_TIMING set)");
    SequenceRequest& seq = o->sequence;
    auto* framesOpt =
        cmd->add_option(
               "--frames", seq.frames,
               "Growth parameter files: bake frames FIRST-LAST[:STEP] into -o with a run of '#' "
               "(out/populus.####.vdb), frame f at year f / fps-per-year")
            ->excludes(o->model.timeOption);
    // (each for sequences only: given to a single bake they were ignored)
    cmd->add_option("--fps-per-year", seq.fpsPerYear, "Frames per year of growth")
        ->capture_default_str()
        ->needs(framesOpt);
    cmd->add_flag("--resume", seq.resume,
                  "Keep the frames an interrupted run of the same bake finished")
        ->needs(framesOpt);
    cmd->add_option("--jobs", seq.jobs,
                    "Frames baked at once (default: as many as cores and memory allow)")
        ->check(CLI::Range(1, 4096))
        ->needs(framesOpt);
    auto* slurmOpt = cmd->add_flag(
        "--slurm", o->slurm.slurm,
        "With --frames: bake the sequence as a Slurm job array (docs/farm.md), one task per "
        "chunk of frames; with --tiles or --max-memory: the frame's tiles as one, merged by its "
        "final job");
    cmd->add_option("--chunk", o->slurm.chunk,
                    "With --slurm and --frames: at least this many frames a task (whole years "
                    "of growth)")
        ->check(CLI::Range(1, 1000000))
        ->needs(slurmOpt);
    cmd->add_option("--throttle", o->slurm.throttle,
                    "With --slurm: at most this many tasks at once")
        ->check(CLI::Range(1, 100000))
        ->needs(slurmOpt);
    cmd->add_option("--retries", o->slurm.retries,
                    "With --slurm: times the final job submits a failed chunk again (not one "
                    "that failed for bad input)")
        ->check(CLI::Range(0, 100))
        ->capture_default_str()
        ->needs(slurmOpt);
    cmd->add_option("--slurm-arg", o->slurm.sbatchArgs,
                    "With --slurm: one more sbatch option for the array and its final job, e.g. "
                    "--slurm-arg=--partition=render (repeatable)")
        ->needs(slurmOpt);
    cmd->add_flag("--wait", o->slurm.wait,
                  "With --slurm: follow the array to its end, a line per chunk")
        ->needs(slurmOpt);
    cmd->add_flag("--dry-run", o->slurm.dryRun,
                  "Print the plan (voxel size, memory, disk; with --slurm the batch scripts) "
                  "and bake or submit nothing");
    auto* tilesOpt =
        cmd->add_option("--tiles", o->tiles,
                        "Bake the frame as this many spatial tiles, each by a process of its own "
                        "(its memory its tile's), then merge them into -o: the same grids")
            ->check(CLI::Range(1, 4096));
    auto* memoryOpt = cmd->add_option(
        "--max-memory", o->maxMemory,
        "A tile's share of the frame's estimated memory at most this (8G = 8 GB = "
        "8e9 bytes, "
        "512M): with --tiles "
        "a check, alone as many tiles as that takes (one bake when the frame fits)");
    cmd->add_option("--tile", o->tile,
                    "K/N: bake tile K of N only (what --tiles runs; docs/farm.md)")
        ->excludes(tilesOpt)
        ->excludes(memoryOpt);
    cmd->callback([o, voxelOpt, &action] {
        action = [o, voxelOpt] { return runBakeOptions(o, voxelOpt->count() > 0); };
    });
}

}  // namespace cambium
