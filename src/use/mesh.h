// cambium — polygonising a baked level set (openvdb::tools::volumeToMesh).
#pragma once

#include "io/grids.h"
#include "io/mesh_file.h"

#include <openvdb/openvdb.h>

#include <array>
#include <iosfwd>
#include <string>
#include <vector>

namespace cambium {

/// The zero iso-surface of a level set (negative inside), quads split into
/// two triangles along their shorter diagonal.  `adaptivity` in [0, 1] is
/// volumeToMesh's (0: uniform, higher: fewer triangles where flat).  With a
/// colour grid, each point gets its colour (trilinear).
TriangleMesh meshLevelSet(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color = nullptr,
                          double adaptivity = 0.0);

/// `cambium mesh`: the float level-set grid `grid` of a .vdb file (and its
/// `Cd` grid when present) meshed and written to `output`; for a sequence,
/// input and output are patterns with a run of `#` and `frames` a range
/// (core/frames.h): one mesh per frame.
struct MeshRequest {
    std::string input, output, grid = kSurfaceGrid, frames;
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
