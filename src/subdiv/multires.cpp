// cambium — multi-resolution Catmull-Clark surfaces on OpenSubdiv's Far.
#include "subdiv/multires.h"

#include "core/parallel.h"
#include "core/error.h"

#include <fmt/format.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <cmath>

namespace cambium {

namespace Far = OpenSubdiv::Far;
namespace Sdc = OpenSubdiv::Sdc;

namespace {

/// Far's primvar interface (Clear, AddWithWeight) over plain arrays of
/// values (points, scalars, pairs), through proxies, so that the surface
/// stores glm vectors.
template <class T>
struct ValueRef {
    T& v;
    void Clear(void* = nullptr) { v = T(0.0); }
    void AddWithWeight(const ValueRef& s, double w) { v += w * s.v; }
};
template <class T>
struct ValueView {
    T* data;
    ValueRef<T> operator[](int i) const { return {data[i]}; }
};
using PointView = ValueView<glm::dvec3>;
using ScalarView = ValueView<double>;

glm::dvec3 anyPerpendicular(const glm::dvec3& n)
{
    const glm::dvec3 a = std::fabs(n.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    return glm::normalize(a - glm::dot(a, n) * n);
}

void copyTopology(const Far::TopologyLevel& t, SubdivLevel& lv)
{
    const int nf = t.GetNumFaces(), nv = t.GetNumVertices(), ne = t.GetNumEdges();
    lv.faceSizes.resize(size_t(nf));
    lv.faceStart.resize(size_t(nf) + 1);
    lv.faceStart[0] = 0;
    for (int f = 0; f < nf; ++f) {
        const auto fv = t.GetFaceVertices(f);
        lv.faceSizes[size_t(f)] = fv.size();
        lv.faceStart[size_t(f) + 1] = lv.faceStart[size_t(f)] + fv.size();
        for (int k = 0; k < fv.size(); ++k)
            lv.faceVerts.push_back(fv[k]);
    }
    lv.vertexFaceStart.resize(size_t(nv) + 1);
    lv.vertexFaceStart[0] = 0;
    lv.tangentNeighbour.resize(size_t(nv));
    lv.boundary.resize(size_t(nv));
    for (int v = 0; v < nv; ++v) {
        const auto vf = t.GetVertexFaces(v);
        lv.vertexFaceStart[size_t(v) + 1] = lv.vertexFaceStart[size_t(v)] + vf.size();
        for (int k = 0; k < vf.size(); ++k)
            lv.vertexFaces.push_back(vf[k]);
        const auto ev = t.GetEdgeVertices(t.GetVertexEdges(v)[0]);
        lv.tangentNeighbour[size_t(v)] = ev[0] == v ? ev[1] : ev[0];
        lv.boundary[size_t(v)] = t.IsVertexBoundary(v) ? 1 : 0;
    }
    lv.edges.resize(size_t(ne));
    for (int e = 0; e < ne; ++e) {
        const auto ev = t.GetEdgeVertices(e);
        lv.edges[size_t(e)] = {ev[0], ev[1]};
    }
}

}  // namespace

struct MultiresSurface::Refiner {
    std::unique_ptr<Far::TopologyRefiner> topology;
    std::unique_ptr<Far::PrimvarRefinerReal<double>> primvar;
};

MultiresSurface::MultiresSurface(const ControlMesh& base, int levels, const std::string& what)
{
    if (levels < 0 || levels > kMaxSubdivisionLevels)
        throw InputError(
            fmt::format("{}: {} subdivision levels (0 to {}: OpenSubdiv's uniform "
                        "refinement stops at {})",
                        what, levels, kMaxSubdivisionLevels, kMaxSubdivisionLevels));
    const MeshTopologyStats topo = checkControlMesh(base, what);
    // Closed meshes face outwards (frames' normals point out of the solid).
    ControlMesh turned;
    const ControlMesh* mesh = &base;
    if (topo.closed() && enclosedVolume(base) < 0.0) {
        turned = base;
        reverseFaces(turned);
        mesh = &turned;
    }

    Sdc::Options sdc;
    sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    sdc.SetFVarLinearInterpolation(Sdc::Options::FVAR_LINEAR_ALL);
    Far::TopologyDescriptor desc;
    desc.numVertices = int(mesh->points.size());
    desc.numFaces = int(mesh->faceSizes.size());
    desc.numVertsPerFace = mesh->faceSizes.data();
    desc.vertIndicesPerFace = mesh->faceVerts.data();
    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    refiner_ = std::make_unique<Refiner>();
    refiner_->topology.reset(Factory::Create(desc, Factory::Options(Sdc::SCHEME_CATMARK, sdc)));
    if (!refiner_->topology)
        throw InputError(fmt::format("{}: OpenSubdiv cannot refine this mesh", what));
    if (levels > 0) {
        Far::TopologyRefiner::UniformOptions uniform(levels);
        uniform.fullTopologyInLastLevel = true;  // the limit evaluation needs it
        refiner_->topology->RefineUniform(uniform);
    }
    refiner_->primvar = std::make_unique<Far::PrimvarRefinerReal<double>>(*refiner_->topology);

    levels_.resize(size_t(levels) + 1);
    for (int l = 0; l <= levels; ++l) {
        SubdivLevel& lv = levels_[size_t(l)];
        copyTopology(refiner_->topology->GetLevel(l), lv);
        const size_t n = lv.vertexCount();
        lv.detail.assign(n, glm::dvec3(0.0));
        lv.scalarDetail.assign(n, 0.0);
        lv.subdivided.resize(n);
        lv.subdividedScalar.resize(n);
    }
    levels_[0].subdivided = base.points;
    if (base.scalar.empty())
        levels_[0].subdividedScalar.assign(base.points.size(), 0.0);
    else
        levels_[0].subdividedScalar = base.scalar;
}

MultiresSurface::~MultiresSurface() = default;

std::vector<glm::dvec3> vertexNormals(const SubdivLevel& lv, const std::vector<glm::dvec3>& p)
{
    const size_t nf = lv.faceCount();
    std::vector<glm::dvec3> area(nf);
    forEachIndex(nf, [&](size_t f) {
        const int* c = lv.faceVerts.data() + lv.faceStart[f];
        const int n = lv.faceSizes[f];
        if (n == 4) {
            area[f] =
                glm::cross(p[size_t(c[2])] - p[size_t(c[0])], p[size_t(c[3])] - p[size_t(c[1])]);
        } else {  // Newell: twice the vector area of any polygon
            glm::dvec3 s(0.0);
            for (int k = 0; k < n; ++k)
                s += glm::cross(p[size_t(c[k])], p[size_t(c[(k + 1) % n])]);
            area[f] = s;
        }
    });
    std::vector<glm::dvec3> normal(p.size());
    forEachIndex(p.size(), [&](size_t v) {
        glm::dvec3 s(0.0);
        for (int k = lv.vertexFaceStart[v]; k < lv.vertexFaceStart[v + 1]; ++k)
            s += area[size_t(lv.vertexFaces[size_t(k)])];
        const double len = glm::length(s);
        normal[v] = len > 0.0 ? s / len : glm::dvec3(0.0, 0.0, 1.0);
    });
    return normal;
}

void MultiresSurface::computeFrames(SubdivLevel& lv) const
{
    const std::vector<glm::dvec3>& q = lv.subdivided;
    const std::vector<glm::dvec3> normal = vertexNormals(lv, q);
    lv.frames.resize(q.size());
    forEachIndex(q.size(), [&](size_t v) {
        Frame& f = lv.frames[v];
        f.n = normal[v];
        const glm::dvec3 d = q[size_t(lv.tangentNeighbour[v])] - q[v];
        const glm::dvec3 t = d - glm::dot(d, f.n) * f.n;
        const double len = glm::length(t);
        f.t = len > 1e-300 ? t / len : anyPerpendicular(f.n);
        f.b = glm::cross(f.n, f.t);
    });
    const double sum = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, lv.edges.size(), 8192), 0.0,
        [&](const tbb::blocked_range<size_t>& r, double s) {
            for (size_t e = r.begin(); e != r.end(); ++e)
                s += glm::length(q[size_t(lv.edges[e][1])] - q[size_t(lv.edges[e][0])]);
            return s;
        },
        std::plus<double>());
    lv.meanEdgeLength = lv.edges.empty() ? 0.0 : sum / double(lv.edges.size());
}

void MultiresSurface::applyDetails(SubdivLevel& lv) const
{
    const size_t n = lv.subdivided.size();
    lv.points.resize(n);
    lv.scalar.resize(n);
    forEachIndex(n, [&](size_t v) {
        lv.points[v] = lv.subdivided[v] + lv.frames[v].toWorld(lv.detail[v]);
        lv.scalar[v] = lv.subdividedScalar[v] + lv.scalarDetail[v];
    });
}

void MultiresSurface::subdivide(int l)
{
    SubdivLevel& coarse = levels_[size_t(l) - 1];
    SubdivLevel& fine = levels_[size_t(l)];
    PointView dst{fine.subdivided.data()};
    refiner_->primvar->Interpolate(l, PointView{coarse.points.data()}, dst);
    ScalarView dstScalar{fine.subdividedScalar.data()};
    refiner_->primvar->Interpolate(l, ScalarView{coarse.scalar.data()}, dstScalar);
}

std::vector<glm::dvec2> MultiresSurface::subdivideValues(
    int l, const std::vector<glm::dvec2>& coarse) const
{
    if (l < 1 || l > levels() || coarse.size() != levels_[size_t(l) - 1].vertexCount())
        throw std::logic_error("subdivideValues: not a level's values");
    std::vector<glm::dvec2> fine(levels_[size_t(l)].vertexCount());
    // Far's interface takes the sources through the same view; it only reads them.
    ValueView<glm::dvec2> dst{fine.data()};
    refiner_->primvar->Interpolate(l, ValueView<glm::dvec2>{const_cast<glm::dvec2*>(coarse.data())},
                                   dst);
    return fine;
}

void MultiresSurface::synthesize(const DetailHook& hook)
{
    synthesizeFrom(0, hook);
}

void MultiresSurface::synthesizeFrom(int from, const DetailHook& hook)
{
    for (int l = std::max(from, 0); l <= levels(); ++l) {
        SubdivLevel& lv = levels_[size_t(l)];
        if (l > 0)
            subdivide(l);
        computeFrames(lv);
        if (hook)
            hook(l, lv);
        applyDetails(lv);
    }
}

void MultiresSurface::analyse(const Target& target)
{
    for (int l = 0; l <= levels(); ++l) {
        SubdivLevel& lv = levels_[size_t(l)];
        if (l > 0) {
            subdivide(l);
            computeFrames(lv);
            forEachIndex(lv.vertexCount(), [&](size_t v) {
                const glm::dvec3 q = lv.subdivided[v];
                const Frame& f = lv.frames[v];
                lv.detail[v] = f.toLocal(target(q, f, lv.meanEdgeLength) - q);
            });
        } else {
            computeFrames(lv);
        }
        applyDetails(lv);
    }
}

void MultiresSurface::limit(std::vector<glm::dvec3>& position,
                            std::vector<glm::dvec3>& normal) const
{
    const SubdivLevel& lv = levels_.back();
    const size_t n = lv.vertexCount();
    std::vector<glm::dvec3> src = lv.points, du(n), dv(n);
    position.assign(n, glm::dvec3(0.0));
    PointView s{src.data()}, p{position.data()}, a{du.data()}, b{dv.data()};
    refiner_->primvar->Limit(s, p, a, b);
    normal.resize(n);
    for (size_t v = 0; v < n; ++v) {
        const glm::dvec3 c = glm::cross(du[v], dv[v]);
        const double len = glm::length(c);
        normal[v] = len > 0.0 ? c / len : glm::dvec3(0.0);
    }
}

TriangleMesh levelMesh(const SubdivLevel& lv, const std::vector<glm::dvec3>* moved)
{
    TriangleMesh m;
    const std::vector<glm::dvec3>& p = moved ? *moved : lv.points;
    const std::vector<glm::dvec3> normal = vertexNormals(lv, p);
    m.points.resize(p.size());
    m.normals.resize(p.size());
    for (size_t v = 0; v < p.size(); ++v) {
        m.points[v] = openvdb::math::Vec3s(float(p[v].x), float(p[v].y), float(p[v].z));
        m.normals[v] =
            openvdb::math::Vec3s(float(normal[v].x), float(normal[v].y), float(normal[v].z));
    }
    m.triangles.reserve(2 * lv.faceCount());
    m.polygons.sizes.reserve(lv.faceCount());
    m.polygons.corners.reserve(lv.faceVerts.size());
    std::vector<uint32_t> c;
    for (size_t f = 0; f < lv.faceCount(); ++f) {
        c.assign(lv.faceVerts.begin() + lv.faceStart[f],
                 lv.faceVerts.begin() + lv.faceStart[f] + lv.faceSizes[f]);
        m.addPolygon(c.data(), c.size());
    }
    return m;
}

}  // namespace cambium
