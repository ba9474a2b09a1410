// cambium — captured models as bases.
#include "shape/capture.h"

#include "bake/bake.h"
#include "bake/mesh_levelset.h"
#include "use/mesh.h"
#include "core/error.h"
#include "core/files.h"
#include "field/program.h"
#include "io/vdb.h"
#include "io/vdb_header.h"
#include "model/load_model.h"

#include <fmt/format.h>
#include <openvdb/tools/GridTransformer.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/enumerable_thread_specific.h>

#include <cmath>
#include <memory>

namespace cambium {

namespace {

/// Trilinear distance and its gradient at world points, one accessor per thread.
class DistanceField {
public:
    explicit DistanceField(openvdb::FloatGrid::ConstPtr g)
        : grid_(std::move(g)),
          h_(grid_->voxelSize()[0]),
          background_(double(grid_->background())),
          accessors_([this] { return grid_->getConstAccessor(); })
    {
    }

    /// phi at p; false when p is outside the band (no gradient there).
    bool sample(const glm::dvec3& p, double& phi, glm::dvec3& grad) const
    {
        auto& acc = accessors_.local();
        auto at = [&](const glm::dvec3& q) {
            const openvdb::Vec3d i = grid_->worldToIndex(openvdb::Vec3d(q.x, q.y, q.z));
            float v = 0.0f;
            openvdb::tools::BoxSampler::sample(acc, i, v);
            return double(v);
        };
        phi = at(p);
        if (!(std::fabs(phi) < 0.9 * background_))
            return false;
        const double e = 0.5 * h_;
        grad = glm::dvec3(at(p + glm::dvec3(e, 0, 0)) - at(p - glm::dvec3(e, 0, 0)),
                          at(p + glm::dvec3(0, e, 0)) - at(p - glm::dvec3(0, e, 0)),
                          at(p + glm::dvec3(0, 0, e)) - at(p - glm::dvec3(0, 0, e))) /
               (2.0 * e);
        return glm::dot(grad, grad) > 1e-12;
    }

    double voxelSize() const { return h_; }

private:
    openvdb::FloatGrid::ConstPtr grid_;
    double h_, background_;
    mutable tbb::enumerable_thread_specific<openvdb::FloatGrid::ConstAccessor> accessors_;
};

glm::dvec3 project(const DistanceField& f, const glm::dvec3& q, const glm::dvec3& n, double limit)
{
    const double tol = 1e-4 * f.voxelSize();
    double phi;
    glm::dvec3 g;
    // Along the normal: Newton on phi(q + t n).
    double t = 0.0;
    bool along = false;
    for (int it = 0; it < 12; ++it) {
        if (!f.sample(q + t * n, phi, g))
            break;
        const double slope = glm::dot(g, n);
        if (std::fabs(phi) < tol) {
            along = std::fabs(t) <= limit;
            break;
        }
        if (std::fabs(slope) < 0.2)
            break;
        t -= phi / slope;
        if (!(std::fabs(t) <= 2.0 * limit))
            break;
    }
    if (along)
        return q + t * n;
    // The closest point: p - phi grad / |grad|^2, repeated.
    glm::dvec3 p = q;
    for (int it = 0; it < 12; ++it) {
        if (!f.sample(p, phi, g))
            return q;
        if (std::fabs(phi) < tol)
            return p;
        p -= phi * g / glm::dot(g, g);
    }
    return p;
}

/// The half-width of the fine surfaces cambium bakes to capture: the
/// projection finds the surface only within the band, and a control mesh's
/// subdivided points lie up to a few voxels from it.
constexpr double kCaptureHalfWidth = 8.0;

openvdb::FloatGrid::Ptr bakeModel(const FieldProgram& program, double h, Device device,
                                  const std::function<void(const char*, double)>& progress)
{
    std::unique_ptr<FieldSampler> sampler = makeSampler(device);
    BakeOptions opt;
    opt.progress = progress;
    opt.voxelSize = h;
    opt.halfWidth = kCaptureHalfWidth;
    return bakeLevelSet(program, *sampler, opt).surface;
}

}  // namespace

BaseShape captureLevelSet(openvdb::FloatGrid::ConstPtr fine, double coarse, const std::string& what,
                          const std::function<void(const char*, double)>& progress)
{
    // OpenVDB resamples a level set by meshing it at its own voxels and
    // rebuilding the mesh at the new ones: as costly as meshing the fine
    // surface (a file of 40,000 leaves, each alone in its internal node,
    // ran out of memory inside it and aborted, sweep 24).
    checkMeshingFits(
        *fine, false,
        fmt::format("{} (its surface, to resample it to voxels of {:g})", what, coarse));
    if (progress)
        progress("resampling", 0.0);
    // The coarse surface resampled with OpenVDB's usual band of 3 voxels:
    // its mesh needs the zero crossing only (resampled with the fine band's
    // width in voxels, a level set whose background was 1000 made a band
    // of 20,000 voxels and ran past a minute into the memory limit).
    auto grid = openvdb::FloatGrid::create(float(openvdb::LEVEL_SET_HALF_WIDTH * coarse));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(coarse));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    openvdb::tools::resampleToMatch<openvdb::tools::BoxSampler>(*fine, *grid);
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    checkMeshingFits(*grid, false, what);
    openvdb::tools::volumeToMesh(*grid, points, triangles, quads, 0.0, 0.0);
    BaseShape s;
    for (const auto& p : points)
        s.mesh.points.push_back({double(p.x()), double(p.y()), double(p.z())});
    for (const auto& q : quads) {
        s.mesh.faceSizes.push_back(4);
        s.mesh.faceVerts.insert(s.mesh.faceVerts.end(),
                                {int(q[3]), int(q[2]), int(q[1]), int(q[0])});
    }
    for (const auto& t : triangles) {
        s.mesh.faceSizes.push_back(3);
        s.mesh.faceVerts.insert(s.mesh.faceVerts.end(), {int(t[2]), int(t[1]), int(t[0])});
    }
    if (s.mesh.faceSizes.empty())
        throw InputError(
            fmt::format("{}: the surface meshed at voxel size {:g} has no faces: "
                        "use a smaller base voxel_size",
                        what, coarse));
    try {
        checkControlMesh(s.mesh, what);
    } catch (const InputError& e) {
        throw InputError(
            fmt::format("{} (the base meshed at voxel size {:g}: try another "
                        "voxel_size)",
                        e.what(), coarse));
    }
    s.target = projectionOnto(fine);
    return s;
}

MultiresSurface::Target projectionOnto(openvdb::FloatGrid::ConstPtr fine)
{
    auto field = std::make_shared<DistanceField>(std::move(fine));
    return [field](const glm::dvec3& q, const Frame& f, double edge) {
        return project(*field, q, f.n, edge);
    };
}

ControlMesh readControlMesh(const std::string& path)
{
    const TriangleMesh m = readMesh(path);
    ControlMesh c;
    for (const auto& p : m.points)
        c.points.push_back({double(p.x()), double(p.y()), double(p.z())});
    c.faceSizes.assign(m.polygons.sizes.begin(), m.polygons.sizes.end());
    c.faceVerts.assign(m.polygons.corners.begin(), m.polygons.corners.end());
    c.firstIndex = fileFormat(path, {"obj", "ply"}, "mesh") == "obj" ? 1 : 0;
    return c;
}

BaseShape captureBase(const BaseSpec& b, const std::string& source, Device device,
                      const std::function<void(const char*, double)>& progress)
{
    const std::string what = fmt::format("{}: base {}", source, b.file);
    // A given control mesh is read and checked before any bake.
    ControlMesh control;
    if (!b.control.empty()) {
        control = readControlMesh(b.control);
        checkControlMesh(control, fmt::format("{}: base control {}", source, b.control));
    }
    openvdb::FloatGrid::Ptr fine;
    double extent = 0.0;
    if (b.type == BaseType::LevelSet) {
        // (readLevelSet refuses a tile of a frame: a fragment of the shape)
        fine = readLevelSet(b.file).surface;
        const openvdb::CoordBBox box = fine->evalActiveVoxelBoundingBox();
        const openvdb::Vec3d d = box.dim().asVec3d() * fine->voxelSize()[0];
        extent = std::max({d.x(), d.y(), d.z()});
    } else if (b.type == BaseType::Mesh) {
        const TriangleMesh mesh = readMesh(b.file);
        extent = meshExtent(mesh);
        MeshBakeOptions opt;
        opt.voxelSize = b.fineVoxelSize > 0.0 ? b.fineVoxelSize : extent / 256.0;
        opt.halfWidth = kCaptureHalfWidth;
        fine = bakeMeshLevelSet(mesh, opt, what).surface;
    } else {
        ModelOptions options;
        if (b.year >= 0.0)
            options.time = b.year;
        BlobTree tree = loadModel(b.file, options);
        BakeRequest req;
        req.input = what;
        req.tilesOffered = false;
        req.voxelSizeName = "fine_voxel_size";
        const double automatic = autoVoxelSize(FieldProgram::compile(tree, b.file), 256.0);
        req.voxelSizeOfThisModel = b.fineVoxelSize > 0.0;
        if (b.fineVoxelSize > 0.0)
            req.voxelSize = b.fineVoxelSize;
        else if (automatic > 0.0)  // (none: planVoxelSize names the empty model)
            req.voxelSize = automatic;
        // (its thin parts thickened as a bake's)
        const PlannedModel planned = planModel(tree, req);
        extent = planned.plan.extent;
        fine = bakeModel(planned.program, planned.plan.voxelSize, device, progress);
    }
    if (!b.control.empty()) {  // the given control mesh, analysed onto the fine surface
        // Points are projected where they lie in the fine surface's band:
        // a control mesh with none there is another shape, used as it was
        // (one moved 100 away was synthesised there, exit 0).
        const auto acc = fine->getConstAccessor();
        const float outside = fine->background();
        bool near = false;
        for (const auto& p : control.points) {
            const openvdb::Coord ijk =
                openvdb::Coord::round(fine->worldToIndex(openvdb::Vec3d(p.x, p.y, p.z)));
            const float d = acc.getValue(ijk);
            near = near || std::abs(d) < outside;
        }
        if (!near) {
            const openvdb::CoordBBox box = fine->evalActiveVoxelBoundingBox();
            const openvdb::Vec3d lo = fine->indexToWorld(box.min()),
                                 hi = fine->indexToWorld(box.max());
            throw InputError(fmt::format(
                "{}: its control mesh {} has no point within the band of the surface it is "
                "analysed onto (the surface lies in ({:g}, {:g}, {:g}) to ({:g}, {:g}, {:g})): "
                "it must be a coarse version of that surface, in its place",
                what, b.control, lo.x(), lo.y(), lo.z(), hi.x(), hi.y(), hi.z()));
        }
        BaseShape s;
        s.mesh = std::move(control);
        s.target = projectionOnto(fine);
        return s;
    }
    // By default 48 voxels across, each at least twice the fine surface's
    // (a level set's own voxels may be coarser than the 48th).
    const double fineVoxel = fine->voxelSize()[0];
    if (!(extent > 0.0))
        throw InputError(fmt::format("{}: the surface is empty (no active voxels)", what));
    const double coarse =
        b.coarseVoxelSize > 0.0 ? b.coarseVoxelSize : std::max(extent / 48.0, 2.0 * fineVoxel);
    // A base meshed at fewer voxels across is a blob of a few faces, which
    // the levels cannot bring back: a unit cube at 0.6 was captured with a
    // hundredth of its volume.
    constexpr double kFewestVoxelsAcross = 8.0;
    if (b.coarseVoxelSize <= 0.0 && coarse * kFewestVoxelsAcross > extent)
        throw InputError(fmt::format(
            "{}: the surface's voxels ({:g}) are too coarse for its extent {:g}: a base of {:g} "
            "voxels across, each twice the surface's, needs them at most {:g}",
            what, fineVoxel, extent, kFewestVoxelsAcross, extent / (2.0 * kFewestVoxelsAcross)));
    if (coarse * kFewestVoxelsAcross > extent)
        throw InputError(fmt::format(
            "{}: the base voxel_size {:g} spans {:.3g} voxels across the surface's extent {:g}: "
            "at most {:g} ({:g} voxels across) captures its shape",
            what, coarse, extent / coarse, extent, extent / kFewestVoxelsAcross,
            kFewestVoxelsAcross));
    if (!(coarse > fineVoxel))
        throw InputError(
            fmt::format("{}: the base voxel_size {:g} must be larger than the fine "
                        "surface's {:g}",
                        what, coarse, fineVoxel));
    return captureLevelSet(fine, coarse, what, progress);
}

}  // namespace cambium
