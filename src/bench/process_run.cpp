// cambium — running and measuring a whole command.
#include "bench/process_run.h"

#include "bench/median.h"
#include "core/clock.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

#include <fmt/format.h>

#include <fcntl.h>
#include <fstream>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

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
    // The command runs under GNU time, which reports its peak memory: a
    // child spawned from this process would inherit this process's peak
    // (Linux keeps the larger of the exec'ed address space's high-water mark
    // and the new one), time's own is a few MB.
    const char* timeExe = "/usr/bin/time";
    if (::access(timeExe, X_OK) != 0)
        throw std::runtime_error(
            "the whole-process benchmark needs GNU time (/usr/bin/time): bash tools/setup.sh "
            "packages installs it");
    const std::string rss = logPath + ".rss";
    std::vector<std::string> full = {timeExe, "-f", "%M", "-o", rss};
    full.insert(full.end(), argv.begin(), argv.end());
    std::vector<char*> args;
    for (const std::string& a : full)
        args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, logPath.c_str(), O_WRONLY | O_CREAT | O_APPEND,
                                     0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    const auto t0 = Clock::now();
    pid_t pid = 0;
    const int err = ::posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (err != 0)
        throw std::runtime_error(fmt::format("cannot start {}: {}", argv[0], std::strerror(err)));
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0)
        if (errno != EINTR)
            throw std::runtime_error(
                fmt::format("waiting for {}: {}", argv[0], std::strerror(errno)));
    ProcessRun run;
    run.seconds = secondsSince(t0);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
        throw std::runtime_error(
            fmt::format("{} failed (status {}); its output is in {}", argv[0], status, logPath));
    std::ifstream in(rss);
    double kb = 0.0;
    if (!(in >> kb))
        throw std::runtime_error("GNU time wrote no peak memory to " + rss);
    run.peakBytes = kb * 1024.0;
    return run;
}

}  // namespace cambium
