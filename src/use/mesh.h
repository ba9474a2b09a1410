// cambium — polygonising a baked level set (openvdb::tools::volumeToMesh) and
// writing the mesh as OBJ or binary PLY.
#pragma once

#include <openvdb/openvdb.h>

#include <array>
#include <iosfwd>
#include <string>
#include <vector>

namespace cambium {

/// A triangle mesh in world space, counter-clockwise seen from outside.
struct TriangleMesh {
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3s> normals;  ///< unit, outward: the level set's gradient at each point
    std::vector<openvdb::Vec3s> colors;   ///< from the Cd grid at each point; empty without one
    std::vector<std::array<uint32_t, 3>> triangles;
};

/// The zero iso-surface of a level set (negative inside), quads split into
/// two triangles along their shorter diagonal.  `adaptivity` in [0, 1] is
/// volumeToMesh's (0: uniform, higher: fewer triangles where flat).  With a
/// colour grid, each point gets its colour (trilinear).
TriangleMesh meshLevelSet(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color = nullptr,
                          double adaptivity = 0.0);

/// Writes the mesh as Wavefront OBJ (points, normals, triangles; colours as
/// the common "v x y z r g b" extension) or as binary little-endian PLY
/// (points, normals, 8-bit colours, faces), chosen by the extension of
/// `path` (.obj or .ply), through a temporary file.  Throws InputError for
/// another extension or an unwritable path.
void writeMesh(const TriangleMesh& mesh, const std::string& path);

/// Reads a triangle mesh from OBJ (v [r g b], vn, f with any of its corner
/// forms, polygons fanned) or PLY (ascii or binary little-endian; x y z,
/// optional nx ny nz and red green blue, faces as vertex_indices lists), such
/// as writeMesh and other tools write.  Missing normals are made from the
/// triangles.  InputError naming the file (and line) for anything it cannot
/// read.
TriangleMesh readMesh(const std::string& path);
/// readMesh of a stream holding a mesh of `format` "obj" or "ply" (`name`
/// names it in messages).
TriangleMesh parseMesh(std::istream& in, const std::string& name, const std::string& format);

/// Throws InputError, before any work, when `path` is not a .obj or .ply
/// file that can be written.
void checkMeshOutput(const std::string& path);

/// `cambium mesh`: the float level-set grid `grid` of a .vdb file (and its
/// `Cd` grid when present) meshed and written to `output`; for a sequence,
/// input and output are patterns with a run of `#` and `frames` a range
/// (core/frames.h): one mesh per frame.
struct MeshRequest {
    std::string input, output, grid = "surface", frames;
    double adaptivity = 0.0;
};
/// Runs it and prints a one-line summary per file; InputError, before any
/// work, for a bad output path or a missing input file, and for a file
/// without the grid or whose grid is not a float level set.
int runMeshCommand(const MeshRequest& request);

/// Surface area and enclosed volume (divergence theorem; positive when the
/// triangles face outwards) of a mesh.
double meshArea(const TriangleMesh& mesh);
double meshVolume(const TriangleMesh& mesh);

}  // namespace cambium
