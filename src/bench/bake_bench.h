// cambium — `cambium bench bake`: cambium's bake against the ways a user
// would do the same job today, side by side in one process.
#pragma once

#include "bench/process_run.h"

#include "model/skeleton.h"

#include <openvdb/Grid.h>
#include <openvdb/openvdb.h>

#include <functional>
#include <string>
#include <vector>

namespace cambium {

struct BakeBenchCase {
    Skeleton skeleton;  ///< e.g. generateBenchSkeleton's
    std::string label;  ///< e.g. "1k internodes"
    double voxelSize = 0.01;
    double halfWidth = 3.0;
    /// The skeleton's text (what generateBenchSkeleton wrote), for the
    /// whole-process rows: cambium bake and cambium-ptls read it from a
    /// file.  Empty: no whole-process rows.
    std::string text;
};

/// A whole command's runs: median, fastest and slowest wall time, median
/// peak memory, the file it wrote.

/// checkLevelSet's Eikonal test (9) counted: zero-crossing voxels, and those
/// of them whose squared gradient norm is outside [0.5, 1.5].
struct EikonalCount {
    size_t crossing = 0, outside = 0;
    double fraction() const { return crossing ? double(outside) / double(crossing) : 0.0; }
};
/// Counted on `grid` (fifth-order WENO gradients, CheckEikonal's own functor).
EikonalCount eikonalOutliers(const openvdb::FloatGrid& grid);

struct BakeBenchRow {
    std::string method;
    double seconds = 0.0;
    bool estimated = false;  ///< extrapolated from a timed part
    double activeVoxels = 0.0;
    double peakBytes = 0.0;  ///< peak resident memory during the run
};

/// One case's table.
struct BakeBenchResult {
    std::string label;
    size_t primitives = 0;
    double voxelSize = 0.0, halfWidth = 0.0;
    double boxVoxels = 0.0;  ///< voxels of the bounding box (what (c) evaluates)
    int repeats = 0;
    std::vector<BakeBenchRow> rows;  ///< (a), (b) unless skipped, (c), (d)
    /// Writing (a)'s grids (surface and Cd, Blosc), medians: cambium's file
    /// made in memory (leaves compressed on all cores), the same through
    /// OpenVDB's serial writer, cambium's whole checked write (temporary,
    /// fsync, rename), and io::File::write as a user of OpenVDB writes.
    double encodeParallel = 0.0, encodeSerial = 0.0, writeVdbSeconds = 0.0, fileWrite = 0.0;
    double fileBytes = 0.0;
    EikonalCount eikonal, peerEikonal;  ///< (a)'s and (d)'s grids
    /// Whole processes (when the case has its text): `cambium bake` and the
    /// peer program cambium-ptls (ParticlesToLevelSet, io::File::write).
    ProcessSummary process, peerProcess;
};

/// Runs, for each case: (a) cambium's OpenCL bake, (b) cambium's CPU bake
/// over the same topology, (c) a naive dense evaluation of the same field
/// (every voxel of the bounding box, every primitive; extrapolated from a
/// timed slab), (d) OpenVDB's ParticlesToLevelSet of spheres along every
/// internode (minimum radius lowered to 1 voxel).  (a), (b) and (d) run in
/// turn `repeats` times and report their median.  Then, for a case with its
/// text, the whole commands `cambium bake` and `cambium-ptls` in turn
/// `repeats` times.  `done` gets each case's table as it is finished.
std::vector<BakeBenchResult> runBakeBench(
    const std::vector<BakeBenchCase>& cases, bool skipCpu = false, int repeats = 3,
    const std::function<void(const BakeBenchResult&)>& done = {});

}  // namespace cambium
