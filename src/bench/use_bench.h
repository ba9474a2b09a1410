// cambium — `cambium bench mesh` and `cambium bench render`: using a baked
// grid, timed side by side in one process and set against the papers'
// figures.
#pragma once

#include "model/skeleton.h"

#include <string>

namespace cambium {

struct MeshBenchResult {
    std::string label;
    double voxelSize = 0.0;
    size_t activeVoxels = 0;
    int runs = 0;
    size_t triangles = 0;
    double seconds = 0.0;  ///< median
};

/// Bakes the skeleton's summation blend (OpenCL path) at voxel size h, then
/// times meshing it (`repeats` runs, median), to set against paper 002's
/// 347.8 s for a million triangles.
MeshBenchResult runMeshBench(const Skeleton& skeleton, const std::string& label, double h,
                             int repeats);

struct RenderBenchResult {
    std::string label;
    double voxelSize = 0.0;
    size_t activeVoxels = 0, triangles = 0;
    int width = 0, height = 0, runs = 0;
    double coverage = 0.0;                           ///< fraction of rays that hit
    double opencl = 0.0, march = 0.0, embree = 0.0;  ///< median seconds of each method
    /// Set-up not counted in the methods' times.
    double gridBytes = 0.0, openclSetup = 0.0, marchSetup = 0.0, meshSeconds = 0.0,
           bvhSeconds = 0.0;
};

/// Bakes the skeleton at voxel size h, then renders the framing view at
/// width x height, 1 sample per pixel, with the CPU level-set march
/// (LevelSetRayIntersector) and with Embree on the level set's mesh
/// (`repeats` runs each, in turn, medians): rays per second, and the times
/// this gives for the papers' images (768 x 768: 430 s in papers 000/003;
/// 1536 x 2048 with 9 samples per pixel: about an hour); the OpenCL march too.
RenderBenchResult runRenderBench(const Skeleton& skeleton, const std::string& label, double h,
                                 int width, int height, int repeats);

}  // namespace cambium
