// cambium — polygonising a baked level set (openvdb::tools::volumeToMesh) and
// writing the mesh as OBJ or binary PLY.
#pragma once

#include <openvdb/openvdb.h>

#include <array>
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

/// Surface area and enclosed volume (divergence theorem; positive when the
/// triangles face outwards) of a mesh.
double meshArea(const TriangleMesh& mesh);
double meshVolume(const TriangleMesh& mesh);

}  // namespace cambium
