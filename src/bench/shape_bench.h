// cambium — `cambium bench shape`: multi-scale shape synthesis (paper 004)
// against OpenSubdiv's plain uniform refinement of the same mesh, an edit's
// re-synthesis, and cambium's mesh -> level set against OpenVDB's
// meshToLevelSet, side by side in one process.
#pragma once

#include <cstddef>
#include <functional>
#include <string>

namespace cambium {

struct ShapeBenchRequest {
    int levels = 8;            ///< of the rock cube-sphere (8: 393,218 vertices)
    int editLevel = 7;         ///< the edit re-synthesised on a shape of this many levels
    double voxelSize = 0.005;  ///< of the mesh -> level set step
    int repeats = 3;
};

struct ShapeBenchResult {
    int levels = 0;
    size_t vertices = 0, faces = 0;
    // Median seconds.
    double osdTopology = 0.0, osdInterpolate = 0.0;  ///< OpenSubdiv: refiner, then primvars
    double setup = 0.0;           ///< cambium: topology and the sphere's fitted details
    double synthesis = 0.0;       ///< cambium: every level subdivided, framed, rock added
    double plainSynthesis = 0.0;  ///< cambium: the same without details (frames included)
    /// The same rock blended with a second rock across a plane (both sides'
    /// details, the alpha, the blend parameter's channels) and shaded by the
    /// terrain shader, against the rock alone: synthesis, then the mesh with
    /// its colours (where the shader runs), each on a surface made once (as
    /// a sequence's frames are).
    double aloneSynthesis = 0.0, blendSynthesis = 0.0, plainMesh = 0.0, shadedMesh = 0.0;
    int editLevel = 0;
    size_t editVertices = 0;
    double edit = 0.0;  ///< re-synthesis of the edit level after its details changed
    // Mesh -> level set.
    double voxelSize = 0.0;
    size_t cambiumVoxels = 0, openvdbVoxels = 0, compared = 0;
    double cambiumBake = 0.0, openvdbBake = 0.0;
    double largestDifference = 0.0;  ///< voxels, over band voxels within 1 voxel of the surface
    size_t beyondTolerance = 0;      ///< of those, how many differ by more than 0.05 voxel
    /// A sample of those measured against every triangle: how many of the
    /// sample each method has right (within 0.001 voxel).
    size_t bruteChecked = 0, bruteCambium = 0, bruteOpenVdb = 0;
};

/// Runs every method `repeats` times in turn; `progress` names each step.
ShapeBenchResult runShapeBench(const ShapeBenchRequest& request,
                               const std::function<void(const std::string&)>& progress = {});

}  // namespace cambium
