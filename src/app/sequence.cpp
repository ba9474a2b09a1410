// cambium bake --frames — a growth sequence's report, frame by frame.
#include "app/app.h"

#include "bake/sequence.h"
#include "core/frames.h"

#include <fmt/format.h>

#include <cstdio>

namespace cambium {

int runSequenceCommand(const SequenceRequest& request, bool timings)
{
    const char* outcome[] = {"baked", "reused: its BlobTree is the previous frame's",
                             "kept: --resume", "empty: nothing a voxel thick yet"};
    SequenceCallbacks callbacks;
    callbacks.notice = printNotice;
    size_t doneFrames = 0;
    const size_t total = parseFrames(request.frames).size();
    callbacks.done = [&](const FrameReport& f) {
        ++doneFrames;
        // A line a farm manager parses: "frame I/N done S s -> PATH", then
        // in parentheses what was done.
        fmt::print("frame {}/{} done {:.2f} s -> {} ({}, frame {}, year {:.3g}", doneFrames, total,
                   f.seconds, f.path, outcome[int(f.outcome)], f.frame, f.time);
        if (f.outcome == FrameReport::Outcome::Baked) {
            fmt::print(", {} active voxels", formatCount(double(f.stats.activeVoxels)));
            if (f.stats.reusedLeaves)
                fmt::print(" ({} of {} leaves unchanged, not sampled)",
                           formatCount(double(f.stats.reusedLeaves)),
                           formatCount(double(f.stats.candidateLeaves)));
        }
        fmt::print(")\n");
        std::fflush(stdout);
        if (timings && f.outcome == FrameReport::Outcome::Baked)
            printTimings(f.stats);
    };
    const SequenceReport r = bakeSequence(request, callbacks);
    size_t baked = 0, reused = 0, kept = 0, empty = 0;
    for (const FrameReport& f : r.frames)
        ++(f.outcome == FrameReport::Outcome::Baked     ? baked
           : f.outcome == FrameReport::Outcome::Reused  ? reused
           : f.outcome == FrameReport::Outcome::Skipped ? kept
                                                        : empty);
    fmt::print(
        "sequence {}: {} frames ({} baked, {} reused, {} kept, {} empty) in {:.1f} s, {} at once, "
        "voxel size "
        "{:g}{}, device {}, peak memory {:.0f} MB\n",
        request.bake.output, r.frames.size(), baked, reused, kept, empty, r.seconds, r.jobs,
        r.voxelSize, r.autoVoxelSize ? " (auto: 512 voxels across the last frame)" : "", r.device,
        r.peakMemoryBytes / 1e6);
    return 0;
}

}  // namespace cambium
