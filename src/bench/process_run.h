// cambium — a whole command timed as a user runs it: wall time from start
// to exit, and the peak resident memory the kernel accounted to it.
#pragma once

#include <string>
#include <vector>

namespace cambium {

struct ProcessRun {
    double seconds = 0.0;
    double peakBytes = 0.0;  ///< the command's peak resident memory (GNU time's %M)
};

/// Repeated runs of one command: the median time with its spread, the
/// median peak memory (and the file it wrote, where the caller fills it).
struct ProcessSummary {
    double seconds = 0.0, minSeconds = 0.0, maxSeconds = 0.0;
    double peakBytes = 0.0, fileBytes = 0.0;
};
ProcessSummary summariseRuns(const std::vector<ProcessRun>& runs);

/// runChild (core/process.h) with standard output and errors appended to
/// `logPath`; throws std::runtime_error when the command does not exit 0
/// (naming the log) or its own peak memory cannot be measured (no GNU time:
/// refused before it runs).
ProcessRun runProcess(const std::vector<std::string>& argv, const std::string& logPath);

}  // namespace cambium
