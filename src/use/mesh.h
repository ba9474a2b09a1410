// cambium — polygonising a baked level set (openvdb::tools::volumeToMesh).
#pragma once

#include "io/grids.h"
#include "io/mesh_file.h"

#include <array>
#include <iosfwd>
#include <string>
#include <vector>

namespace cambium {

/// Where meshLevelSet's time went (seconds).
struct MeshTimings {
    double polygons = 0.0;    ///< volumeToMesh
    double triangles = 0.0;   ///< its quads split
    double attributes = 0.0;  ///< normals and colours at the points
};

/// The zero iso-surface of a level set (negative inside), quads split into
/// two triangles along their shorter diagonal.  `adaptivity` in [0, 1] is
/// volumeToMesh's (0: uniform, higher: fewer triangles where flat).  With a
/// colour grid, each point gets its colour (trilinear).
TriangleMesh meshLevelSet(const openvdb::FloatGrid& surface,
                          const openvdb::Vec3fGrid* color = nullptr, double adaptivity = 0.0,
                          MeshTimings* timings = nullptr);

/// Surface area and enclosed volume (divergence theorem; positive when the
/// triangles face outwards) of a mesh.
double meshArea(const TriangleMesh& mesh);
double meshVolume(const TriangleMesh& mesh);

}  // namespace cambium
