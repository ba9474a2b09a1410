// cambium — `cambium bench preview`: the live preview's loop as a person uses
// it.  For each year, the first picture of a whole `cambium preview --once`
// command (process start-up included, the kernel cache warm), then edits
// made as the page makes them (a curve's points sent to the page server,
// written to the file, seen by inotify, grown, baked, rendered, written,
// pushed as an event and the picture fetched by a client of the server),
// each stage timed.
#pragma once

#include "core/system.h"

#include <functional>
#include <string>
#include <vector>

namespace cambium {

struct PreviewBenchRequest {
    std::string parameters;  ///< a growth parameter file
    std::vector<int> years{10, 27};
    int edits = 5;  ///< edits a year
    Device device = Device::OpenCL;
    int width = 640, height = 480;
};

/// One stage over the edits: the median and the range.
struct PreviewBenchStage {
    double median = 0.0, min = 0.0, max = 0.0;
};

struct PreviewBenchYear {
    int year = 0;
    double voxelSize = 0.0;
    size_t leaves = 0, reusedLeaves = 0;  ///< the last edit's bake
    /// `cambium preview --once`: start to exit, and its peak memory.
    double firstCommandSeconds = 0.0, firstCommandPeakBytes = 0.0;
    double firstInProcessSeconds = 0.0;  ///< the session's first update
    /// The edits' stages: read and grow, compile, bake, render, write (the
    /// session's), push (update written to picture fetched by a client of
    /// the page server), and the whole: the page's request sent to the
    /// picture fetched.
    PreviewBenchStage read, compile, bake, render, write, push, editToPicture;
};

/// The request's options checked before any work: edits, the picture's
/// size, every year one of the growth's.  InputError naming the option.
void checkPreviewBench(const PreviewBenchRequest& req);

/// Measures each year in turn, calling `year` with each.  Throws
/// std::runtime_error when a picture does not come (naming the year).
void runPreviewBench(const PreviewBenchRequest& request,
                     const std::function<void(const PreviewBenchYear&)>& year);

}  // namespace cambium
