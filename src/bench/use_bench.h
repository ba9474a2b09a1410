// cambium — `cambium bench mesh` and `cambium bench render`: using a baked
// grid, timed side by side in one process and set against the papers'
// figures.
#pragma once

#include <string>

namespace cambium {

/// Bakes the skeleton (OpenCL path) at voxel size h, then times meshing it
/// (`repeats` runs, median): triangles, seconds, triangles per second, and
/// the time a million triangles take against paper 002's 347.8 s.  Prints the table.
void runMeshBench(const std::string& skeleton, const std::string& label, double h, int repeats);

/// Bakes the skeleton at voxel size h, then renders the framing view at
/// width x height, 1 sample per pixel, with the CPU level-set march
/// (LevelSetRayIntersector) and with Embree on the level set's mesh
/// (`repeats` runs each, in turn, medians): rays per second, and the times
/// this gives for the papers' images (768 x 768: 430 s in papers 000/003;
/// 1536 x 2048 with 9 samples per pixel: about an hour).  Prints the table.
void runRenderBench(const std::string& skeleton, const std::string& label, double h, int width, int height,
                    int repeats);

}  // namespace cambium
