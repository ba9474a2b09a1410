// cambium shape — a shape file (docs/shape-format.md) synthesised into a mesh
// or baked into a level set.
#include "app/app.h"
#include "core/frames.h"

#include "core/system.h"
#include "shape/shape_job.h"

#include <fmt/format.h>

namespace cambium {

namespace {

struct ShapeFlags {
    ShapeRequest request;
    double voxelSize = 0.0;
    CLI::Option* voxelOption = nullptr;
    std::string device = "opencl", colour = "shell";
};

int runShapeCommand(ShapeFlags& f)
{
    if (f.voxelOption->count())
        f.request.voxelSize = f.voxelSize;
    f.request.device = parseDevice(f.device);
    f.request.colour = parseColourExtent(f.colour);
    if (!f.request.frames.empty())  // (each frame's file read too)
        notePlanning(parseFrames(f.request.frames).size());
    ProgressBar bar;
    ShapeCallbacks cb;
    cb.progress = [&](const char* stage, double fraction) { bar(stage, fraction); };
    cb.notice = [&](const std::string& line) {
        bar.clear();
        printNotice(line);
    };
    cb.frameDone = [&](const ShapeFrame& fr) {
        bar.clear();
        if (fr.skipped)
            fmt::print("frame {}: {} finished before (--resume)\n", fr.frame, fr.path);
        else
            fmt::print("frame {}: {}, {} active voxels, {:.2f} s\n", fr.frame, fr.path,
                       formatCount(double(fr.activeVoxels)), fr.seconds);
    };
    const ShapeReport r = runShape(f.request, cb);
    bar.clear();
    if (!r.frames.empty()) {
        fmt::print(
            "shape {}: {} frames of {} levels ({} vertices), voxel size {:.6g}{}; synthesis "
            "{:.2f} s, bake {:.2f} s, write {:.2f} s in all; peak memory {}\n",
            f.request.input, r.frames.size(), r.levels, formatCount(double(r.vertices)),
            r.voxelSize, r.autoVoxelSize ? " (automatic, from the first frame)" : "",
            r.synthesisSeconds, r.bakeSeconds, r.writeSeconds, formatBytes(r.peakMemoryBytes));
        return 0;
    }
    fmt::print(
        "shape {}: {} levels, {} vertices, {} faces, synthesised in {:.3f} s; area {:.6g}, "
        "volume {:.6g}\n",
        f.request.input, r.levels, formatCount(double(r.vertices)), formatCount(double(r.faces)),
        r.synthesisSeconds, r.area, r.volume);
    if (r.levelSet)
        fmt::print(
            "baked {}: voxel size {:.6g}{}, {} active voxels in {} leaves, {:.2f} s; "
            "written in {:.2f} s; peak memory {}\n",
            f.request.output, r.voxelSize, r.autoVoxelSize ? " (automatic)" : "",
            formatCount(double(r.stats.activeVoxels)), formatCount(double(r.stats.activeLeaves)),
            r.bakeSeconds, r.writeSeconds, formatBytes(r.peakMemoryBytes));
    else
        fmt::print("wrote {} in {:.2f} s; peak memory {}\n", f.request.output, r.writeSeconds,
                   formatBytes(r.peakMemoryBytes));
    return 0;
}

}  // namespace

void addShapeCommand(CLI::App& app, Action& action)
{
    auto f = std::make_shared<ShapeFlags>();
    auto* cmd = app.add_subcommand("shape",
                                   "Synthesise a multi-scale subdivision shape (paper 004; "
                                   "docs/shape-format.md) into a mesh or a level set");
    cmd->add_option("shape", f->request.input, "Shape file (.json)")->required();
    cmd->add_option("-o,--output", f->request.output,
                    "Output: .vdb (a level set with Cd), .obj or .ply (the finest level's quads)")
        ->required();
    f->voxelOption = cmd->add_option("--voxel-size", f->voxelSize,
                                     "Voxel size of a .vdb (default: 512 voxels across the shape)");
    cmd->add_option("--levels", f->request.levels, "Subdivision levels (0-15; default: the file's)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--half-width", f->request.halfWidth, "Narrow-band half-width in voxels")
        ->capture_default_str();
    cmd->add_flag("--fog", f->request.fog, "Also write a 'density' fog volume");
    cmd->add_flag("--half", f->request.half, "Store the grids' floats as 16-bit halves");
    cmd->add_option("--colour", f->colour,
                    "Where a .vdb keeps the colour grid Cd: shell (the voxels a lookup on the "
                    "surface reads), band (every band voxel) or none")
        ->capture_default_str();
    auto* timeOpt =
        cmd->add_option("--time", f->request.time,
                        "Animation time of the output: keyframed numbers take their value at it")
            ->capture_default_str();
    // (a sequence's frame f is at time f: --time was ignored)
    cmd->add_option("--frames", f->request.frames,
                    "A sequence: frames FIRST-LAST[:STEP] (frame f at time f) into -o with a run "
                    "of '#', e.g. -o out/shape.####.vdb")
        ->excludes(timeOpt);
    cmd->add_flag("--resume", f->request.resume,
                  "Keep the frames an interrupted run of the same sequence finished");
    cmd->add_option("--device", f->device,
                    "opencl or cpu: the bake of a captured model (\"base\": {\"type\": \"model\"})")
        ->capture_default_str();
    cmd->callback([f, &action] { action = [f] { return runShapeCommand(*f); }; });
}

}  // namespace cambium
