// cambium — the shape command's work.
#include "shape/shape_job.h"

#include "bake/bake.h"
#include "bake/mesh_levelset.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/files.h"
#include "core/system.h"
#include "io/vdb.h"
#include "shape/synthesis.h"
#include "use/mesh.h"

#include <fmt/format.h>

#include <cmath>

namespace cambium {

namespace {

/// Memory per band voxel of a mesh bake: the value and colour leaves, the
/// bins and the flood fill's tiles (measured about 30 bytes; with margin).
constexpr double kMeshBakeBytesPerVoxel = 48.0;

}  // namespace

ShapeReport runShape(const ShapeRequest& req, const ShapeCallbacks& cb)
{
    const std::string format = fileFormat(req.output, {"vdb", "obj", "ply"}, "output");
    const bool levelSet = format == "vdb";
    if (req.voxelSize && !(*req.voxelSize >= kMinVoxelSize && std::isfinite(*req.voxelSize)))
        throw InputError(fmt::format("--voxel-size must be at least {} (got {})", kMinVoxelSize,
                                     *req.voxelSize));
    if (!(req.halfWidth >= 1.0 && req.halfWidth <= 64.0))
        throw InputError(
            fmt::format("--half-width must be from 1 to 64 voxels (got {})", req.halfWidth));
    if (req.levels > kMaxSubdivisionLevels)
        throw InputError(
            fmt::format("--levels {}: at most {} (OpenSubdiv's uniform refinement "
                        "stops at 15)",
                        req.levels, kMaxSubdivisionLevels));
    if (!levelSet && (req.voxelSize || req.fog || req.half))
        throw InputError(
            fmt::format("{}: --voxel-size, --fog and --half are for level sets "
                        "(.vdb)",
                        req.output));
    const ShapeSpec spec = readShapeFile(req.input);
    const int levels = req.levels >= 0 ? req.levels : spec.levels;
    checkShapeLevels(spec, levels);
    checkOutputPath(req.output);

    // Memory, before any work: synthesis from the base's faces, the bake
    // from its area (the limit surface's is smaller; details add some).
    // (ShapeSurface checks the details themselves before it refines.)
    const BaseShape base = makeBase(spec.base, spec.source, req.device);
    checkSynthesisMemory(base.mesh, levels, req.input);
    const double available = availableMemoryBytes();
    if (levelSet && req.voxelSize) {
        const double area = 2.0 * surfaceArea(base.mesh);
        const double voxels = area / (*req.voxelSize * *req.voxelSize) * 2.0 * req.halfWidth;
        if (voxels * kMeshBakeBytesPerVoxel > available)
            throw InputError(
                fmt::format("--voxel-size {}: the level set would need about {} "
                            "of memory ({} available): use a larger voxel size",
                            *req.voxelSize, formatBytes(voxels * kMeshBakeBytesPerVoxel),
                            formatBytes(available)));
    }

    ShapeReport r;
    auto t = Clock::now();
    ShapeSurface shape(spec, levels, base);
    shape.synthesize();
    TriangleMesh mesh = shape.mesh();
    r.synthesisSeconds = secondsSince(t);
    r.levels = levels;
    r.vertices = mesh.points.size();
    r.faces = mesh.polygons.sizes.size();
    r.area = meshArea(mesh);
    r.volume = meshVolume(mesh);
    r.levelSet = levelSet;
    if (cb.progress)
        cb.progress("synthesis", 1.0);

    if (!levelSet) {
        t = Clock::now();
        writeMesh(mesh, req.output);
        r.writeSeconds = secondsSince(t);
    } else {
        MeshBakeOptions opt;
        r.autoVoxelSize = !req.voxelSize;
        opt.voxelSize =
            req.voxelSize ? *req.voxelSize : std::max(meshExtent(mesh) / 512.0, kMinVoxelSize);
        if (r.autoVoxelSize) {
            const double voxels = r.area / (opt.voxelSize * opt.voxelSize) * 2.0 * req.halfWidth;
            if (voxels * kMeshBakeBytesPerVoxel > available)
                throw InputError(fmt::format(
                    "{}: the automatic voxel size {} would need about "
                    "{} of memory: give a larger --voxel-size",
                    req.input, opt.voxelSize, formatBytes(voxels * kMeshBakeBytesPerVoxel)));
        }
        opt.halfWidth = req.halfWidth;
        opt.fog = req.fog;
        opt.progress = cb.progress;
        t = Clock::now();
        BakedGrids grids = bakeMeshLevelSet(mesh, opt, req.input);
        r.bakeSeconds = secondsSince(t);
        r.stats = grids.stats;
        r.voxelSize = opt.voxelSize;
        VdbFileInfo info;
        info.scene = req.input;
        info.halfWidth = req.halfWidth;
        info.threshold = 0.0;
        info.half = req.half;
        t = Clock::now();
        writeVdb(grids, req.output, info);
        r.writeSeconds = secondsSince(t);
    }
    r.peakMemoryBytes = peakMemoryBytes();
    return r;
}

}  // namespace cambium
