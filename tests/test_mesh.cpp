// Meshing a baked level set: area and volume of a sphere and a capsule against
// their closed forms, a closed and consistently oriented 2-manifold, vertices
// on the zero crossing, outward normals; OBJ and PLY files that read back.
#include "use/mesh.h"

#include "bake_util.h"
#include "core/error.h"
#include "test_util.h"

#include <gtest/gtest.h>
#include <openvdb/tools/Interpolation.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

namespace {

using namespace cambium;
using namespace cambium::test;

/// Every undirected edge in exactly two triangles, once in each direction.
void expectClosedManifold(const TriangleMesh& m)
{
    std::map<std::pair<uint32_t, uint32_t>, int> directed;
    for (const auto& t : m.triangles)
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = t[size_t(k)], b = t[size_t((k + 1) % 3)];
            ASSERT_NE(a, b) << "degenerate triangle";
            ++directed[{a, b}];
        }
    for (const auto& [e, count] : directed) {
        ASSERT_EQ(count, 1) << "edge " << e.first << "-" << e.second << " used twice the same way";
        const auto back = directed.find({e.second, e.first});
        ASSERT_TRUE(back != directed.end())
            << "edge " << e.first << "-" << e.second << " on the border";
    }
}

/// Vertices on the zero crossing of the trilinear level set, normals outward.
void expectOnSurface(const TriangleMesh& m, const openvdb::FloatGrid& g,
                     const glm::dvec3& centreOfMass)
{
    openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> s(g);
    const double h = g.voxelSize()[0];
    double worst = 0.0;
    for (size_t i = 0; i < m.points.size(); ++i) {
        worst = std::max(worst, std::abs(double(s.wsSample(m.points[i]))) / h);
        const openvdb::Vec3d out = openvdb::Vec3d(m.points[i]) -
                                   openvdb::Vec3d(centreOfMass.x, centreOfMass.y, centreOfMass.z);
        ASSERT_GT(out.dot(openvdb::Vec3d(m.normals[i])), 0.0) << "vertex " << i;  // convex shapes
        ASSERT_NEAR(m.normals[i].length(), 1.0, 1e-5);
    }
    EXPECT_LT(worst, 0.05) << "largest |distance| at a vertex, voxels";
}

TEST(Mesh, SphereHasItsAreaAndVolume)
{
    BlobTree tree;
    const glm::dvec3 c(0.013, -0.021, 0.007);
    const double r = 0.5, h = 0.02;
    tree.setRoot(tree.sphere(c, r));
    tree.finalize();
    const BakedGrids g = bakeTree(tree, h);
    const TriangleMesh m = meshLevelSet(*g.surface);
    ASSERT_GT(m.triangles.size(), 1000u);
    const double area = 4.0 * M_PI * r * r, volume = 4.0 / 3.0 * M_PI * r * r * r;
    // A polygon inscribed in the surface loses area and volume of the order
    // of (voxel / radius)^2: 0.16 % here.
    EXPECT_NEAR(meshArea(m) / area, 1.0, 0.005);
    EXPECT_NEAR(meshVolume(m) / volume, 1.0, 0.005);
    expectClosedManifold(m);
    expectOnSurface(m, *g.surface, c);
}

TEST(Mesh, CapsuleHasItsAreaAndVolume)
{
    BlobTree tree;
    const glm::dvec3 a(-0.3, -0.2, 0.1), b(0.4, 0.5, -0.2);
    const double r = 0.17, h = 0.01, L = glm::length(b - a);
    tree.setRoot(tree.segment(a, b, r));
    tree.finalize();
    const BakedGrids g = bakeTree(tree, h);
    const TriangleMesh m = meshLevelSet(*g.surface);
    const double area = 2.0 * M_PI * r * L + 4.0 * M_PI * r * r;
    const double volume = M_PI * r * r * L + 4.0 / 3.0 * M_PI * r * r * r;
    EXPECT_NEAR(meshArea(m) / area, 1.0, 0.005);
    EXPECT_NEAR(meshVolume(m) / volume, 1.0, 0.005);
    expectClosedManifold(m);
    expectOnSurface(m, *g.surface, 0.5 * (a + b));
}

TEST(Mesh, AdaptivityKeepsTheShapeWithFewerTriangles)
{
    BlobTree tree;
    const double r = 0.5, volume = 4.0 / 3.0 * M_PI * r * r * r;
    tree.setRoot(tree.sphere({0, 0, 0}, r));
    tree.finalize();
    const BakedGrids g = bakeTree(tree, 0.02);
    const TriangleMesh fine = meshLevelSet(*g.surface, nullptr, 0.0);
    for (double adaptivity : {0.05, 0.5}) {
        const TriangleMesh coarse = meshLevelSet(*g.surface, nullptr, adaptivity);
        const double v = meshVolume(coarse) / volume;
        report("adaptivity {:.2f}: {} triangles (0: {}), volume {:.4f} of the sphere's", adaptivity,
               coarse.triangles.size(), fine.triangles.size(), v);
        EXPECT_LT(coarse.triangles.size(), fine.triangles.size() / 2);
        // Flat cells of up to a leaf (8 voxels) cut the sphere of radius 25
        // voxels: 1.7 % of its volume at 0.05 (1,356 triangles), 6 % at 0.5 (348).
        EXPECT_NEAR(v, 1.0, adaptivity < 0.1 ? 0.025 : 0.08);
        expectClosedManifold(coarse);
    }
}

TEST(Mesh, ColoursComeFromTheCdGrid)
{
    // Two spheres of different colours: each vertex takes its sphere's colour.
    BlobTree tree;
    const int a = tree.sphere({-0.4, 0, 0}, 0.25), b = tree.sphere({0.4, 0, 0}, 0.25);
    tree.setColor(a, {1.0, 0.0, 0.0});
    tree.setColor(b, {0.0, 0.0, 1.0});
    tree.setRoot(tree.op(Combiner{}, {a, b}));  // a blend
    tree.finalize();
    const BakedGrids g = bakeTree(tree, 0.02);
    const TriangleMesh m = meshLevelSet(*g.surface, g.color.get());
    ASSERT_EQ(m.colors.size(), m.points.size());
    for (size_t i = 0; i < m.points.size(); ++i) {
        const bool left = m.points[i][0] < 0.0f;
        EXPECT_NEAR(m.colors[i][0], left ? 1.0 : 0.0, 0.02) << "vertex " << i;
        EXPECT_NEAR(m.colors[i][2], left ? 0.0 : 1.0, 0.02) << "vertex " << i;
    }
}

TEST(Mesh, NormalsAndColoursAreTheSamplersOwnUnderAnyTransform)
{
    // The CPU reference: a vertex's normal is the normalised difference of
    // six trilinear lookups half a voxel either side, its colour the
    // trilinear Cd, each through OpenVDB's GridSampler at the world point;
    // on the bake's own (scale and move) transform, where the mesh samples
    // in index space, and on a turned one, where it cannot.
    BlobTree tree;
    const int a = tree.sphere({-0.3, 0.05, 0}, 0.25), b = tree.sphere({0.3, -0.05, 0.1}, 0.25);
    tree.setColor(a, {1.0, 0.2, 0.0});
    tree.setColor(b, {0.0, 0.3, 1.0});
    tree.setRoot(tree.op(Combiner{}, {a, b}));
    tree.finalize();
    const BakedGrids g = bakeTree(tree, 0.02);
    ASSERT_TRUE(g.color);
    for (bool turned : {false, true}) {
        openvdb::FloatGrid::Ptr surface = g.surface->deepCopy();
        openvdb::Vec3fGrid::Ptr colour = g.color->deepCopy();
        if (turned) {
            for (openvdb::GridBase* grid : {static_cast<openvdb::GridBase*>(surface.get()),
                                            static_cast<openvdb::GridBase*>(colour.get())})
                grid->transform().postRotate(0.3, openvdb::math::Y_AXIS);
        }
        const TriangleMesh m = meshLevelSet(*surface, colour.get());
        ASSERT_GT(m.points.size(), 500u);
        openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> s(*surface);
        openvdb::tools::GridSampler<openvdb::Vec3fGrid, openvdb::tools::BoxSampler> c(*colour);
        const double h = surface->voxelSize()[0];
        double worstNormal = 0.0, worstColour = 0.0;
        for (size_t i = 0; i < m.points.size(); ++i) {
            const openvdb::Vec3d p(m.points[i]);
            openvdb::Vec3d d;
            for (int k = 0; k < 3; ++k) {
                openvdb::Vec3d e(0.0);
                e[k] = 0.5 * h;
                d[k] = double(s.wsSample(p + e)) - double(s.wsSample(p - e));
            }
            d.normalize();
            worstNormal = std::max(worstNormal, (d - openvdb::Vec3d(m.normals[i])).length());
            worstColour = std::max(worstColour, double((c.wsSample(p) - m.colors[i]).length()));
        }
        EXPECT_LT(worstNormal, 1e-6) << (turned ? "turned" : "the bake's transform");
        EXPECT_LT(worstColour, 1e-5) << (turned ? "turned" : "the bake's transform");
    }
}

TEST(Mesh, ASparseLevelSetsMeshingIsRefusedWhereItWouldNotFit)
{
    // 8,000 leaves, each alone in its internal node of 128^3 voxels (32 KB),
    // a plane through each: 16 MB of leaves, 270 MB of nodes, and
    // volumeToMesh builds trees of the same nodes three times more.  Under
    // an address-space limit of 600 MB above what the test holds it ran out
    // of memory inside volumeToMesh; now it is refused before, by name.
    auto grid = openvdb::FloatGrid::create(0.3f);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    auto acc = grid->getAccessor();
    for (int i = 0; i < 20; ++i)
        for (int j = 0; j < 20; ++j)
            for (int k = 0; k < 20; ++k) {
                const openvdb::Coord o(i * 128, j * 128, k * 128);
                auto* leaf = acc.touchLeaf(o);
                for (auto it = leaf->beginValueAll(); it; ++it) {
                    it.setValue(0.1f * (float(it.getCoord().z() - o.z()) - 3.5f));
                    it.setValueOn();
                }
            }
    EXPECT_GT(meshingBytes(*grid, false), 0.9e9);
    expectRefusedUnderAddressSpaceLimit(
        6e8,
        [&] {
            checkMeshingFits(*grid, false, "planes.vdb");
            meshLevelSet(*grid);
        },
        [](const std::string& what) {
            return what.rfind(
                       "meshing planes.vdb (8,000 leaves, 4,096,000 active voxels) needs "
                       "about ",
                       0) == 0;
        });
}

TEST(Mesh, TheColourShellGivesTheBandsColoursAtEveryVertex)
{
    // A mesh's colours looked up in Cd kept on the shell (the default) are
    // those of Cd on the whole band: equal, or within a step of 8-bit colour
    // where a leaf of one colour became a tile.  Blended spheres: every
    // colour between red and blue.
    BlobTree tree;
    const int a = tree.sphere({-0.3, 0, 0}, 0.3), b = tree.sphere({0.3, 0.05, 0}, 0.3);
    tree.setColor(a, {1.0, 0.2, 0.0});
    tree.setColor(b, {0.0, 0.3, 1.0});
    tree.setRoot(tree.op(Combiner{}, {a, b}));
    tree.finalize();
    const BakedGrids band = bakeTree(tree, 0.01, 3.0, true, false, ColourExtent::Band),
                     shell = bakeTree(tree, 0.01, 3.0, true, false, ColourExtent::Shell);
    const TriangleMesh mb = meshLevelSet(*band.surface, band.color.get()),
                       ms = meshLevelSet(*shell.surface, shell.color.get());
    ASSERT_EQ(mb.points.size(), ms.points.size());
    ASSERT_GT(mb.points.size(), 10000u);
    size_t equal = 0;
    float most = 0.0f;
    for (size_t i = 0; i < mb.points.size(); ++i) {
        const openvdb::Vec3f d = ms.colors[i] - mb.colors[i];
        most = std::max({most, std::abs(d[0]), std::abs(d[1]), std::abs(d[2])});
        equal += d == openvdb::Vec3f(0.0f);
    }
    EXPECT_LE(most, 1.0f / 255.0f + 1e-6f);
    EXPECT_GT(equal, mb.points.size() / 2);
    EXPECT_LT(shell.color->activeVoxelCount() - 512 * shell.color->tree().activeTileCount(),
              band.color->activeVoxelCount() * 3 / 4);
}

TEST(Mesh, FilesReadBack)
{
    BlobTree tree;
    tree.setRoot(tree.sphere({0, 0, 0}, 0.3));
    tree.finalize();
    const BakedGrids g = bakeTree(tree, 0.03);
    const TriangleMesh m = meshLevelSet(*g.surface, g.color.get());
    const auto dir =
        std::filesystem::temp_directory_path() / ("cambium_mesh_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string obj = (dir / "s.obj").string(), ply = (dir / "s.ply").string();
    writeMesh(m, obj);
    writeMesh(m, ply);
    {  // OBJ: one v and vn per point, one f per triangle
        std::ifstream in(obj);
        std::string line;
        size_t v = 0, vn = 0, f = 0;
        while (std::getline(in, line)) {
            v += line.rfind("v ", 0) == 0;
            vn += line.rfind("vn ", 0) == 0;
            f += line.rfind("f ", 0) == 0;
        }
        EXPECT_EQ(v, m.points.size());
        EXPECT_EQ(vn, m.points.size());
        EXPECT_EQ(f, m.triangles.size());
    }
    {  // PLY: the header's counts, then exactly the binary payload they announce
        std::ifstream in(ply, std::ios::binary);
        std::string line, header;
        size_t vertices = 0, faces = 0;
        while (std::getline(in, line) && line != "end_header") {
            std::istringstream w(line);
            std::string a, b;
            size_t n = 0;
            w >> a >> b >> n;
            if (a == "element" && b == "vertex")
                vertices = n;
            if (a == "element" && b == "face")
                faces = n;
            header += line + "\n";
        }
        EXPECT_NE(header.find("format binary_little_endian 1.0"), std::string::npos);
        EXPECT_EQ(vertices, m.points.size());
        EXPECT_EQ(faces, m.triangles.size());
        const auto start = in.tellg();
        in.seekg(0, std::ios::end);
        EXPECT_EQ(size_t(in.tellg() - start), vertices * (24 + 3) + faces * 13);
    }
    // No temporary file left; an unknown format is refused before writing.
    EXPECT_THROW(writeMesh(m, (dir / "s.stl").string()), InputError);
    size_t files = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        (void)e;
        ++files;
    }
    EXPECT_EQ(files, 2u);

    // readMesh gives back what was written: PLY exactly, OBJ to its 5 digits.
    for (const std::string& path : {ply, obj}) {
        const TriangleMesh r = readMesh(path);
        const float tol = path == ply ? 0.0f : 1e-4f;
        ASSERT_EQ(r.points.size(), m.points.size()) << path;
        ASSERT_EQ(r.triangles.size(), m.triangles.size()) << path;
        ASSERT_EQ(r.colors.size(), m.colors.size()) << path;
        for (size_t i = 0; i < m.points.size(); ++i)
            for (int k = 0; k < 3; ++k) {
                ASSERT_NEAR(r.points[i][k], m.points[i][k], tol) << path << " point " << i;
                ASSERT_NEAR(r.normals[i][k], m.normals[i][k], tol) << path << " normal " << i;
                // Colours: 8 bits in PLY, 5 digits in OBJ.
                ASSERT_NEAR(r.colors[i][k], m.colors[i][k], 0.5f / 255.0f + tol)
                    << path << " colour " << i;
            }
        for (size_t i = 0; i < m.triangles.size(); ++i)
            ASSERT_EQ(r.triangles[i], m.triangles[i]) << path << " triangle " << i;
    }
    std::filesystem::remove_all(dir);
}

/// Writes `text` to a file of the temporary directory and reads it as a mesh.
TriangleMesh readText(const std::string& name, const std::string& text)
{
    const auto path =
        std::filesystem::temp_directory_path() / (std::to_string(::getpid()) + "_" + name);
    {
        std::ofstream out(path, std::ios::binary);
        out << text;
    }
    struct Remove {
        std::filesystem::path p;
        ~Remove() { std::filesystem::remove(p); }
    } remove{path};
    return readMesh(path.string());
}

/// The unit cube [0,1]^3 as six outward quads, in OBJ and in ASCII PLY.
const char* kCubeObj =
    "# a cube\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
    "vt 0 0\ng cube\ns off\n"
    "f 1 4 3 2\nf 5/1 6/1 7/1 8/1\nf 1 2 6 5\nf -5 -1 -2 -6\nf 1 5 8 4\nf 2 3 7 6\n";
const char* kCubePly =
    "ply\nformat ascii 1.0\ncomment a cube\nelement vertex 8\nproperty float x\n"
    "property float y\nproperty float z\nproperty float red\nproperty float green\n"
    "property float blue\nelement face 6\nproperty list uchar int vertex_indices\nend_header\n"
    "0 0 0 1 0 0\n1 0 0 1 0 0\n1 1 0 1 0 0\n0 1 0 1 0 0\n0 0 1 0 0 1\n1 0 1 0 0 1\n"
    "1 1 1 0 0 1\n0 1 1 0 0 1\n"
    "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 3 7 6 2\n4 0 4 7 3\n4 1 2 6 5\n";

TEST(Mesh, ReadsOtherToolsObjAndPly)
{
    for (const auto& [name, text] :
         {std::pair<const char*, const char*>{"cube.obj", kCubeObj}, {"cube.ply", kCubePly}}) {
        const TriangleMesh m = readText(name, text);
        EXPECT_EQ(m.points.size(), 8u) << name;
        EXPECT_EQ(m.triangles.size(), 12u) << name;  // quads fanned
        EXPECT_NEAR(meshArea(m), 6.0, 1e-9) << name;
        EXPECT_NEAR(meshVolume(m), 1.0, 1e-9) << name;  // outward: positive
        // Normals made from the faces: unit, away from the centre (area
        // weights over the fanned triangles tilt them from the diagonal).
        ASSERT_EQ(m.normals.size(), 8u) << name;
        for (size_t i = 0; i < 8; ++i) {
            const openvdb::Vec3s out = m.points[i] - openvdb::Vec3s(0.5f);
            EXPECT_NEAR(m.normals[i].length(), 1.0, 1e-6) << name << " vertex " << i;
            EXPECT_GT(m.normals[i].dot(out) / out.length(), 0.9) << name << " vertex " << i;
        }
    }
    // An int alpha is on uchar's 0-255 scale as a uchar one (it was divided
    // by 2^32 - 1: every int alpha read as 0).
    const TriangleMesh intAlpha =
        readText("alpha.ply",
                 "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                 "property float z\nproperty int alpha\nelement face 1\nproperty list uchar int "
                 "vertex_indices\nend_header\n0 0 0 255\n1 0 0 51\n0 1 0 0\n3 0 1 2\n");
    ASSERT_EQ(intAlpha.alpha.size(), 3u);
    EXPECT_FLOAT_EQ(intAlpha.alpha[0], 1.0f);
    EXPECT_FLOAT_EQ(intAlpha.alpha[1], 0.2f);
    const TriangleMesh ply = readText("cube.ply", kCubePly);
    ASSERT_EQ(ply.colors.size(), 8u);
    EXPECT_EQ(ply.colors[0], openvdb::Vec3s(1, 0, 0));
    EXPECT_EQ(ply.colors[7], openvdb::Vec3s(0, 0, 1));
}

TEST(Mesh, UnreadableMeshFilesAreNamedWithTheirLine)
{
    auto expectRefused = [](const std::string& name, const std::string& text,
                            const std::string& message) {
        test::expectInputError([&] { readText(name, text); }, message, name);
    };
    expectRefused("a.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
                  "a.obj:4: vertex index 4 out of range");
    expectRefused("b.obj", "v 0 0\n", "b.obj:1: 'v' expects 3 numbers");
    expectRefused("c.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n",
                  "c.obj:3: a face needs at least 3 vertices");
    expectRefused("d.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 x 3\n", "d.obj:4: bad face corner 'x'");
    expectRefused("e.obj", "# nothing\n", "the mesh has no faces");
    expectRefused("e2.obj", "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\nf 3 2 1\n",
                  "e2.obj: the mesh has no area: every face's corners lie on one line or at one "
                  "point");
    // A tetrahedron 1e-14 across has area (5e-29), but not in float
    // arithmetic (its cross products' squares underflow): named as small.
    expectRefused("e3.obj",
                  "v 0 0 0\nv 1e-14 0 0\nv 0 1e-14 0\nv 0 0 1e-14\n"
                  "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
                  "e3.obj: the mesh is too small for single precision: its largest face's area is "
                  "8.66e-29");
    expectRefused("f.ply", "ply\nformat binary_big_endian 1.0\nend_header\n",
                  "binary_big_endian' is not read");
    expectRefused("g.ply", "PLY\n", "not a PLY file");
    expectRefused("h.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n",
                  "no end_header");
    expectRefused("i.ply",
                  "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float "
                  "x\nproperty float y\n"
                  "property float z\nend_header\n1234",
                  "the file ends inside element 'vertex'");
    expectRefused("j.ply",
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float q\nend_header\n1\n",
                  "the vertex element has no x, y, z");
    expectRefused("k.stl", "solid\n", "unknown mesh format '.stl'");
    // Colours and alphas off their scale: an integer beyond 255 (a 16-bit
    // scale, read as 300/255), a real alpha beyond 1.
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\n";
    const std::string face = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    expectRefused(
        "l.ply",
        header + "property uchar alpha\n" + face + "0 0 0 1\n1 0 0 300\n0 1 0 0\n3 0 1 2\n",
        "l.ply: vertex 1 ('alpha'): 300 is not within 0-255");
    expectRefused(
        "m.ply",
        header + "property float alpha\n" + face + "0 0 0 1\n1 0 0 1.5\n0 1 0 0\n3 0 1 2\n",
        "m.ply: vertex 1 ('alpha'): 1.5 is not within 0-1");
    expectRefused("n.ply",
                  header + "property ushort red\nproperty ushort green\nproperty ushort blue\n" +
                      face + "0 0 0 1 2 3\n1 0 0 65535 0 0\n0 1 0 0 0 0\n3 0 1 2\n",
                  "n.ply: vertex 1 ('red'): 65535 is not within 0-255");
    expectRefused(
        "o.ply",
        header + "property uchar alpha\n" + face + "0 0 0 1\n1 0 0 2.5\n0 1 0 0\n3 0 1 2\n",
        "o.ply: vertex 1 ('alpha'): 2.5 is not within 0-255");
    // An OBJ's vertex colours on 0-1 (1e30 drew a picture of 1e30, exit 0).
    expectRefused("p.obj", "v 0 0 0 1e30 0 0\nv 1 0 0 1 1 1\nv 0 1 0 1 1 1\nf 1 2 3\n",
                  "p.obj:1: vertex 1: colour 1e+30 is outside 0-1");
    // A vertex's weight (OBJ's optional w) is read past.
    EXPECT_EQ(readText("w.obj", "v 0 0 0 1\nv 1 0 0 1\nv 0 1 0 1\nf 1 2 3\n").points.size(), 3u);
    // Points no tool can draw (Embree's build overflowed on 1e38 and aborted).
    expectRefused("l.obj", "v 0 0 0\nv 1e38 0 1\nv 0 1 0\nf 1 2 3\n",
                  "l.obj:2: vertex 2 lies 1e+38 from the origin, beyond the 1e+15");
    // Numbers beyond a float or not numbers are named as such (they were
    // "'v' expects 3 numbers").
    expectRefused("l2.obj", "v 1e300 1 1\n", "l2.obj:1: vertex 1 lies 1e+300 from the origin");
    expectRefused("l3.obj", "v 0 0 0\nv nan 0 0\n", "l3.obj:2: vertex 2 has a value nan");
    expectRefused("l4.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n",
                  "l4.obj:4: bad face corner '99999999999999999999'");
    // Lists whose counts or indices are not whole numbers, as written.
    const std::string plyFloatList =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list float float vertex_indices\n"
        "end_header\n0 0 0\n1 0 0\n0 1 0\n";
    expectRefused("n.ply", plyFloatList + "2.5 0 1 2\n", "element 'face' 0: a list of 2.5 items");
    expectRefused("o.ply", plyFloatList + "3 0 1.5 2\n",
                  "element 'face' 0: vertex index 1.5 is not a whole number");
    expectRefused("q.ply",
                  "ply\nformat ascii 1.0\nelement vertex -1\nproperty float x\nend_header\n",
                  "q.ply:3: element 'vertex' has count '-1' (not a whole number of items)");
    // A binary element of no properties takes no bytes, whatever its count:
    // read past at once (it looped over 2^64 items).
    const std::string junk =
        "ply\nformat binary_little_endian 1.0\nelement junk 18446744073709551615\n"
        "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    std::string body = junk;
    for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f})
        body.append(reinterpret_cast<const char*>(&v), 4);
    body.push_back(char(3));
    for (int32_t i : {0, 1, 2})
        body.append(reinterpret_cast<const char*>(&i), 4);
    EXPECT_EQ(readText("r.ply", body).triangles.size(), 1u);
    const float inf = std::numeric_limits<float>::infinity();
    std::memcpy(body.data() + junk.size() + 4 * 5, &inf, 4);  // vertex 1's z
    expectRefused("m.ply", body, "m.ply: vertex 1 ('z') has a value inf (not a finite number)");
    expectRefused("s.ply",
                  "ply\nformat ascii 1.0\nelement vertex 18446744073709551616\nend_header\n",
                  "element 'vertex' has count '18446744073709551616'");
    EXPECT_THROW(readMesh("/nonexistent/m.obj"), InputError);
    // A NUL byte ended the corner for strtol, which took "2\0junk" as 2.
    static const char nul[] = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\0junk 3\n";
    expectRefused("t.obj", std::string(nul, sizeof nul - 1), "t.obj:4: the line holds a NUL byte");
    // PLY versions other than 1.0, and a property or mesh element twice
    // (which x is the vertex's?), are refused by their header line.
    expectRefused("u.ply", "ply\nformat ascii 2.0\nend_header\n",
                  "u.ply:2: PLY version '2.0' is not read (1.0 is)");
    expectRefused("v.ply",
                  "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
                  "y\nproperty double x\nend_header\n",
                  "v.ply:6: element 'vertex' has a second property 'x'");
    expectRefused("w.ply",
                  "ply\nformat ascii 1.0\nelement vertex 0\nelement vertex 0\nend_header\n",
                  "w.ply:4: a second 'vertex' element");
    expectRefused("x.ply", "ply\rformat ascii 1.0\r",
                  "x.ply:1: the line ends with a lone carriage");
}

TEST(Mesh, ObjLinesEndAsAnyEditorEndsThem)
{
    // LF, CRLF and old Mac CR files, and a UTF-8 byte-order mark (Windows
    // editors write one), all read as the same cube; the bare CR file was
    // read as one line, a mesh of one vertex and no faces.
    std::string crlf, cr;
    for (const char* c = kCubeObj; *c; ++c) {
        crlf += *c == '\n' ? std::string("\r\n") : std::string(1, *c);
        cr += *c == '\n' ? '\r' : *c;
    }
    for (const auto& [name, text] : {std::pair<std::string, std::string>{"lf.obj", kCubeObj},
                                     {"crlf.obj", crlf},
                                     {"cr.obj", cr},
                                     {"bom.obj", "\xEF\xBB\xBF" + std::string(kCubeObj)}}) {
        const TriangleMesh m = readText(name, text);
        EXPECT_EQ(m.points.size(), 8u) << name;
        EXPECT_EQ(m.triangles.size(), 12u) << name;
        EXPECT_NEAR(meshVolume(m), 1.0, 1e-9) << name;
    }
    // Lines are counted across bare CRs as an editor shows them.
    std::string bad = "v 0 0 0\rv 1 0 0\rv 0 1 0\rf 1 2 4\r";
    test::expectInputError([&] { readText("y.obj", bad); }, "y.obj:4: vertex index 4", "y.obj");
}

}  // namespace
