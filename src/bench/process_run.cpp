// cambium — running and measuring a whole command.
#include "bench/process_run.h"

#include "bench/median.h"
#include "core/process.h"

#include <algorithm>
#include <stdexcept>

#include <fmt/format.h>

namespace cambium {

ProcessSummary summariseRuns(const std::vector<ProcessRun>& runs)
{
    ProcessSummary s;
    std::vector<double> t, m;
    for (const ProcessRun& r : runs) {
        t.push_back(r.seconds);
        m.push_back(r.peakBytes);
    }
    s.seconds = medianOf(t);
    s.minSeconds = *std::min_element(t.begin(), t.end());
    s.maxSeconds = *std::max_element(t.begin(), t.end());
    s.peakBytes = medianOf(m);
    return s;
}

ProcessRun runProcess(const std::vector<std::string>& argv, const std::string& logPath)
{
    if (!measuresOwnPeak())
        throw std::runtime_error(
            "the whole-process benchmark needs GNU time (/usr/bin/time) for a command's own peak "
            "memory: bash tools/setup.sh packages installs it");
    const ChildRun run = runChild(argv, {logPath, logPath + ".rss"});
    if (run.status != 0)
        throw std::runtime_error(fmt::format("{} failed (exit {}); its output is in {}", argv.at(0),
                                             run.status, logPath));
    if (!run.peakExact)
        throw std::runtime_error(fmt::format("GNU time wrote no peak memory for {}", argv.at(0)));
    return {run.seconds, run.peakBytes};
}

}  // namespace cambium
