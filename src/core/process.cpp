// cambium — running a command and measuring it.
#include "core/process.h"

#include "core/clock.h"
#include "core/files.h"

#include <fmt/format.h>

#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include <fcntl.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace cambium {

namespace {

constexpr const char* kGnuTime = "/usr/bin/time";

/// The peak GNU time wrote (kB, the last line: a line before it says how
/// the command ended when that was not exit 0), in bytes; 0 when none.
double readGnuTimePeak(const std::string& path)
{
    std::ifstream in(path);
    std::string line, last;
    while (std::getline(in, line))
        if (!line.empty())
            last = line;
    double kb = 0.0;
    std::istringstream(last) >> kb;
    return kb * 1024.0;
}

constexpr const char* kParentFd = "CAMBIUM_PARENT_FD";

/// The pipe runChild's commands watch: its read end inherited, its write
/// end this process's alone (close-on-exec), open while the process lives.
int lifelineReadEnd()
{
    static const int fd = [] {
        int p[2];
        if (::pipe2(p, O_CLOEXEC) != 0)
            return -1;
        ::fcntl(p[0], F_SETFD, 0);  // (the read end goes to the children)
        return p[0];
    }();
    return fd;
}

}  // namespace

void endWithParent()
{
    const char* value = std::getenv(kParentFd);
    if (!value)
        return;
    const int fd = std::atoi(value);
    ::unsetenv(kParentFd);
    struct stat st;
    if (fd <= 2 || ::fstat(fd, &st) != 0 || !S_ISFIFO(st.st_mode))
        return;
    ::fcntl(fd, F_SETFD, FD_CLOEXEC);
    std::thread([fd] {
        char c;
        for (;;) {
            const ssize_t n = ::read(fd, &c, 1);
            if (n == 0)
                break;  // end of file: no writer is left
            if (n < 0 && errno != EINTR)
                return;
        }
        ::kill(::getpid(), SIGTERM);
    }).detach();
}

bool measuresOwnPeak()
{
    return ::access(kGnuTime, X_OK) == 0;
}

ChildRun runChild(const std::vector<std::string>& argv, const ChildOutput& output)
{
    // The command's own peak needs a small process between: a child of
    // this one starts from this process's peak.
    const bool timed = !output.peakFile.empty() && measuresOwnPeak();
    std::vector<std::string> full;
    if (timed)
        full = {kGnuTime, "-f", "%M", "-o", output.peakFile};
    full.insert(full.end(), argv.begin(), argv.end());
    std::vector<char*> args;
    for (const std::string& a : full)
        args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);

    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    if (output.log.empty()) {
        posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
    } else {
        posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, output.log.c_str(),
                                         O_WRONLY | O_CREAT | O_APPEND, 0644);
        posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
    }
    // Should GNU time end first (SIGTERM ends it, it ignores SIGINT), the
    // command becomes this process's child, for the signal handler to wait for.
    ::prctl(PR_SET_CHILD_SUBREAPER, 1);
    std::fflush(stdout);
    std::fflush(stderr);
    ChildRun run;
    const auto start = Clock::now();
    pid_t pid = 0;
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attr, 0);
    // Its environment names the lifeline's read end (endWithParent).
    std::vector<std::string> env;
    for (char** e = environ; *e; ++e)
        if (std::strncmp(*e, kParentFd, std::strlen(kParentFd)) != 0)
            env.emplace_back(*e);
    if (const int fd = lifelineReadEnd(); fd >= 0)
        env.push_back(fmt::format("{}={}", kParentFd, fd));
    std::vector<char*> envp;
    for (std::string& e : env)
        envp.push_back(e.data());
    envp.push_back(nullptr);
    const int err = ::posix_spawn(&pid, args[0], &actions, &attr, args.data(), envp.data());
    posix_spawnattr_destroy(&attr);
    posix_spawn_file_actions_destroy(&actions);
    if (err != 0)
        throw std::runtime_error(
            fmt::format("cannot start {}: {}", argv.at(0), std::strerror(err)));
    RemoveOnSignal group(pid);
    int status = 0;
    struct rusage usage {};
    while (::wait4(pid, &status, 0, &usage) < 0)
        if (errno != EINTR)
            throw std::runtime_error(
                fmt::format("waiting for {} failed: {}", argv.at(0), std::strerror(errno)));
    group.release();
    run.seconds = secondsSince(start);
    run.status = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    if (timed) {
        run.peakBytes = readGnuTimePeak(output.peakFile);
        run.peakExact = run.peakBytes > 0.0;
        std::remove(output.peakFile.c_str());
    }
    if (!run.peakExact)
        run.peakBytes = double(usage.ru_maxrss) * 1024.0;
    return run;
}

}  // namespace cambium
