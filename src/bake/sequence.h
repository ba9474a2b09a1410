// cambium — baking a growth model into a frame sequence: one .vdb per frame,
// the same transform and grid names in every file, frame and time in the
// metadata (what `cambium bake PARAMS --frames A-B -o tree.####.vdb` runs).
//
// A sequence is a plan (every frame's time and file, the one voxel size of
// the whole sequence, the reuse groups, the memory a frame needs), made once
// and checked before any output, and a runner that bakes any range of it:
// two processes baking halves of one plan write frames that one process
// would have written.
#pragma once

#include "bake/bake.h"
#include "core/files.h"
#include "model/growth.h"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace cambium {

/// InputError unless `fpsPerYear` (--fps-per-year) is a positive number of
/// at most 1e6.
void checkFpsPerYear(double fpsPerYear);

struct SequenceRequest {
    /// The growth parameter file, the output pattern (a run of '#' for the
    /// frame number), voxel size (default: 512 voxels across the last
    /// frame), half-width, device, fog, half, threads; model.leaves.
    BakeRequest bake;
    std::string frames;  ///< FIRST-LAST[:STEP]; frame f is year f / fpsPerYear
    double fpsPerYear = 1.0;
    bool resume = false;  ///< keep the frames a previous run of the same bake finished
    int jobs = 0;         ///< frames baked at once; 0: as many as cores and memory allow
};

/// Everything a sequence is, decided before any frame is baked.
struct SequencePlan {
    SequenceRequest request;
    std::shared_ptr<const GrowthModel> model;
    std::vector<long long> frames;   ///< in the order of --frames
    std::vector<double> times;       ///< years, one per frame
    std::vector<std::string> paths;  ///< files, one per frame
    double voxelSize = 0.0;          ///< the whole sequence's (the last frame sizes it)
    bool autoVoxelSize = false;
    double bytesPerFrame = 0.0;  ///< estimated memory of the largest frame's bake
    double fileBytes = 0.0;      ///< estimated bytes of all the frames' files
    double bandVoxels = 0.0;     ///< estimated band voxels of all the frames
    double threshold = 0.5;
    /// Reuse groups: frames of one growth year, in order (indices into
    /// frames).  A worker bakes a group in order, so that a dormant frame
    /// finds its predecessor's grids and unchanged leaves.
    std::vector<std::vector<size_t>> groups;
    std::string key;  ///< sequenceKey: what --resume compares
    BarkPaint paint;  ///< the bark photo, read once
};

/// The tree a sequence's frame of skeleton `sk` bakes: `model`'s tree of it
/// with its parts thinner than `minRadius` voxels of `voxelSize` thickened
/// (bake/thicken.h): what the plan estimates and the frame's bake samples.
BlobTree frameTree(const GrowthModel& model, const Skeleton& sk, double minRadius,
                   double voxelSize);

/// Validates everything (parameters, frames and their times, output pattern,
/// voxel size at the last frame, memory at the last year's frames) and
/// throws InputError naming the problem before any output.
SequencePlan planSequence(const SequenceRequest& request);

/// Frames a run of `frames` of the plan bakes at once: --jobs, else the
/// cores, at most what memory holds and the frames there are.
int sequenceJobs(const SequencePlan& plan, size_t frames);

struct FrameReport {
    long long frame = 0;
    double time = 0.0;  ///< years
    std::string path;
    /// Baked: sampled.  Reused: its BlobTree is the previous frame's (a
    /// dormant season): the previous grids written again.  Skipped: --resume
    /// found it finished.  Empty: nothing thicker than a voxel yet.
    enum class Outcome { Baked, Reused, Skipped, Empty } outcome = Outcome::Baked;
    BakeStats stats;
    double seconds = 0.0;  ///< building, baking and writing
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

struct SequenceCallbacks {
    /// Things a user should know that are not errors, one line each.
    std::function<void(const std::string&)> notice;
    /// After each frame (from worker threads, one at a time).
    std::function<void(const FrameReport&)> done;
};

/// The files of a sequence's `frames` written to `pattern`, each checked as an
/// output before any work: InputError unless the pattern has a run of '#'
/// for the frame number (`example` shows one: "out/tree.####.vdb"), where a
/// frame is one of the `inputs` (through a link) or two frames are one file.
/// What every sequence writer (growth and shape) names its frames by.
std::vector<std::string> sequencePaths(const std::string& pattern,
                                       const std::vector<long long>& frames, const char* example,
                                       const std::vector<std::string>& inputs);

/// The key a sequence's files carry (file metadata `cambium_sequence`, what
/// --resume matches): a hash of its main input's `text`, the `options` that
/// change its frames and the bytes of every other file it reads (`files`,
/// filesContentKey).  Growth and shape sequences alike.
std::string sequenceKeyOf(const std::string& text, const std::string& options,
                          const std::vector<std::string>& files);

/// The outputs of frames [first, last) of a sequence (`paths`, matching the
/// output `pattern`), made ready for writing: one run at a time writes a
/// range (a lock file: PATTERN.frames-A-B.lock for frames A to B; a run
/// whose frames overlap is refused), temporaries that killed runs
/// left for the range's frames are removed (`notice`d), and with `resume`
/// the frames already finished with this sequence's `key` are found (a
/// damaged one is baked again; one from another bake is refused:
/// InputError).  Every sequence writer (growth and shape) goes through this.
class SequenceOutput {
public:
    SequenceOutput(const std::string& pattern, const std::vector<long long>& frames,
                   const std::vector<std::string>& paths, size_t first, size_t last,
                   const std::string& key, bool resume,
                   const std::function<void(const std::string&)>& notice);
    /// Whether frame i (an index into the paths) was found finished.
    bool finished(size_t i) const { return finished_[i]; }
    /// Whether every frame of the range was found finished.
    bool allFinished() const;

private:
    OutputLock lock_;
    std::vector<bool> finished_;
    size_t first_, last_;
};

/// Bakes frames [first, last) of the plan (indices into plan.frames), `jobs`
/// at once, each reuse group in order by one worker.  Within a worker, a
/// baked frame also reuses the sampled values of the 8^3 leaves whose
/// specialised program is unchanged since the frame it baked before
/// (LeafValueCache): identical to a full bake of the frame.  One run at a
/// time writes a range (a lock file: PATTERN.frames-A-B.lock for frames A
/// to B; runs of ranges that overlap are refused); temporaries that killed runs left for the
/// range's frames are removed; with --resume, finished frames of this plan
/// are kept, damaged ones baked again, and another bake's refused
/// (InputError).
SequenceReport runSequence(const SequencePlan& plan, size_t first, size_t last,
                           const SequenceCallbacks& callbacks = {});

/// planSequence, then runSequence of every frame.
SequenceReport bakeSequence(const SequenceRequest& request,
                            const SequenceCallbacks& callbacks = {});

/// The key a sequence's files carry (file metadata `cambium_sequence`): a
/// hash of the parameter file's text and every option that changes a frame.
/// --resume keeps a finished frame only when its key matches.
std::string sequenceKey(const SequenceRequest& request, const std::string& parameterText,
                        double voxelSize);

}  // namespace cambium
