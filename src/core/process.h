// cambium — one command run to its end by this process, timed and its peak
// memory measured: the tiles' bakes of `bake --tiles` and the whole-command
// benchmarks.
#pragma once

#include <string>
#include <vector>

namespace cambium {

struct ChildRun {
    int status = 0;          ///< its exit status, or 128 + the signal that ended it
    double seconds = 0.0;    ///< wall time from start to exit
    double peakBytes = 0.0;  ///< its peak resident memory
    /// Whether peakBytes is the command's own (measured by GNU time).
    /// Without /usr/bin/time it is the kernel's account of the child, which
    /// starts from this process's own peak (Linux keeps the larger of the
    /// exec'ed address space's high-water mark and the new one).
    bool peakExact = false;
};

/// Where a command's output goes.
struct ChildOutput {
    /// Its standard output and errors, appended; "": its output discarded,
    /// its errors this process's.
    std::string log;
    /// Where GNU time writes the peak (read, then removed).
    std::string peakFile;
};

/// Whether a command's own peak can be measured: GNU time (/usr/bin/time)
/// is installed.
bool measuresOwnPeak();

/// Runs `argv` (argv[0] a path) and waits for it.  It runs in a process
/// group of its own, under GNU time (/usr/bin/time) where that is
/// installed; a signal that ends this process reaches the whole group first
/// (RemoveOnSignal), and waits for it.  Throws std::runtime_error when it
/// cannot be started.  A cambium it runs ends itself when this process is
/// gone, however it ended (endWithParent).
ChildRun runChild(const std::vector<std::string>& argv, const ChildOutput& output);

/// In a cambium that runChild started: ends this process by SIGTERM (its
/// cleanup, installCleanupOnSignals, removes its temporaries) once the
/// process that started it is gone, killed by SIGKILL too (a tiled bake's
/// tile went on baking as an orphan).  It watches a pipe whose only writer
/// is that process (`CAMBIUM_PARENT_FD`).  Nothing elsewhere.
void endWithParent();

}  // namespace cambium
