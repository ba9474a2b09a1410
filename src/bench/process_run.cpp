// cambium — running and measuring a whole command.
#include "bench/process_run.h"

#include "bench/median.h"
#include "core/error.h"
#include "core/process.h"

#include <algorithm>
#include <fstream>
#include <iterator>
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

namespace {

/// The last lines of a command's output, for its failure's message (the
/// benchmark's scratch directory, the log's, is removed when it ends).
std::string outputTail(const std::string& logPath)
{
    std::ifstream in(logPath, std::ios::binary);
    const std::string all((std::istreambuf_iterator<char>(in)), {});
    std::string tail = all.substr(all.size() > 600 ? all.size() - 600 : 0);
    while (!tail.empty() && (tail.back() == '\n' || tail.back() == ' '))
        tail.pop_back();
    const size_t from = tail.find_last_of('\n', tail.size() > 300 ? tail.size() - 300 : 0);
    tail = tail.substr(from == std::string::npos ? 0 : from + 1);
    for (char& c : tail)
        if (c == '\n')
            c = ' ';
    return tail.empty() ? std::string("it printed nothing") : "it said: " + printable(tail);
}

}  // namespace

ProcessRun runProcess(const std::vector<std::string>& argv, const std::string& logPath)
{
    if (!measuresOwnPeak())
        throw std::runtime_error(
            "the whole-process benchmark needs GNU time (/usr/bin/time) for a command's own peak "
            "memory: bash tools/setup.sh packages installs it");
    const ChildRun run = runChild(argv, {logPath, logPath + ".rss"});
    if (run.status != 0)
        throw std::runtime_error(
            fmt::format("{} failed (exit {}); {}", argv.at(0), run.status, outputTail(logPath)));
    if (!run.peakExact)
        throw std::runtime_error(fmt::format("GNU time wrote no peak memory for {}", argv.at(0)));
    return {run.seconds, run.peakBytes};
}

}  // namespace cambium
