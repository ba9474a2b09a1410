// cambium render — a baked level set (or a mesh) ray-traced into a picture.
#include "app/app.h"

#include "cl/runtime.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/frames.h"
#include "core/system.h"
#include "io/grids.h"
#include "io/vdb_header.h"
#include "io/image_codec.h"
#include "io/image_file.h"
#include "io/mesh_file.h"
#include "io/vdb.h"
#include "use/mesh.h"
#include "use/render.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <thread>
#include <utility>

namespace cambium {

namespace {

struct RenderRequest {
    std::string input, output, grid = kSurfaceGrid, camera = "auto", device = "cpu", frames;
    int width = 960, height = 720, spp = 1;
    bool viaMesh = false;
    bool timings = false;  ///< mesh the level set and trace the triangles with Embree instead
    std::string mesh;      ///< render this mesh file (OBJ, PLY) with Embree instead of a .vdb
};

int runRenderCommand(RenderRequest req)
{
    req.timings = timingsAsked(req.timings);
    checkPicture(req.width, req.height, req.spp);
    const Device device = parseDevice(req.device);
    parseCamera(req.camera, Box(glm::dvec3(0.0), glm::dvec3(1.0)),
                1.0);  // the spec, before any work
    if (!req.mesh.empty() && (!req.input.empty() || req.viaMesh))
        throw InputError("--mesh renders a mesh file instead of a .vdb: give one or the other");
    if (req.mesh.empty() && req.input.empty())
        throw InputError("nothing to render: give a .vdb file (or --mesh MESH.obj|ply)");
    const bool meshFile = !req.mesh.empty();
    // A render estimated past ten seconds says so before it starts, after
    // every check (4096 samples a pixel of the default picture ran an hour
    // and more without a word).  Rays a second: the slowest path measured
    // here, per core.
    bool noted = false;
    auto note = [&] {
        if (std::exchange(noted, true))
            return;
        constexpr double kRaysPerCoreSecond = 0.3e6, kSaySeconds = 10.0;
        const double frames = req.frames.empty() ? 1.0 : double(parseFrames(req.frames).size());
        const double rays = double(req.width) * req.height * req.spp * frames;
        const double seconds =
            rays / (kRaysPerCoreSecond * std::max(1u, std::thread::hardware_concurrency()));
        if (seconds > kSaySeconds)
            printNotice(fmt::format(
                "rendering {} rays ({} x {} pixels, {} sample{} each{}): roughly {} here",
                formatCount(rays), req.width, req.height, req.spp, req.spp == 1 ? "" : "s",
                frames > 1.0 ? fmt::format(", {} frames", formatCount(frames)) : "",
                formatDuration(seconds)));
    };
    // A sequence keeps one camera, framed on its last frame (a growing tree
    // grows into the picture instead of the camera backing away), and one
    // OpenCL marcher (its context and kernel built once, new grids each frame).
    std::optional<Box> sequenceBounds;
    std::unique_ptr<OpenCLMarcher> marcher;
    if (!req.frames.empty() && !meshFile && isFramePattern(req.input)) {
        const std::string last = framePath(req.input, parseFrames(req.frames).back());
        if (std::filesystem::exists(last))
            sequenceBounds = storedActiveBounds(last, req.grid);
    }
    // (each frame's summary kept for its reads: verified once, unless it
    // changed meanwhile)
    std::map<std::string, VdbSummary> checked;
    forEachFile(
        meshFile ? req.mesh : req.input, req.output, req.frames,
        [&](const std::string& in) {
            // (every frame read before the first picture: a mesh cut short
            // in frame 4 was found after frames 1-3 were written)
            if (meshFile)
                readMesh(in);
            else
                checked[in] = checkLevelSetFile(in, req.grid);
        },
        checkImageOutput,
        [&](const std::string& in, const std::string& out) {
            note();
            const auto start = Clock::now();
            const double aspect = double(req.width) / double(req.height);
            double read = 0.0, readPeak = 0.0;
            RenderImage img;
            const char* how;
            if (meshFile) {
                const TriangleMesh mesh = readMesh(in);
                img = renderMeshEmbree(mesh, parseCamera(req.camera, meshBounds(mesh), aspect),
                                       req.width, req.height, req.spp);
                how = "Embree on the mesh's triangles, reading included";
            } else {
                // (the CPU march reads the colour once the level set is gone,
                // holding every hit meanwhile, a few dozen bytes a sample:
                // where they could take more than a quarter of this
                // machine's memory, both grids are held instead, whose
                // picture is the same; 8192 x 4096 at 4096 samples grew
                // past 7 GB in a minute)
                const double hitBytes = double(req.width) * double(req.height) *
                                        double(std::max(1, req.spp)) *
                                        double(sizeof(std::pair<uint32_t, TraceHit>));
                const bool apart = hitBytes <= 0.25 * availableMemoryBytes();
                const bool cpu = device == Device::Cpu && !req.viaMesh && apart;
                VdbSummary& summary = checked[in];
                // (the CPU march decodes its level set's leaves a strip of
                // the picture at a time, and reads the colour after)
                LevelSetGrids f =
                    cpu ? readLevelSetDelayed(in, summary, req.grid, ColourRead::None, false)
                        : readLevelSet(in, req.grid, ColourRead::Whole, &summary);
                LazySurface lazy;
                if (cpu)
                    lazy.leaves = std::make_unique<LazyLeaves>(in, summary, *f.surface);
                read = secondsSince(start);
                readPeak = peakMemoryBytes();
                voxelizeActiveTiles(*f.surface);
                const Box bounds = activeWorldBounds(*f.surface);
                // (a sequence's empty frame, a tree before its first year,
                // is its camera's empty picture; a lone empty file is refused)
                const bool inSequence = sequenceBounds && !sequenceBounds->empty();
                if (bounds.empty() && !inSequence)
                    throw InputError(
                        fmt::format("{}: the level set has no active voxels: nothing to see", in));
                const Camera cam =
                    parseCamera(req.camera, inSequence ? *sequenceBounds : bounds, aspect);
                if (bounds.empty()) {
                    img = renderBackground(cam, req.width, req.height, req.spp);
                    how = "an empty frame: the background";
                } else if (req.viaMesh) {
                    // (and Embree's triangles and hierarchy, about 96 bytes a
                    // triangle, two a point)
                    checkMeshingFits(*f.surface, bool(f.color),
                                     fmt::format("{}'s grid '{}'", in, f.surface->getName()),
                                     192.0);
                    img = renderMeshEmbree(meshLevelSet(*f.surface, f.color.get()), cam, req.width,
                                           req.height, req.spp);
                    how = "Embree on the volumeToMesh triangles, meshing included";
                } else if (device == Device::Cpu && !apart) {
                    img = renderLevelSetCpu(*f.surface, f.color.get(), cam, req.width, req.height,
                                            req.spp);
                    how = "OpenVDB's level-set ray intersector, both grids held";
                } else if (device == Device::Cpu) {
                    // (its transform and name, to check the colours' against)
                    const openvdb::FloatGrid::Ptr frame =
                        openvdb::gridPtrCast<openvdb::FloatGrid>(f.surface->copyGridWithNewTree());
                    img = renderLevelSetCpu(
                        std::move(f.surface),
                        [&](const std::vector<openvdb::Coord>& leaves) {
                            // (the picture's writer loads while the colours are found)
                            preloadImageCodec();
                            return readColourGrid(in, *frame, &leaves, &summary);
                        },
                        cam, req.width, req.height, req.spp, std::move(lazy));
                    how = "OpenVDB's level-set ray intersector";
                } else {
                    how = marcher ? "OpenCL NanoVDB march, conversion included"
                                  : "OpenCL NanoVDB march, conversion and kernel build included";
                    img = withOpenCLHint("render", [&] {
                        // The march reads its NanoVDB copies only: OpenVDB's go
                        // as they are made.
                        if (marcher)
                            marcher->load(std::move(f));
                        else
                            marcher = std::make_unique<OpenCLMarcher>(std::move(f));
                        return marcher->render(cam, req.width, req.height, req.spp);
                    });
                }
            }
            const auto written = Clock::now();
            writeImage(img, out);
            const double s = secondsSince(start);
            if (req.timings)
                fmt::print(stderr,
                           "timings: read {:.3f} s (peak memory {:.0f} MB), rendered {:.3f} s, "
                           "written {:.3f} s (peak memory {:.0f} MB)\n",
                           read, readPeak * 1e-6,
                           std::chrono::duration<double>(written - start).count() - read,
                           secondsSince(written), peakMemoryBytes() * 1e-6);
            size_t covered = 0;
            for (float a : img.alpha)
                covered += a > 0.0f;
            // (an empty picture of a surface, exit 0, said why it may be:
            // the marches find a crossing only between values within two
            // voxels of zero, as OpenVDB's intersector does, and a band of
            // active tiles at +-3 voxels was drawn by --via-mesh alone,
            // sweep 20)
            if (covered == 0 && !meshFile && std::string(how).rfind("an empty frame", 0) != 0)
                printNotice(
                    req.viaMesh
                        ? fmt::format("{}: no ray met the surface: it is out of view (--camera)",
                                      in)
                        : fmt::format("{}: no ray met the surface: it is out of view (--camera), "
                                      "or its values near the surface are not distances (a "
                                      "crossing between values more than two voxels from zero "
                                      "is not seen; --via-mesh draws what volumeToMesh finds)",
                                      in));
            checked.erase(in);  // (a million frames' summaries were held to the end)
            fmt::print(
                "rendered {} -> {}: {} x {}, {} sample{} per pixel, {:.1f} % of pixels on the "
                "surface, {:.2f} s "
                "({:.3g} M rays/s, {})\n",
                in, out, req.width, req.height, req.spp, req.spp == 1 ? "" : "s",
                100.0 * double(covered) / double(img.alpha.size()), s,
                double(req.width) * req.height * req.spp / s * 1e-6, how);
        });
    return 0;
}

}  // namespace

void addRenderCommand(CLI::App& app, Action& action)
{
    auto req = std::make_shared<RenderRequest>();
    auto* cmd = app.add_subcommand("render",
                                   "Ray-march a baked level set into a picture (.png) or "
                                   "channels for tools (.exr)");
    cmd->add_option("input", req->input, "Input .vdb file");
    auto* mesh = cmd->add_option(
        "--mesh", req->mesh, "Render this mesh (.obj or .ply) with Embree instead of a .vdb file");
    cmd->add_option("-o,--output", req->output, "Output image (.png or .exr)")->required();
    cmd->add_option("--width", req->width, "Image width in pixels")->capture_default_str();
    cmd->add_option("--height", req->height, "Image height in pixels")->capture_default_str();
    cmd->add_option("--spp", req->spp, "Samples per pixel (anti-aliasing)")->capture_default_str();
    cmd->add_option("--camera", req->camera,
                    "auto (a three-quarter view), turntable:ANGLE or look:EX,EY,EZ:TX,TY,TZ[:FOV]")
        ->capture_default_str();
    // A mesh is traced by Embree and has no grids: these would be ignored.
    cmd->add_option("--device", req->device,
                    "cpu (OpenVDB's level-set ray intersector; the faster here, measured: "
                    "docs/rendering.md) or opencl (NanoVDB's HDDA in an OpenCL kernel)")
        ->capture_default_str()
        ->excludes(mesh);
    cmd->add_option("--grid", req->grid, "Name of the level-set grid")
        ->capture_default_str()
        ->excludes(mesh);
    cmd->add_flag("--timings", req->timings,
                  "Print the time of each stage on stderr (also with CAMBIUM_TIMING set)");
    cmd->add_flag("--via-mesh", req->viaMesh,
                  "Mesh the level set and trace the triangles with Embree (the cross-check)");
    cmd->add_option(
        "--frames", req->frames,
        "A sequence: frames FIRST-LAST[:STEP] of an input and output with a run of '#'");
    cmd->callback([req, &action] { action = [req] { return runRenderCommand(*req); }; });
}

}  // namespace cambium
