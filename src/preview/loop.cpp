// cambium — the live preview's loop and its sources of file changes.
#include "preview/loop.h"

#include "core/error.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <poll.h>
#include <sys/inotify.h>
#include <thread>
#include <unistd.h>

namespace cambium {

namespace fs = std::filesystem;

InotifyChanges::InotifyChanges(const std::string& path)
{
    const fs::path file = fs::absolute(path);
    name_ = file.filename().string();
    fd_ = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (fd_ < 0)
        throw std::runtime_error(fmt::format("inotify: {}", std::strerror(errno)));
    const std::string dir = file.parent_path().string();
    if (::inotify_add_watch(fd_, dir.c_str(), IN_CLOSE_WRITE | IN_MOVED_TO | IN_CREATE) < 0) {
        const int e = errno;
        ::close(fd_);
        throw InputError(
            fmt::format("{}: cannot watch its directory {}: {}", path, dir, std::strerror(e)));
    }
}

InotifyChanges::~InotifyChanges()
{
    ::close(fd_);
}

bool InotifyChanges::wait(std::chrono::milliseconds timeout)
{
    pollfd p{fd_, POLLIN, 0};
    if (::poll(&p, 1, int(timeout.count())) <= 0)
        return false;
    // Every event queued; a change when one names the file.
    alignas(inotify_event) char buffer[16384];
    bool changed = false;
    for (;;) {
        const ssize_t n = ::read(fd_, buffer, sizeof buffer);
        if (n <= 0)
            break;
        for (ssize_t at = 0; at < n;) {
            const auto* e = reinterpret_cast<const inotify_event*>(buffer + at);
            if (e->len > 0 && name_ == e->name)
                changed = true;
            at += ssize_t(sizeof(inotify_event) + e->len);
        }
    }
    return changed;
}

void ManualChanges::notify()
{
    {
        std::lock_guard<std::mutex> lock(mutex_);
        ++pending_;
    }
    changed_.notify_all();
}

bool ManualChanges::wait(std::chrono::milliseconds timeout)
{
    std::unique_lock<std::mutex> lock(mutex_);
    if (!changed_.wait_for(lock, timeout, [&] { return pending_ > 0; }))
        return false;
    --pending_;
    return true;
}

void runPreviewLoop(PreviewSession& session, ChangeSource& changes, const std::atomic<bool>& stop,
                    const PreviewLoopOptions& options)
{
    using Clock = std::chrono::steady_clock;
    // The watcher: each change raises `interrupt` (an update in flight is
    // stale) and stamps the time; the loop starts an update once the stamp
    // is `quiet` old.
    std::mutex mutex;
    std::condition_variable woken;
    bool pending = true;  // (the first picture)
    Clock::time_point last = Clock::now() - options.quiet;
    std::atomic<bool> interrupt{false}, done{false};
    std::thread watcher([&] {
        while (!stop.load() && !done.load()) {
            if (!changes.wait(std::chrono::milliseconds(50)))
                continue;
            {
                std::lock_guard<std::mutex> lock(mutex);
                pending = true;
                last = Clock::now();
                interrupt.store(true);
            }
            woken.notify_all();
        }
        woken.notify_all();
    });
    // The watcher ended however the loop ends (a callback may throw).
    struct Join {
        std::thread& thread;
        std::atomic<bool>& done;
        ~Join()
        {
            done.store(true);
            thread.join();
        }
    } join{watcher, done};
    for (;;) {
        {
            std::unique_lock<std::mutex> lock(mutex);
            // A change, then quiet.
            for (;;) {
                if (stop.load())
                    break;
                if (pending && Clock::now() - last >= options.quiet)
                    break;
                woken.wait_for(lock, pending ? options.quiet : std::chrono::milliseconds(50));
            }
            if (stop.load())
                break;
            pending = false;
            interrupt.store(false);
        }
        const PreviewUpdate u = session.update(&interrupt);
        if (options.updated)
            options.updated(u);
    }
}

}  // namespace cambium
