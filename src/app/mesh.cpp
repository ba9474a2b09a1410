// cambium mesh — a baked level set polygonised into an OBJ or PLY mesh.
#include "app/app.h"

#include "core/clock.h"
#include "core/error.h"
#include "core/frames.h"
#include "io/grids.h"
#include "io/vdb_header.h"
#include "io/mesh_file.h"
#include "io/vdb.h"
#include "use/mesh.h"

#include <fmt/format.h>

#include <cstdlib>
#include <map>
#include <thread>

namespace cambium {

namespace {

/// `cambium mesh`: the float level-set grid `grid` of a .vdb file (and its
/// `Cd` grid when present) meshed and written to `output`; for a sequence,
/// input and output are patterns with a run of `#` and `frames` a range
/// (core/frames.h): one mesh per frame.
struct MeshRequest {
    std::string input, output, grid = kSurfaceGrid, frames;
    double adaptivity = 0.0;
    bool timings = false;
};

/// One line per file; InputError, before any work, for a bad output path or
/// a missing input file, and for a file without the grid or whose grid is
/// not a float level set.
int runMeshCommand(const MeshRequest& req)
{
    const bool timings = timingsAsked(req.timings);
    if (!(req.adaptivity >= 0.0 && req.adaptivity <= 1.0))
        throw InputError(
            fmt::format("--adaptivity must be between 0 and 1 (got {})", req.adaptivity));
    // (each frame's summary kept for its read: verified once, unless it
    // changed meanwhile)
    std::map<std::string, VdbSummary> checked;
    forEachFile(
        req.input, req.output, req.frames,
        [&](const std::string& in) { checked[in] = checkLevelSetFile(in, req.grid); },
        checkMeshOutput,
        [&](const std::string& in, const std::string& out) {
            const auto start = Clock::now();
            LevelSetGrids f = readLevelSet(in, req.grid, ColourRead::Whole, &checked[in]);
            checked.erase(in);  // (a million frames' summaries were held to the end)
            // (a sequence's empty frame, a tree before its first year, is an
            // empty mesh; a lone empty file is refused)
            if (f.surface->activeVoxelCount() == 0 && req.frames.empty())
                throw InputError(
                    fmt::format("{}: the level set has no active voxels: nothing to mesh", in));
            const double read = secondsSince(start);
            checkMeshingFits(*f.surface, bool(f.color),
                             fmt::format("{}'s grid '{}'", in, req.grid));
            MeshTimings tm;
            const TriangleMesh mesh = meshLevelSet(*f.surface, f.color.get(), req.adaptivity, &tm);
            const auto written = Clock::now();
            const bool coloured = bool(f.color);
            // While the file is written: the grids' memory (a million blocks
            // for a large frame) given back, and the mesh's area and volume
            // summed, on another thread.
            double area = 0.0, volume = 0.0;
            std::thread beside([&, g = std::move(f)]() mutable {
                g = LevelSetGrids();
                area = meshArea(mesh);
                volume = meshVolume(mesh);
            });
            try {
                writeMesh(mesh, out);
            } catch (...) {
                beside.join();
                throw;
            }
            beside.join();
            const double s = secondsSince(start);
            if (timings)
                fmt::print(stderr,
                           "timings: read {:.3f} s, volumeToMesh {:.3f} s, triangles "
                           "{:.3f} s, normals and colours {:.3f} s, written {:.3f} s\n",
                           read, tm.polygons, tm.triangles, tm.attributes, secondsSince(written));
            fmt::print(
                "meshed {} -> {}: {} vertices, {} triangles{}, {:.2f} s ({:.3g} M "
                "triangles/s), area {:.6g}, "
                "volume {:.6g}\n",
                in, out, mesh.points.size(), mesh.triangles.size(),
                coloured ? ", colours from Cd" : "", s, double(mesh.triangles.size()) / s * 1e-6,
                area, volume);
        });
    return 0;
}

}  // namespace

void addMeshCommand(CLI::App& app, Action& action)
{
    auto req = std::make_shared<MeshRequest>();
    auto* cmd = app.add_subcommand("mesh",
                                   "Polygonise a baked level set (OpenVDB's volumeToMesh) into "
                                   "an OBJ or binary PLY mesh");
    cmd->add_option("input", req->input, "Input .vdb file")->required();
    cmd->add_option("-o,--output", req->output, "Output mesh (.obj or .ply)")->required();
    cmd->add_option("--adaptivity", req->adaptivity,
                    "0: uniform triangles; up to 1: fewer where the surface is flat")
        ->capture_default_str();
    cmd->add_option("--grid", req->grid, "Name of the level-set grid")->capture_default_str();
    cmd->add_flag("--timings", req->timings,
                  "Print the time of each stage on stderr (also with CAMBIUM_TIMING set)");
    cmd->add_option("--frames", req->frames,
                    "A sequence: frames FIRST-LAST[:STEP] of an input and output with a run of '#' "
                    "(tree.####.vdb)");
    cmd->callback([req, &action] { action = [req] { return runMeshCommand(*req); }; });
}

}  // namespace cambium
