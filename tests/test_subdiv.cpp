// Multi-resolution Catmull-Clark surfaces: closed forms, OpenSubdiv as a
// second path, frames, analysis and synthesis, control mesh checks.
#include "core/half_edges.h"
#include "shape/base_shapes.h"
#include "subdiv/multires.h"
#include "test_util.h"

#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>

#include <cmath>
#include <random>

using namespace cambium;

namespace {

/// The vertex of `lv` nearest to `p`.
size_t nearest(const std::vector<glm::dvec3>& pts, const glm::dvec3& p)
{
    size_t best = 0;
    for (size_t i = 1; i < pts.size(); ++i)
        if (glm::length(pts[i] - p) < glm::length(pts[best] - p))
            best = i;
    return best;
}

}  // namespace

TEST(Subdiv, CubeLimitPointsAreTheClosedForms)
{
    // The cube [-1, 1]^3: corner limit (n^2 v + 4 sum e + sum f) / (n (n + 5))
    // with n = 3 gives (9 + 4 - 1) / 24 = 1/2 per coordinate; the face centre,
    // a regular vertex after one step (v = 1, edge points 3/4, corners 5/9),
    // gives (16 + 12 + 20/9) / 36 = 68/81.
    MultiresSurface s(cubeBase(2.0).mesh, 8, "cube");
    s.synthesize();
    const auto& fine = s.finest().points;
    for (int c = 0; c < 8; ++c)  // a vertex keeps its index at every level
        for (int k = 0; k < 3; ++k)
            EXPECT_NEAR(std::fabs(fine[size_t(c)][k]), 0.5, 1e-5) << "corner " << c;
    const size_t top = nearest(fine, {0, 0, 1});
    EXPECT_NEAR(fine[top].z, 68.0 / 81.0, 1e-5);
    EXPECT_NEAR(fine[top].x, 0.0, 1e-12);

    // OpenSubdiv's limit evaluation, a second path: exact at every vertex.
    std::vector<glm::dvec3> lim, normal;
    s.limit(lim, normal);
    for (int c = 0; c < 8; ++c)
        for (int k = 0; k < 3; ++k)
            EXPECT_NEAR(std::fabs(lim[size_t(c)][k]), 0.5, 1e-12);
    EXPECT_NEAR(lim[top].z, 68.0 / 81.0, 1e-12);
    EXPECT_NEAR(glm::dot(normal[top], glm::dvec3(0, 0, 1)), 1.0, 1e-12);  // outward
    test::report("level 8: corner {:.9f}, face centre {:.9f} (68/81 = {:.9f})", fine[7].x,
                 fine[top].z, 68.0 / 81.0);
}

TEST(Subdiv, UnitSpikeOnAFlatGridFollowsTheMasks)
{
    // One control point of a flat grid raised by 1: one step gives 9/16 at
    // it, 3/8 at its edges' new points, 1/4 at its faces' centres; its limit
    // is 16/36 = 4/9 (the regular limit mask).
    BaseShape plane = planeBase(8.0, 8);
    const size_t centre = 4 * 9 + 4;
    plane.mesh.points[centre].z = 1.0;
    MultiresSurface s(plane.mesh, 1, "grid");
    s.synthesize();
    const auto& p = s.level(1).points;
    const glm::dvec3 c = plane.mesh.points[centre];
    EXPECT_DOUBLE_EQ(p[nearest(p, {c.x, c.y, 1})].z, 9.0 / 16.0);
    EXPECT_DOUBLE_EQ(p[nearest(p, {c.x + 0.5, c.y, 0.5})].z, 3.0 / 8.0);
    EXPECT_DOUBLE_EQ(p[nearest(p, {c.x + 0.5, c.y + 0.5, 0.25})].z, 1.0 / 4.0);
    EXPECT_DOUBLE_EQ(p[nearest(p, {c.x + 1.5, c.y, 0})].z, 0.0);  // outside the support
    std::vector<glm::dvec3> lim, normal;
    s.limit(lim, normal);
    EXPECT_NEAR(lim[centre].z, 4.0 / 9.0, 1e-12);
    // The boundary stays in the plane and on the square's edge.
    for (size_t v = 0; v < p.size(); ++v) {
        if (s.level(1).boundary[v]) {
            EXPECT_NEAR(std::max(std::fabs(p[v].x), std::fabs(p[v].y)), 4.0, 1e-12);
        }
    }
}

TEST(Subdiv, NoDetailsIsPlainSubdivisionBitForBit)
{
    // OpenSubdiv's own refinement of the same mesh, in double.
    namespace Far = OpenSubdiv::Far;
    namespace Sdc = OpenSubdiv::Sdc;
    const BaseShape torus = torusBase(2.0, 0.7, 8, 6);
    const int levels = 4;
    MultiresSurface s(torus.mesh, levels, "torus");
    s.synthesize();

    Sdc::Options sdc;
    sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_AND_CORNER);
    Far::TopologyDescriptor desc;
    desc.numVertices = int(torus.mesh.points.size());
    desc.numFaces = int(torus.mesh.faceCount());
    desc.numVertsPerFace = torus.mesh.faceSizes.data();
    desc.vertIndicesPerFace = torus.mesh.faceVerts.data();
    // The surface may have turned the faces outwards: compare with its level 0.
    std::vector<int> verts = s.level(0).faceVerts;
    desc.vertIndicesPerFace = verts.data();
    using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
    std::unique_ptr<Far::TopologyRefiner> r(
        Factory::Create(desc, Factory::Options(Sdc::SCHEME_CATMARK, sdc)));
    r->RefineUniform(Far::TopologyRefiner::UniformOptions(levels));
    struct V {
        double x, y, z;
        void Clear() { x = y = z = 0; }
        void AddWithWeight(const V& o, double w) { x += w * o.x, y += w * o.y, z += w * o.z; }
    };
    std::vector<V> a(size_t(r->GetNumVerticesTotal()));
    for (size_t i = 0; i < torus.mesh.points.size(); ++i)
        a[i] = {torus.mesh.points[i].x, torus.mesh.points[i].y, torus.mesh.points[i].z};
    Far::PrimvarRefinerReal<double> pr(*r);
    V* src = a.data();
    for (int l = 1; l <= levels; ++l) {
        V* dst = src + r->GetLevel(l - 1).GetNumVertices();
        pr.Interpolate(l, src, dst);
        src = dst;
    }
    const auto& fine = s.finest().points;
    ASSERT_EQ(fine.size(), size_t(r->GetLevel(levels).GetNumVertices()));
    size_t differ = 0;
    for (size_t i = 0; i < fine.size(); ++i)
        differ += fine[i].x != src[i].x || fine[i].y != src[i].y || fine[i].z != src[i].z;
    EXPECT_EQ(differ, 0u);
}

TEST(Subdiv, FramesAreOrthonormalOutwardAndTheirOwnDetailsLeaveThemAlone)
{
    MultiresSurface s(sphereBase(1.0).mesh, 5, "sphere");
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-0.01, 0.01);
    for (int l = 1; l <= 5; ++l)
        for (auto& d : s.level(l).detail)
            d = {u(rng), u(rng), u(rng)};
    s.synthesize();
    for (int l = 0; l <= 5; ++l) {
        const SubdivLevel& lv = s.level(l);
        for (size_t v = 0; v < lv.vertexCount(); ++v) {
            const Frame& f = lv.frames[v];
            ASSERT_NEAR(glm::length(f.t), 1.0, 1e-12);
            ASSERT_NEAR(glm::length(f.b), 1.0, 1e-12);
            ASSERT_NEAR(glm::length(f.n), 1.0, 1e-12);
            ASSERT_NEAR(glm::dot(f.t, f.n), 0.0, 1e-12);
            ASSERT_NEAR(glm::dot(f.t, f.b), 0.0, 1e-12);
            ASSERT_NEAR(glm::dot(glm::cross(f.t, f.b), f.n), 1.0, 1e-12);  // right-handed
            ASSERT_GT(glm::dot(f.n, glm::normalize(lv.subdivided[v])), 0.9) << "level " << l;
        }
    }
    // Level 3's details changed: its frames stay, level 4's move.
    const std::vector<Frame> f3 = s.level(3).frames, f4 = s.level(4).frames;
    for (auto& d : s.level(3).detail)
        d *= -3.0;
    s.synthesizeFrom(3);
    size_t same3 = 0, moved4 = 0;
    for (size_t v = 0; v < f3.size(); ++v)
        same3 += f3[v].n == s.level(3).frames[v].n && f3[v].t == s.level(3).frames[v].t;
    for (size_t v = 0; v < f4.size(); ++v)
        moved4 += f4[v].n != s.level(4).frames[v].n;
    EXPECT_EQ(same3, f3.size());
    EXPECT_GT(moved4, f4.size() / 2);
}

TEST(Subdiv, AnalysisThenSynthesisReproducesTheAnalysedPoints)
{
    // Fine surface: a bumpy sphere, r(p) = 1 + 0.1 sin(5x) sin(4y) cos(3z).
    auto bumpy = [](const glm::dvec3& q, const Frame&, double) {
        const glm::dvec3 d = glm::normalize(q);
        return d * (1.0 + 0.1 * std::sin(5 * d.x) * std::sin(4 * d.y) * std::cos(3 * d.z));
    };
    const int levels = 6;
    MultiresSurface s(cubeBase(1.0).mesh, levels, "cube");
    s.analyse(bumpy);
    // Synthesis from the details alone, after the points were thrown away.
    for (int l = 1; l <= levels; ++l)
        s.level(l).points.assign(s.level(l).vertexCount(), glm::dvec3(0.0));
    s.synthesize();
    double worst = 0.0;
    for (int l = 1; l <= levels; ++l) {
        const SubdivLevel& lv = s.level(l);
        for (size_t v = 0; v < lv.vertexCount(); ++v) {
            const glm::dvec3 want = bumpy(lv.subdivided[v], lv.frames[v], lv.meanEdgeLength);
            worst = std::max(worst, glm::length(lv.points[v] - want));
        }
    }
    EXPECT_LT(worst, 1e-9);
    test::report("round trip over {} levels: largest error {:.3g}", levels, worst);
}

TEST(Subdiv, ControlMeshChecksNameTheProblem)
{
    auto refused = [](ControlMesh m, const std::string& words) {
        try {
            checkControlMesh(m, "m.obj");
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
            return;
        }
        ADD_FAILURE() << "accepted: " << words;
    };
    ControlMesh cube = cubeBase(2).mesh;
    const MeshTopologyStats st = checkControlMesh(cube, "cube");
    EXPECT_EQ(st.eulerCharacteristic(), 2);
    EXPECT_TRUE(st.closed());
    EXPECT_GT(enclosedVolume(cube), 7.99);

    ControlMesh flipped = cube;  // one face reversed
    std::reverse(flipped.faceVerts.begin(), flipped.faceVerts.begin() + 4);
    refused(flipped, "not consistently oriented");
    ControlMesh fin = cube;  // a third face on an edge
    fin.points.push_back({0, 0, 3});
    fin.faceSizes.push_back(3);
    fin.faceVerts.insert(fin.faceVerts.end(), {0, 2, 8});
    refused(fin, "not a 2-manifold");
    ControlMesh bowtie;  // two triangles sharing only a point
    bowtie.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}};
    bowtie.faceSizes = {3, 3};
    bowtie.faceVerts = {0, 1, 2, 0, 3, 4};
    refused(bowtie, "not one fan");
    ControlMesh unused = cube;
    unused.points.push_back({5, 5, 5});
    refused(unused, "point 8 is used by no face");
    ControlMesh badIndex = cube;
    badIndex.faceVerts[3] = 42;
    refused(badIndex, "uses point 42");
    ControlMesh nan = cube;
    nan.points[2].y = std::nan("");
    refused(nan, "point 2 is not finite");
    EXPECT_THROW(MultiresSurface(cube, 16, "cube"), InputError);

    const MeshTopologyStats torus = checkControlMesh(torusBase(2, 0.5, 8, 6).mesh, "torus");
    EXPECT_EQ(torus.eulerCharacteristic(), 0);
    const MeshTopologyStats plane = checkControlMesh(planeBase(1, 3).mesh, "plane");
    EXPECT_EQ(plane.eulerCharacteristic(), 1);
    EXPECT_EQ(plane.boundaryEdges, 12u);
    EXPECT_EQ(checkControlMesh(fuseBase(3, 1, 2, 8, 8).mesh, "fuse").eulerCharacteristic(), 2);
}

// One search of the half-edges serves the control meshes and the meshes
// baked into level sets (core/half_edges.h): a twin runs its corner's edge
// back, twins pair up, and a fan of triangles finds the same pairs as the
// same mesh given as polygons.
TEST(Subdiv, HalfEdgesPairEachEdgeWithTheFaceRunningItBack)
{
    auto check = [](const ControlMesh& m, size_t boundary) {
        std::vector<size_t> first(1, 0);
        for (int n : m.faceSizes)
            first.push_back(first.back() + size_t(n));
        std::vector<uint32_t> corner(m.faceVerts.begin(), m.faceVerts.end());
        const FaceCorners faces{first.data(), m.faceSizes.size(), 0, corner.data(),
                                m.points.size()};
        const HalfEdges he = findHalfEdges(faces);
        EXPECT_EQ(he.firstBad, HalfEdges::kNone);
        size_t open = 0;
        for (size_t c = 0; c < corner.size(); ++c) {
            const uint32_t t = he.twin[c];
            if (t == HalfEdges::kNone) {
                ++open;
                continue;
            }
            EXPECT_EQ(he.twin[t], c);
            EXPECT_EQ(corner[t], corner[faces.next(c)]);
            EXPECT_EQ(corner[faces.next(t)], corner[c]);
            EXPECT_NE(faces.faceOf(t), faces.faceOf(c));
        }
        EXPECT_EQ(open, boundary);
        return he;
    };
    check(cubeBase(2).mesh, 0);
    check(torusBase(2, 0.5, 8, 6).mesh, 0);
    check(planeBase(1, 3).mesh, 12);

    // A quad and the same quad fanned into two triangles of fixed size 3.
    const std::vector<uint32_t> tris = {0, 1, 2, 0, 2, 3, 0, 3, 4};
    const FaceCorners fan{nullptr, 3, 3, tris.data(), 5};
    const HalfEdges he = findHalfEdges(fan);
    EXPECT_EQ(he.twin[2], 3u);  // 2 -> 0 runs back as 0 -> 2
    EXPECT_EQ(he.twin[5], 6u);
    EXPECT_EQ(std::count(he.twin.begin(), he.twin.end(), HalfEdges::kNone), 5);
    EXPECT_EQ(he.start[0], 0u);
    EXPECT_EQ(he.start[1], 3u);  // point 0 is a corner of all three

    // An edge run the same way twice, and one shared by three faces.
    const std::vector<uint32_t> twice = {0, 1, 2, 0, 1, 3};
    EXPECT_EQ(findHalfEdges(FaceCorners{nullptr, 2, 3, twice.data(), 4}).firstBad, 0u);
    const std::vector<uint32_t> three = {0, 1, 2, 1, 0, 3, 1, 0, 4};
    EXPECT_EQ(findHalfEdges(FaceCorners{nullptr, 3, 3, three.data(), 5}).firstBad, 0u);
    // A face that uses a point twice has no edges of its own.
    const std::vector<uint32_t> flat = {0, 1, 1, 1, 0, 2};
    const HalfEdges f = findHalfEdges(FaceCorners{nullptr, 2, 3, flat.data(), 3});
    EXPECT_EQ(f.firstBad, HalfEdges::kNone);
    EXPECT_EQ(std::count(f.twin.begin(), f.twin.end(), HalfEdges::kNone), 6);
}
