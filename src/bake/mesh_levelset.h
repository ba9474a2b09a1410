// cambium — a closed triangle mesh baked into a narrow-band level set: exact
// distances to the triangles, signs from angle-weighted pseudo-normals
// (Baerentzen and Aanaes), colours interpolated at the nearest points.
#pragma once

#include "bake/levelset.h"
#include "io/mesh_file.h"

#include <functional>
#include <string>

namespace cambium {

struct MeshBakeOptions {
    double voxelSize = 0.0;                     ///< world units per voxel (> 0)
    double halfWidth = 3.0;                     ///< voxels
    bool fog = false;                           ///< also the `density` fog volume
    ColourExtent colour = ColourExtent::Shell;  ///< where Cd is kept
    std::function<void(const char* stage, double fraction)> progress;
};

/// The mesh's surface as a level set like a field's bake (io/grids.h:
/// `surface`, class level set, negative inside, background halfWidth * h;
/// `Cd` from the points' colours when the mesh has them).  Each band voxel
/// holds the exact distance to its nearest triangle; the sign is that of
/// (p - c) . N, N the pseudo-normal of the nearest feature (face, edge or
/// corner), which is exact for a closed, consistently oriented mesh.
/// InputError naming `what` when the mesh has a boundary or an edge of more
/// than two triangles (no inside), or is empty.
BakedGrids bakeMeshLevelSet(const TriangleMesh& mesh, const MeshBakeOptions& options,
                            const std::string& what);

/// What bakeMeshLevelSet refuses before it bins a triangle (InputError naming
/// `what`): the options, an empty mesh, points missing, not finite or beyond
/// OpenVDB's index space, and a binning that would not fit in memory.  For a
/// sequence, every frame's mesh is checked so before any frame is written.
void checkMeshBake(const TriangleMesh& mesh, const MeshBakeOptions& options,
                   const std::string& what);

/// The largest extent of the mesh's points' bounding box.
double meshExtent(const TriangleMesh& mesh);

}  // namespace cambium
