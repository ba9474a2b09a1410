// cambium tests — running the cambium binary and reading what it did.
#pragma once

#include <gtest/gtest.h>

#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <poll.h>
#include <string>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

namespace cambium::test {

struct Result {
    int status = -1;  ///< exit status; 128 + N when signal N ended it
    std::string out, err;
};

/// Runs `cambium ARGS` through the shell (ARGS may quote and redirect) with
/// standard output and error on pipes, and collects its exit status and both
/// texts.  `fileSizeLimit` >= 0 sets RLIMIT_FSIZE in the child, SIGXFSZ at
/// its default (the process killed) as a shell's `ulimit -f` leaves it:
/// cambium itself ignores it, so that every write of a file past that many
/// bytes fails with EFBIG (the pipes are not files, so the messages still
/// arrive).
/// `addressSpaceLimit` >= 0 sets RLIMIT_AS (what `ulimit -v` sets, in bytes).
inline Result run(const std::string& args, long long fileSizeLimit = -1,
                  long long addressSpaceLimit = -1)
{
    int out[2], err[2];
    if (::pipe(out) != 0 || ::pipe(err) != 0)
        return {};
    const std::string cmd = "exec " + std::string(CAMBIUM_EXE) + " " + args;
    const pid_t pid = ::fork();
    if (pid == 0) {
        ::dup2(out[1], 1);
        ::dup2(err[1], 2);
        ::close(out[0]);
        ::close(err[0]);
        ::close(out[1]);
        ::close(err[1]);
        if (fileSizeLimit >= 0) {
            ::signal(SIGXFSZ, SIG_DFL);
            const rlimit limit{rlim_t(fileSizeLimit), rlim_t(fileSizeLimit)};
            ::setrlimit(RLIMIT_FSIZE, &limit);
        }
        if (addressSpaceLimit >= 0) {
            const rlimit limit{rlim_t(addressSpaceLimit), rlim_t(addressSpaceLimit)};
            ::setrlimit(RLIMIT_AS, &limit);
        }
        ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
        ::_exit(127);
    }
    ::close(out[1]);
    ::close(err[1]);
    Result r;
    pollfd fds[2] = {{out[0], POLLIN, 0}, {err[0], POLLIN, 0}};
    std::string* texts[2] = {&r.out, &r.err};
    int open = 2;
    char buf[4096];
    while (open > 0 && ::poll(fds, 2, -1) >= 0)
        for (int k = 0; k < 2; ++k)
            if (fds[k].fd >= 0 && fds[k].revents) {
                const ssize_t n = ::read(fds[k].fd, buf, sizeof buf);
                if (n > 0) {
                    texts[k]->append(buf, size_t(n));
                } else {
                    ::close(fds[k].fd);
                    fds[k].fd = -1;
                    --open;
                }
            }
    int raw = 0;
    ::waitpid(pid, &raw, 0);
    r.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : WIFSIGNALED(raw) ? 128 + WTERMSIG(raw) : -1;
    return r;
}

inline std::string fileContents(const std::filesystem::path& p)
{
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace cambium::test
