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

/// Runs `argv` (argv[0] a path) under GNU time (/usr/bin/time, for the peak
/// memory) with standard output and error going to `logPath` (appended; the
/// peak in `logPath`.rss) and waits for it.  Throws std::runtime_error when it cannot
/// be started or does not exit with status 0 (naming the log).
ProcessRun runProcess(const std::vector<std::string>& argv, const std::string& logPath);

}  // namespace cambium
