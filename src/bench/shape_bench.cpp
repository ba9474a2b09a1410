// cambium — the shape benchmark.
#include "bench/shape_bench.h"

#include "bake/mesh_levelset.h"
#include "bench/median.h"
#include "core/clock.h"
#include "shape/details.h"
#include "shape/shape_job.h"
#include "shape/synthesis.h"
#include "subdiv/control_mesh.h"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <openvdb/tools/MeshToVolume.h>

#include <fmt/format.h>
#include <malloc.h>

#include <cmath>
#include <limits>
#include <memory>

namespace cambium {

namespace {

namespace Far = OpenSubdiv::Far;
namespace Sdc = OpenSubdiv::Sdc;

ShapeSpec rockSphere(int levels)
{
    ShapeSpec s;
    s.source = "rock cube-sphere";
    s.base.type = BaseType::Sphere;
    s.levels = levels;
    DetailSpec rock;
    rock.type = DetailType::Rock;
    rock.amplitude = 0.08;
    rock.seed = 3;
    for (int l = 1; l <= levels; ++l)
        rock.levels.push_back(l);
    s.details.push_back(rock);
    return s;
}

/// rockSphere blended with a second rock (another seed and frequency) across
/// a plane through the centre, then shaded by the terrain shader.
ShapeSpec blendedRockSphere(int levels)
{
    ShapeSpec s = rockSphere(levels);
    s.blend.enabled = true;
    s.blend.a.details = s.details;
    DetailSpec other = s.details.front();
    other.seed = 11;
    other.frequency = 4.0;
    s.blend.b.details = {other};
    s.details.clear();
    s.blend.alpha.type = AlphaType::Plane;
    s.blend.alpha.normal = glm::dvec3(1.0, 0.0, 0.0);
    s.blend.width = 0.5;
    s.shader.enabled = true;
    s.shader.snowLine = 0.05;
    s.shader.relief = 0.5;
    return s;
}

/// OpenSubdiv alone: a refiner for the mesh, then its points refined level
/// by level (double xyz), as a user of OpenSubdiv would subdivide it.
void openSubdiv(const ControlMesh& mesh, int levels, double& topology, double& interpolate,
                size_t& vertices)
{
    auto t = Clock::now();
    Sdc::Options sdc;
    sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    Far::TopologyDescriptor desc;
    desc.numVertices = int(mesh.points.size());
    desc.numFaces = int(mesh.faceCount());
    desc.numVertsPerFace = mesh.faceSizes.data();
    desc.vertIndicesPerFace = mesh.faceVerts.data();
    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    std::unique_ptr<Far::TopologyRefiner> r(
        Factory::Create(desc, Factory::Options(Sdc::SCHEME_CATMARK, sdc)));
    r->RefineUniform(Far::TopologyRefiner::UniformOptions(levels));
    topology = secondsSince(t);
    struct V {
        double x, y, z;
        void Clear() { x = y = z = 0.0; }
        void AddWithWeight(const V& o, double w) { x += w * o.x, y += w * o.y, z += w * o.z; }
    };
    t = Clock::now();
    std::vector<V> all(size_t(r->GetNumVerticesTotal()));
    for (size_t i = 0; i < mesh.points.size(); ++i)
        all[i] = {mesh.points[i].x, mesh.points[i].y, mesh.points[i].z};
    Far::PrimvarRefinerReal<double> primvar(*r);
    V* src = all.data();
    for (int l = 1; l <= levels; ++l) {
        V* dst = src + r->GetLevel(l - 1).GetNumVertices();
        primvar.Interpolate(l, src, dst);
        src = dst;
    }
    interpolate = secondsSince(t);
    vertices = size_t(r->GetLevel(levels).GetNumVertices());
}

/// Mesh -> level set, both ways, on the finest mesh of `shape`: times, voxel
/// counts and their differences into `r`.
void compareMeshToLevelSet(const ShapeBenchRequest& req, ShapeSurface& shape, ShapeBenchResult& r,
                           const std::function<void(const std::string&)>& say)
{
    shape.synthesize();
    // Distances only, as meshToLevelSet makes (the command also bakes Cd).
    TriangleMesh mesh = shape.mesh();
    mesh.colors.clear();
    r.faces = mesh.polygons.sizes.size();
    r.voxelSize = req.voxelSize;
    std::vector<openvdb::Vec3s> points = mesh.points;
    std::vector<openvdb::Vec3I> tris;
    for (const auto& t : mesh.triangles)
        tris.push_back(openvdb::Vec3I(t[0], t[1], t[2]));
    const auto xform = openvdb::math::Transform::createLinearTransform(req.voxelSize);
    std::vector<double> ours, theirs;
    BakedGrids mine;
    openvdb::FloatGrid::Ptr oracle;
    for (int run = 0; run < req.repeats; ++run) {
        say("cambium mesh -> level set");
        MeshBakeOptions opt;
        opt.voxelSize = req.voxelSize;
        auto t = Clock::now();
        mine = bakeMeshLevelSet(mesh, opt, "bench");
        ours.push_back(secondsSince(t));
        say("OpenVDB meshToLevelSet");
        t = Clock::now();
        oracle = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(*xform, points, tris, 3.0f);
        theirs.push_back(secondsSince(t));
    }
    r.cambiumBake = medianOf(ours);
    r.openvdbBake = medianOf(theirs);
    r.cambiumVoxels = size_t(mine.surface->activeVoxelCount());
    r.openvdbVoxels = size_t(oracle->activeVoxelCount());
    auto acc = oracle->getConstAccessor();
    std::vector<openvdb::Coord> disagree;
    for (auto it = mine.surface->tree().cbeginValueOn(); it; ++it) {
        if (std::fabs(*it) > req.voxelSize || !acc.isValueOn(it.getCoord()))
            continue;
        const double d = double(std::fabs(*it - acc.getValue(it.getCoord()))) / req.voxelSize;
        r.largestDifference = std::max(r.largestDifference, d);
        ++r.compared;
        if (d > 0.05) {
            ++r.beyondTolerance;
            if (disagree.size() < 16)
                disagree.push_back(it.getCoord());
        }
    }
    // Where the two disagree by more than the tolerance, the exact distance
    // (every triangle, OpenVDB's closest point, double precision) decides.
    say("brute-force distances where they disagree");
    auto mineAcc = mine.surface->getConstAccessor();
    for (const openvdb::Coord& c : disagree) {
        const openvdb::Vec3d p = mine.surface->indexToWorld(c);
        double best = 1e300;
        for (const auto& t : mesh.triangles) {
            openvdb::Vec3d uvw;
            const openvdb::Vec3d q = openvdb::math::closestPointOnTriangleToPoint(
                openvdb::Vec3d(mesh.points[t[0]]), openvdb::Vec3d(mesh.points[t[1]]),
                openvdb::Vec3d(mesh.points[t[2]]), p, uvw);
            best = std::min(best, (q - p).lengthSqr());
        }
        best = std::sqrt(best);
        ++r.bruteChecked;
        r.bruteCambium +=
            std::fabs(std::fabs(double(mineAcc.getValue(c))) - best) < 1e-3 * req.voxelSize;
        r.bruteOpenVdb +=
            std::fabs(std::fabs(double(acc.getValue(c))) - best) < 1e-3 * req.voxelSize;
    }
}

}  // namespace

ShapeBenchResult runShapeBench(const ShapeBenchRequest& req,
                               const std::function<void(const std::string&)>& progress)
{
    auto say = [&](const std::string& s) {
        if (progress)
            progress(s);
    };
    // Freed memory kept for reuse (no trimming, no mmap for large blocks):
    // otherwise which method gets pages already faulted in and which new
    // ones (about 8 us each on the 2-core VM) depends on the order of the
    // methods, and the stages' times measure the kernel's page faults.  The
    // first run of each pays them; the medians are of the warm runs.
    mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest
    mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
    ShapeBenchResult r;
    r.levels = req.levels;
    const ShapeSpec spec = rockSphere(req.levels);
    const BaseShape base = makeBase(spec.base, spec.source, Device::Cpu);
    // (what `cambium shape` checks before its work: --levels 10 at voxel
    // size 1e-4 ran out of memory after 17 s; and the benchmark holds
    // four such surfaces at once: the measured one, the rock alone and the
    // blended one with its second rock, where one fitted and the four ran
    // out of memory after 21 s)
    const int levels = std::max(req.levels, req.editLevel);
    constexpr double kSurfacesHeld = 4.0;
    checkMemoryFits(kSurfacesHeld * estimateSynthesisBytes(base.mesh.faceVerts.size(), levels),
                    fmt::format("--levels {}: {:g} surfaces of {} levels of a base of {} faces "
                                "held at once",
                                levels, kSurfacesHeld, levels, base.mesh.faceCount()),
                    "use fewer levels");
    checkBakeMemory(2.0 * surfaceArea(base.mesh), req.voxelSize, 3.0,
                    fmt::format("--voxel-size {}", req.voxelSize));
    std::vector<double> osdTop, osdInt, setup, synth, plain, edit, aloneSynth, blendSynth,
        plainMesh, shadedMesh;
    std::unique_ptr<ShapeSurface> shape;
    for (int run = 0; run < req.repeats; ++run) {
        say("OpenSubdiv uniform refinement");
        double a, b;
        openSubdiv(base.mesh, req.levels, a, b, r.vertices);
        osdTop.push_back(a);
        osdInt.push_back(b);

        say("cambium synthesis");
        auto t = Clock::now();
        shape = std::make_unique<ShapeSurface>(spec, -1, base);
        setup.push_back(secondsSince(t));
        t = Clock::now();
        shape->synthesize();
        synth.push_back(secondsSince(t));
        t = Clock::now();
        shape->surface().synthesize();  // the details as they are, no hook: plain
        plain.push_back(secondsSince(t));
    }
    // An edit at the edit level: that level's details scaled near a point,
    // then re-synthesised from there.
    {
        ShapeSpec e = rockSphere(req.editLevel);
        ShapeSurface s(e, -1, base);
        s.synthesize();
        r.editLevel = req.editLevel;
        r.editVertices = s.surface().level(req.editLevel).vertexCount();
        EditSpec edit1;
        edit1.at = glm::dvec3(0, 0, 1);
        edit1.radius = 0.5;
        edit1.gain = 2.0;
        edit1.levels = {req.editLevel};
        Adjacency adj(s.surface().level(req.editLevel));
        for (int run = 0; run < req.repeats; ++run) {
            say("an edit re-synthesised");
            const auto t = Clock::now();
            s.surface().synthesizeFrom(
                req.editLevel, [&](int l, SubdivLevel& lv) { applyEdit(edit1, l, lv, adj); });
            edit.push_back(secondsSince(t));
        }
    }
    // Synthesis and the coloured mesh of a surface made once, as a
    // sequence's frames do them (the first run's pages fresh, then reused),
    // the rock alone and blended, in turn.
    {
        ShapeSurface alone(spec, -1, base), mixed(blendedRockSphere(req.levels), -1, base);
        for (int run = 0; run < req.repeats; ++run) {
            say("cambium synthesis and mesh, the rock alone");
            auto t = Clock::now();
            alone.synthesize();
            aloneSynth.push_back(secondsSince(t));
            t = Clock::now();
            alone.mesh();
            plainMesh.push_back(secondsSince(t));
            say("cambium synthesis and mesh, blended and shaded");
            t = Clock::now();
            mixed.synthesize();
            blendSynth.push_back(secondsSince(t));
            t = Clock::now();
            mixed.mesh();
            shadedMesh.push_back(secondsSince(t));
        }
    }
    r.osdTopology = medianOf(osdTop);
    r.osdInterpolate = medianOf(osdInt);
    r.setup = medianOf(setup);
    r.synthesis = medianOf(synth);
    r.plainSynthesis = medianOf(plain);
    r.edit = medianOf(edit);
    r.aloneSynthesis = medianOf(aloneSynth);
    r.blendSynthesis = medianOf(blendSynth);
    r.plainMesh = medianOf(plainMesh);
    r.shadedMesh = medianOf(shadedMesh);

    // Mesh -> level set, both ways, on the finest mesh.
    compareMeshToLevelSet(req, *shape, r, say);
    return r;
}

}  // namespace cambium
