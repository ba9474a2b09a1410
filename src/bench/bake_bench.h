// cambium — `cambium bench bake`: cambium's bake against the ways a user
// would do the same job today, side by side in one process.
#pragma once

#include <string>
#include <vector>

namespace cambium {

struct BakeBenchCase {
    std::string skeleton;      ///< skeleton file (docs/skeleton-format.md)
    std::string label;         ///< e.g. "1k internodes"
    double voxelSize = 0.01;
    double halfWidth = 3.0;
};

struct BakeBenchRow {
    std::string method;
    double seconds = 0.0;
    bool estimated = false;    ///< extrapolated from a timed part
    double activeVoxels = 0.0;
    double peakBytes = 0.0;    ///< peak resident memory during the run
};

/// Runs, for each case: (a) cambium's OpenCL bake, (b) cambium's CPU bake
/// over the same topology, (c) a naive dense evaluation of the same field
/// (every voxel of the bounding box, every primitive; extrapolated from a
/// timed slab), (d) OpenVDB's ParticlesToLevelSet of spheres along every
/// internode (minimum radius lowered to 1 voxel).  (a), (b) and (d) run in
/// turn `repeats` times and report their median.  Prints the table.
std::vector<std::vector<BakeBenchRow>> runBakeBench(const std::vector<BakeBenchCase>& cases,
                                                    bool skipCpu = false, int repeats = 3);

/// Writes skeletons with ../shared/bench/gen_skeleton.py (python3).
std::string generateSkeleton(const std::string& generator, int internodes, const std::string& dir);

}  // namespace cambium
