// cambium bake MODEL -o OUT.vdb --tiles N | --max-memory SIZE: one frame
// baked as N spatial tiles (bake/tiles.h), each by a cambium process of its
// own (`--tile K/N`, so that its memory is its tile's), one after another,
// then merged into OUT.vdb: the grids the whole bake makes.
#include "app/app.h"

#include "bake/bake.h"
#include "bake/tiles.h"
#include "bake/topology.h"
#include "core/error.h"
#include "core/files.h"
#include "core/process.h"
#include "core/clock.h"
#include "farm/slurm.h"
#include "field/program.h"
#include "io/vdb.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <unistd.h>

namespace cambium {

namespace fs = std::filesystem;

TilePlan planTiles(const BakeRequest& req, int tiles, double maxMemory, bool here)
{
    checkBakeOptions(req);
    checkOutputPath(req.output);
    checkOutputIsNoInput(req.output, bakeInputFiles(req));
    if (req.fog)
        throw InputError(
            "--tiles: a fog volume (--fog) is made from the whole grid's values; "
            "bake it without --tiles or --max-memory");
    BlobTree tree = loadModel(req.input, req.model);
    const BarkPaint paint = barkPaint(req, tree);
    if (paint.histogram)
        throw InputError(fmt::format(
            "--tiles: bark coloured from a photo ({}) is drawn over the whole grid's values; bake "
            "it without --tiles or --max-memory",
            paint.photo));
    // The frame's voxel size and estimate (the machine's memory checked for
    // a tile's share below, once the tiles are known), of the model as each
    // tile's bake thickens it.
    BakeRequest probe = req;
    probe.tile.count = 1 << 20;
    const PlannedModel planned = planModel(tree, probe);
    const FieldProgram& program = planned.program;
    const VoxelPlan& whole = planned.plan;
    if (tiles == 0) {
        // --max-memory alone: enough tiles for a tile's share to fit.
        // (Counted as a double: a tiny limit must not overflow an int.)
        const double need = std::ceil(1.5 * whole.bytes / maxMemory - 1e-9);
        if (need > 4096.0)
            throw InputError(fmt::format(
                "--max-memory {}: the frame's estimate is {}: it would take {:.0f} tiles (4096 at "
                "most); use a larger --voxel-size or --max-memory",
                formatBytes(maxMemory), formatBytes(whole.bytes), need));
        tiles = whole.bytes <= maxMemory ? 1 : std::max(2, int(need));
    } else if (maxMemory > 0.0 && whole.bytes * tileMemoryShare(tiles) > maxMemory) {
        throw InputError(
            fmt::format("--tiles {}: a tile's share of the frame's estimate ({}) is about {}, over "
                        "--max-memory {}: use more tiles",
                        tiles, formatBytes(whole.bytes),
                        formatBytes(whole.bytes * tileMemoryShare(tiles)), formatBytes(maxMemory)));
    }
    // A tile is a run of 128-voxel layers: tiles beyond the layers would be
    // empty, each a process for nothing (4096 of them on a small frame).
    const long long layers = bandLayers(program, whole.voxelSize, req.halfWidth);
    if (tiles > layers) {
        if (maxMemory > 0.0 && whole.bytes * tileMemoryShare(int(layers)) > maxMemory)
            throw InputError(fmt::format(
                "--max-memory {}: the frame's estimate is {}, and its {} tiles (one for each "
                "128-voxel layer across it) would still need about {} each; use a larger "
                "--voxel-size or --max-memory",
                formatBytes(maxMemory), formatBytes(whole.bytes), layers,
                formatBytes(whole.bytes * tileMemoryShare(int(layers)))));
        printNotice(
            fmt::format("{} tiles: the frame spans {} layers of 128 voxels across its "
                        "longest side, and a tile is a run of them: {} tiles",
                        tiles, layers, layers));
        tiles = int(layers);
    }
    if (here) {
        BakeRequest tiled = req;
        tiled.voxelSize = whole.voxelSize;
        tiled.tile.count = tiles;
        // (at one tile a layer, "use more than 6 --tiles" advised the impossible)
        tiled.tilesOffered = tiles < layers;
        planVoxelSize(program, tiled);  // (a tile's share must fit this machine)
    }
    TilePlan plan;
    plan.voxelSize = whole.voxelSize;
    plan.tiles = tiles;
    plan.frameBytes = whole.bytes;
    plan.tileBytes = whole.bytes * tileMemoryShare(tiles);
    plan.fileBytes = whole.fileBytes;
    plan.bandVoxels = whole.bandVoxels;
    checkDiskSpace(req.output, 2.0 * whole.fileBytes,
                   fmt::format("the tiles of {} and their merge", req.output));
    plan.threshold = tree.threshold();
    plan.time = tree.time();
    return plan;
}

int runTiledBakeCommand(const BakeRequest& req, int tiles, double maxMemory, bool timings)
{
    const auto start = Clock::now();
    // What a killed tiled bake of this output left (SIGKILL: no handler
    // ran), removed.
    const fs::path output = fs::absolute(req.output);
    const std::string prefix =
        (output.parent_path() / fmt::format(".{}.tiles-", output.filename().string())).string();
    for (const std::string& stale : staleDirectories(prefix)) {
        std::error_code ec;
        if (fs::remove_all(stale, ec) > 0 && !ec)
            printNotice(fmt::format("removed {}, the tiles an interrupted run left", stale));
    }
    const TilePlan plan = planTiles(req, tiles, maxMemory, true);
    tiles = plan.tiles;
    if (tiles == 1) {
        if (maxMemory > 0.0)
            printNotice(fmt::format("the frame's estimate ({}) is within --max-memory {}: one bake",
                                    formatBytes(plan.frameBytes), formatBytes(maxMemory)));
        BakeRequest one = req;
        one.voxelSize = plan.voxelSize;
        return runBakeCommand(one, timings);
    }
    // The tiles' files in a directory beside the output, removed whatever
    // happens.
    const ScratchDirectory scratch(prefix + std::to_string(::getpid()));
    const fs::path dir = scratch.path();
    const std::string exe = (fs::path(executableDirectory()) / "cambium").string();
    std::vector<std::string> files;
    double largest = 0.0;
    for (int k = 0; k < tiles; ++k) {
        BakeRequest one = req;
        one.output = (dir / fmt::format("tile-{}.vdb", k + 1)).string();
        // Floats in the tiles' files, whatever --half: the merge takes each
        // leaf's end signs from its values (a float just below zero is half
        // -0.0, not negative) and packs halves itself.
        one.half = false;
        std::vector<std::string> argv = {exe};
        for (const std::string& a : bakeArguments(one, plan.voxelSize))
            argv.push_back(a);
        argv.insert(argv.end(), {"--tile", fmt::format("{}/{}", k + 1, tiles)});
        const ChildRun run =
            runChild(argv, {"", (dir / fmt::format("tile-{}.peak", k + 1)).string()});
        const int status = run.status;
        if (status == 2)
            throw InputError(
                fmt::format("tile {}/{}: its bake refused its input (above)", k + 1, tiles));
        if (status != 0)
            throw std::runtime_error(
                fmt::format("tile {}/{}: its bake failed (exit {})", k + 1, tiles, status));
        largest = std::max(largest, run.peakBytes);
        fmt::print("tile {}/{}: peak memory {:.0f} MB{}, {:.2f} s\n", k + 1, tiles,
                   run.peakBytes / 1e6,
                   run.peakExact ? "" : " at most (GNU time, /usr/bin/time, measures it exactly)",
                   run.seconds);
        std::fflush(stdout);
        files.push_back(one.output);
    }
    const auto t = Clock::now();
    BakedGrids grids = mergeTiles(files, req.half);
    checkSomethingBaked(grids.stats, req);
    writeVdb(grids, req.output, bakeFileInfo(req, plan.threshold, plan.time));
    const BakeStats& s = grids.stats;
    fmt::print(
        "baked {}: {} tiles merged, {} leaves, {} active voxels, voxel size {:g}, {:.2f} s (merge "
        "{:.2f} s); peak memory a tile {:.0f} MB at most (the frame's estimate: {}), the merge "
        "{:.0f} MB\n",
        req.output, tiles, formatCount(double(s.activeLeaves)), formatCount(double(s.activeVoxels)),
        plan.voxelSize, secondsSince(start), secondsSince(t), largest / 1e6,
        formatBytes(plan.frameBytes), peakMemoryBytes() / 1e6);
    return 0;
}

}  // namespace cambium
