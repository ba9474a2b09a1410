// cambium — the shape command's work.
#include "shape/shape_job.h"

#include "bake/bake.h"
#include "bake/mesh_levelset.h"
#include "bake/sequence.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "core/math.h"
#include "core/system.h"
#include "io/vdb.h"
#include "shape/synthesis.h"
#include "use/mesh.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>

namespace cambium {

namespace {

/// Memory per band voxel of a mesh bake: the value and colour leaves, the
/// bins and the flood fill's tiles (measured about 30 bytes; with margin).
constexpr double kMeshBakeBytesPerVoxel = 48.0;

}  // namespace

void checkBakeMemory(double area, double voxelSize, double halfWidth, const std::string& what)
{
    const double voxels = area / (voxelSize * voxelSize) * 2.0 * halfWidth;
    checkMemoryFits(voxels * kMeshBakeBytesPerVoxel,
                    fmt::format("{}: the level set at voxel size {}", what, voxelSize),
                    "use a larger voxel size");
}

namespace {

/// The request's own checks (before the shape file is read).
void checkRequest(const ShapeRequest& req, bool levelSet)
{
    if (req.voxelSize)
        checkVoxelSize(*req.voxelSize);
    checkHalfWidth(req.halfWidth);
    if (req.levels > kMaxSubdivisionLevels)
        throw InputError(
            fmt::format("--levels {}: at most {} (OpenSubdiv's uniform refinement "
                        "stops at 15)",
                        req.levels, kMaxSubdivisionLevels));
    if (!std::isfinite(req.time))
        throw InputError(fmt::format("--time must be a finite number (got {})", req.time));
    if (!levelSet && (req.voxelSize || req.fog || req.half))
        throw InputError(
            fmt::format("{}: --voxel-size, --fog and --half are for level sets "
                        "(.vdb)",
                        req.output));
    if (!req.frames.empty() && !levelSet)
        throw InputError(fmt::format(
            "{}: a sequence (--frames) is written as level sets: give a .vdb pattern such as "
            "out/shape.####.vdb",
            req.output));
    if (req.resume && req.frames.empty())
        throw InputError("--resume is for sequences (--frames)");
}

/// The synthesis's mesh and its measures, into the report.
/// The painted PLYs an alpha signal reads, its operands' too.
void paintedFiles(const AlphaSpec& alpha, std::vector<std::string>& files)
{
    files.push_back(alpha.file);
    for (const AlphaSpec& a : alpha.of)
        paintedFiles(a, files);
}

/// The files a shape reads besides its shape file: its base's file and
/// control mesh, painted PLYs and strokes, and a model base's own (its bark
/// photo): what an output may not replace and a sequence's key depends on.
std::vector<std::string> shapeFiles(const ShapeSpec& spec)
{
    std::vector<std::string> files = {spec.base.file, spec.base.control};
    paintedFiles(spec.blend.alpha, files);
    if (spec.base.type == BaseType::Model)
        for (const std::string& f : modelFiles(spec.base.file))
            if (f != spec.base.file)
                files.push_back(f);
    return files;
}

/// InputError when a synthesised point is not finite or lies beyond
/// kFarthestCoordinate (as read and baked ones may not): details and edits whose gains, radii
/// and amplitudes multiply past any size, named.
void checkSynthesised(const TriangleMesh& mesh, const ShapeSpec& spec)
{
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        const openvdb::Vec3s& p = mesh.points[i];
        bool fine = true;
        for (int k = 0; k < 3; ++k)
            fine = fine && std::isfinite(p[k]) && std::abs(p[k]) <= kFarthestCoordinate;
        if (fine)
            continue;
        std::string causes;
        const size_t named = std::min<size_t>(spec.edits.size(), 3);
        for (size_t k = 0; k < named; ++k) {
            const EditSpec& e = spec.edits[k];
            causes += fmt::format("{}{} (radius {:g}, gain {:g})", k ? ", " : "", e.path, e.radius,
                                  e.gain);
        }
        if (spec.edits.size() > named)
            causes += fmt::format(" and {} more", spec.edits.size() - named);
        throw InputError(fmt::format(
            "{}: the synthesised surface has point {} at ({:g}, {:g}, {:g}): its details{} "
            "push it beyond any size; lower their amplitudes, gains or radii",
            spec.source, i, p[0], p[1], p[2],
            causes.empty() ? "" : fmt::format(" and edits {}", causes)));
    }
}

TriangleMesh synthesise(ShapeSurface& shape, ShapeReport& r, const ShapeCallbacks& cb)
{
    const auto t = Clock::now();
    shape.synthesize([&](double f) {
        if (cb.progress)
            cb.progress("synthesis", f);
    });
    TriangleMesh mesh = shape.mesh();
    checkSynthesised(mesh, shape.spec());
    r.synthesisSeconds += secondsSince(t);
    r.vertices = mesh.points.size();
    r.faces = mesh.polygons.sizes.size();
    r.area = meshArea(mesh);
    r.volume = meshVolume(mesh);
    return mesh;
}

MeshBakeOptions meshBakeOptions(const ShapeRequest& req, const ShapeCallbacks& cb,
                                const ShapeReport& r)
{
    MeshBakeOptions opt;
    opt.voxelSize = r.voxelSize;
    opt.halfWidth = req.halfWidth;
    opt.fog = req.fog;
    opt.colour = req.colour;
    opt.progress = cb.progress;
    return opt;
}

/// The mesh baked into a level set (the report's voxel size) and written.
void bakeAndWrite(const TriangleMesh& mesh, const ShapeRequest& req, const ShapeCallbacks& cb,
                  const VdbFileInfo& info, const std::string& path, ShapeReport& r)
{
    auto t = Clock::now();
    BakedGrids grids = bakeMeshLevelSet(mesh, meshBakeOptions(req, cb, r), req.input);
    r.bakeSeconds += secondsSince(t);
    r.stats = grids.stats;
    t = Clock::now();
    writeVdb(grids, path, info);
    r.writeSeconds += secondsSince(t);
}

VdbFileInfo fileInfo(const ShapeRequest& req)
{
    VdbFileInfo info;
    info.scene = req.input;
    info.halfWidth = req.halfWidth;
    info.threshold = 0.0;
    info.half = req.half;
    return info;
}

/// The frames of a shape sequence checked before any is written (all of
/// a sequence this long or shorter).
constexpr size_t kCheckedShapeFrames = 1024;

/// 512 voxels across the mesh, at least kMinVoxelSize.
double automaticVoxelSize(const TriangleMesh& mesh)
{
    return std::max(meshExtent(mesh) / 512.0, kMinVoxelSize);
}

/// The voxel size: given, or automaticVoxelSize (checked to fit).
void chooseVoxelSize(const ShapeRequest& req, const TriangleMesh& mesh, ShapeReport& r)
{
    r.autoVoxelSize = !req.voxelSize;
    r.voxelSize = req.voxelSize ? *req.voxelSize : automaticVoxelSize(mesh);
    checkHalfRange(req.half, r.voxelSize, req.halfWidth, req.input);
    if (r.autoVoxelSize)
        checkBakeMemory(r.area, r.voxelSize, req.halfWidth,
                        fmt::format("{}: the automatic voxel size", req.input));
}

/// As bake says of primitives thinner than a voxel: a shape a few voxels
/// across bakes as blocks (it did so silently).  After the checks, so that
/// a refused bake has its error alone.
void noteCoarseVoxels(const TriangleMesh& mesh, const ShapeReport& r, const ShapeCallbacks& cb)
{
    const double extent = meshExtent(mesh);
    if (cb.notice && extent < 8.0 * r.voxelSize)
        cb.notice(
            fmt::format("the shape is {:.3g} across, {:.2g} voxels of {:g}: it bakes as a few "
                        "voxel-sized blocks; the automatic voxel size is {:.3g}",
                        extent, extent / r.voxelSize, r.voxelSize, automaticVoxelSize(mesh)));
}

ShapeReport runSequence(const ShapeRequest& req, const ShapeCallbacks& cb)
{
    const std::vector<long long> frames = parseFrames(req.frames);
    // Every frame's file read (and so checked) before any work.
    const std::string text = readTextFile(req.input, "shape file");
    const std::string directory = std::filesystem::path(req.input).parent_path().string();
    std::vector<ShapeSpec> specs;
    for (long long f : frames)
        specs.push_back(parseShape(text, req.input, directory, double(f), req.levels));
    std::vector<std::string> files = shapeFiles(specs.front());
    files.push_back(req.input);
    const std::vector<std::string> paths =
        sequencePaths(req.output, frames, "out/shape.####.vdb", files);
    files.pop_back();
    const int levels = req.levels >= 0 ? req.levels : specs.front().levels;
    for (const ShapeSpec& s : specs)
        checkShapeLevels(s, levels);
    const BaseShape base = makeBase(specs.front().base, req.input, req.device, cb.progress);
    checkSynthesisMemory(base.mesh, levels, req.input);
    if (req.voxelSize) {
        checkHalfRange(req.half, *req.voxelSize, req.halfWidth, req.input);
        checkBakeMemory(2.0 * surfaceArea(base.mesh), *req.voxelSize, req.halfWidth, req.input);
    }

    ShapeReport r;
    r.levels = levels;
    r.levelSet = true;
    r.animated = specs.front().animated;
    ShapeSurface shape(specs.front(), levels, base);  // the refinement, once
    // A long sequence's frames sampled, evenly spread (the first and last
    // among them): checking all of a million took a silent quarter hour;
    // each frame's synthesis and bake check it again.
    const std::vector<size_t> checked = spreadIndices(frames.size(), kCheckedShapeFrames);
    for (size_t i : checked)  // the frames' details
        checkShapeDetails(specs[i], base.mesh);
    // The first frame sizes the voxels of every frame (one transform).
    TriangleMesh first = synthesise(shape, r, cb);
    chooseVoxelSize(req, first, r);
    // Every frame synthesised and checked as its bake will check it before
    // any file is touched: keyframes can grow a later frame past what fits
    // or past any size, and frame 1 was written before frame 2 was refused.
    // (Synthesis is a twentieth of a frame's time; each is made again below.)
    // (the sampled frames, above)
    for (size_t n = 0; n < checked.size(); ++n) {
        const size_t i = checked[n];
        try {
            if (i > 0)
                shape.setSpec(specs[i], true);
            const TriangleMesh mesh = i > 0 ? synthesise(shape, r, cb) : TriangleMesh();
            const TriangleMesh& m = i > 0 ? mesh : first;
            checkMeshBake(m, meshBakeOptions(req, {}, r), req.input);
            checkBakeMemory(meshArea(m), r.voxelSize, req.halfWidth, req.input);
        } catch (const InputError& e) {
            throw InputError(fmt::format("{} (frame {})", e.what(), frames[i]));
        }
        if (cb.progress)
            cb.progress("frames checked", double(n + 1) / double(checked.size()));
    }
    noteCoarseVoxels(first, r, cb);
    const std::string options = fmt::format(
        "h={:.17g} w={:.17g} levels={} fog={} half={} device={} colour={} "
        "base_min_radius={:.17g}",
        r.voxelSize, req.halfWidth, levels, req.fog, req.half, deviceName(req.device),
        colourExtentName(req.colour), kDefaultMinRadiusVoxels);
    // (the files the shape reads too: an edited control mesh or painted
    // PLY makes other frames)
    const std::string key = sequenceKeyOf(text, options, files);
    auto notice = [&](const std::string& line) {
        if (cb.notice)
            cb.notice(line);
    };
    const SequenceOutput output(req.output, frames, paths, 0, frames.size(), key, req.resume,
                                notice);
    for (size_t i = 0; i < frames.size(); ++i) {
        const auto t0 = Clock::now();
        ShapeFrame fr;
        fr.frame = frames[i];
        fr.path = paths[i];
        fr.skipped = output.finished(i);
        if (!fr.skipped) {
            TriangleMesh mesh;
            if (i == 0) {
                mesh = std::move(first);
            } else {
                shape.setSpec(specs[i], true);  // checked above
                mesh = synthesise(shape, r, cb);
            }
            VdbFileInfo info = fileInfo(req);
            info.frame = frames[i];
            info.time = double(frames[i]);
            info.sequence = key;
            info.part = framePart(frames[i]);
            bakeAndWrite(mesh, req, cb, info, paths[i], r);
            fr.activeVoxels = r.stats.activeVoxels;
        }
        first = {};
        fr.seconds = secondsSince(t0);
        r.frames.push_back(fr);
        if (cb.frameDone)
            cb.frameDone(fr);
    }
    r.peakMemoryBytes = peakMemoryBytes();
    return r;
}

}  // namespace

ShapeReport runShape(const ShapeRequest& req, const ShapeCallbacks& cb)
{
    const std::string format = fileFormat(req.output, {"vdb", "obj", "ply"}, "output");
    const bool levelSet = format == "vdb";
    checkRequest(req, levelSet);
    if (!req.frames.empty())
        return runSequence(req, cb);
    const ShapeSpec spec = readShapeFile(req.input, req.time, req.levels);
    const int levels = req.levels >= 0 ? req.levels : spec.levels;
    checkShapeLevels(spec, levels);
    checkOutputPath(req.output);
    std::vector<std::string> files = shapeFiles(spec);
    files.push_back(req.input);
    checkOutputIsNoInput(req.output, files);

    // Memory, before any work: synthesis from the base's faces, the bake
    // from its area (the limit surface's is smaller; details add some).
    // (ShapeSurface checks the details themselves before it refines.)
    const BaseShape base = makeBase(spec.base, spec.source, req.device, cb.progress);
    checkSynthesisMemory(base.mesh, levels, req.input);
    if (!levelSet) {
        // A mesh's points are floats, synthesised and written: as far from
        // the origin as a bake at the automatic voxel size may reach (a
        // cube at 1e7 was written on two x values, exit 0).
        glm::dvec3 lo(0.0), hi(0.0);
        double far = 0.0;
        for (size_t i = 0; i < base.mesh.points.size(); ++i) {
            const glm::dvec3& p = base.mesh.points[i];
            lo = i ? glm::min(lo, p) : p;
            hi = i ? glm::max(hi, p) : p;
            far = std::max({far, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
        }
        const double extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
        const double h = std::max(extent / 512.0, kMinVoxelSize);
        checkVoxelsFromOrigin(
            far, h,
            fmt::format("{}: the shape's base, {:.3g} across (voxels of its 512th),", req.input,
                        extent));
    }
    if (levelSet && req.voxelSize)
        checkBakeMemory(2.0 * surfaceArea(base.mesh), *req.voxelSize, req.halfWidth,
                        fmt::format("--voxel-size {}", *req.voxelSize));

    ShapeReport r;
    r.levels = levels;
    r.levelSet = levelSet;
    r.animated = spec.animated;
    const TriangleMesh mesh = [&] {
        ShapeSurface shape(spec, levels, base);
        return synthesise(shape, r, cb);
    }();
    if (cb.progress)
        cb.progress("synthesis", 1.0);
    if (!levelSet) {
        const auto t = Clock::now();
        writeMesh(mesh, req.output);
        r.writeSeconds = secondsSince(t);
    } else {
        chooseVoxelSize(req, mesh, r);
        checkMeshBake(mesh, meshBakeOptions(req, {}, r), req.input);
        noteCoarseVoxels(mesh, r, cb);
        VdbFileInfo info = fileInfo(req);
        info.time = req.time;
        bakeAndWrite(mesh, req, cb, info, req.output, r);
    }
    r.peakMemoryBytes = peakMemoryBytes();
    return r;
}

}  // namespace cambium
