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

/// The memory meshLevelSet needs beyond its grids (bytes): volumeToMesh's
/// trees of the level set's topology (whose internal nodes, 32 KB each, cost
/// more than the leaves of a long thin band) and the mesh's arrays, with
/// `perPoint` bytes more for each point (a ray tracer's structures), from
/// the grid's node counts and active voxels.  Set high: what was measured
/// (on trees, a bush and needles 2 voxels thick) is 1.2-1.5x below it.
double meshingBytes(const openvdb::FloatGrid& surface, bool colour, double perPoint = 0.0);

/// InputError, before the work, where meshingBytes does not fit in the
/// memory available; `what` names the file and grid.
void checkMeshingFits(const openvdb::FloatGrid& surface, bool colour, const std::string& what,
                      double perPoint = 0.0);

/// Surface area and enclosed volume (divergence theorem; positive when the
/// triangles face outwards) of a mesh.
double meshArea(const TriangleMesh& mesh);
double meshVolume(const TriangleMesh& mesh);

}  // namespace cambium
