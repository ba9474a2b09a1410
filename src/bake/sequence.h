// cambium — baking a growth model into a frame sequence: one .vdb per frame,
// the same transform and grid names in every file, frame and time in the
// metadata (what `cambium bake PARAMS --frames A-B -o tree.####.vdb` runs).
#pragma once

#include "bake/bake.h"

#include <functional>
#include <string>
#include <vector>

namespace cambium {

struct FrameReport {
    long long frame = 0;
    double time = 0.0;       ///< years
    std::string path;
    /// Baked: sampled.  Reused: its BlobTree is the previous frame's (a
    /// dormant season): the previous grids written again.  Skipped: --resume
    /// found it finished.  Empty: nothing thicker than a voxel yet.
    enum class Outcome { Baked, Reused, Skipped, Empty } outcome = Outcome::Baked;
    BakeStats stats;
    double seconds = 0.0;    ///< building, baking and writing
};

struct SequenceReport {
    std::vector<FrameReport> frames;  ///< in frame order
    double voxelSize = 0.0;
    bool autoVoxelSize = false;
    int jobs = 1;
    double seconds = 0.0;
    double peakMemoryBytes = 0.0;
    std::string device;
};

/// Within a worker, a baked frame also reuses the sampled values of the
/// 8^3 leaves whose specialised program is unchanged since the frame it baked
/// before (LeafValueCache): identical to a full bake of the frame.
///
/// Validates everything first (parameters, frames and their times, output
/// pattern, voxel size at the last frame, memory at the last year's frames,
/// resumable files) and
/// throws InputError naming the problem before any output; then bakes the
/// frames, `jobs` at once (each year's frames in order by one worker, so a
/// frame whose BlobTree equals the previous one reuses its grids), and calls
/// `done` after each frame (from worker threads, one at a time).
SequenceReport runBakeSequence(const BakeRequest& request,
                               const std::function<void(const FrameReport&)>& done = {});

/// The key a sequence's files carry (file metadata `cambium_sequence`): a
/// hash of the parameter file's text and every option that changes a frame.
/// --resume keeps a finished frame only when its key matches.
std::string sequenceKey(const BakeRequest& request, const std::string& parameterText, double voxelSize);

}  // namespace cambium
