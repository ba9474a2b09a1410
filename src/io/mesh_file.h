// cambium — triangle meshes and their files: Wavefront OBJ and binary PLY
// written through the checked writer, OBJ and PLY (ascii or binary) read.
#pragma once

#include <openvdb/math/Vec3.h>

#include <array>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

namespace cambium {

/// A triangle mesh in world space, counter-clockwise seen from outside.
/// `polygons` keeps faces of more corners (the quads of a subdivision
/// surface, the faces of a file read): when set, the writers write them and
/// `triangles` is their fan, which everything else reads.
struct TriangleMesh {
    std::vector<openvdb::math::Vec3s> points;
    std::vector<openvdb::math::Vec3s>
        normals;  ///< unit, outward: the level set's gradient at each point
    std::vector<openvdb::math::Vec3s>
        colors;                ///< from the Cd grid at each point; empty without one
    std::vector<float> alpha;  ///< a PLY's vertex "alpha" in [0, 1] (read only); empty without one
    std::vector<std::array<uint32_t, 3>> triangles;
    struct Polygons {
        std::vector<uint32_t> sizes, corners;
        bool empty() const { return sizes.empty(); }
    } polygons;

    /// Adds a face of n >= 3 corners: into polygons, and fanned into triangles.
    void addPolygon(const uint32_t* corners, size_t n);
};

/// Writes the mesh as Wavefront OBJ (points, normals, triangles; colours as
/// the common "v x y z r g b" extension) or as binary little-endian PLY
/// (points, normals, 8-bit colours, faces), chosen by the extension of
/// `path` (.obj or .ply), through a temporary file.  Throws InputError for
/// another extension or an unwritable path.
void writeMesh(const TriangleMesh& mesh, const std::string& path);

/// Reads a triangle mesh from OBJ (v [r g b], vn, f with any of its corner
/// forms, polygons fanned) or PLY (ascii or binary little-endian; x y z,
/// optional nx ny nz, red green blue and alpha (integers scaled to [0, 1]),
/// faces as vertex_indices lists), such
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

}  // namespace cambium
