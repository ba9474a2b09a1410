// cambium — the live preview's loop and its sources of file changes.
#include "preview/loop.h"

#include "core/error.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/inotify.h>
#include <thread>
#include <unistd.h>

namespace cambium {

namespace fs = std::filesystem;

InotifyChanges::InotifyChanges(const std::string& path) : path_(path)
{
    const fs::path file = fs::absolute(path);
    name_ = file.filename().string();
    fd_ = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (fd_ < 0)
        throw std::runtime_error(fmt::format("inotify: {}", std::strerror(errno)));
    const std::string dir = file.parent_path().string();
    // The file written, renamed over, deleted or renamed away (the page
    // then says it is gone, and the next write brings it back).
    if (::inotify_add_watch(fd_, dir.c_str(),
                            IN_CLOSE_WRITE | IN_MOVED_TO | IN_DELETE | IN_MOVED_FROM |
                                IN_DELETE_SELF | IN_MOVE_SELF) < 0) {
        const int e = errno;
        ::close(fd_);
        const std::string message =
            fmt::format("{}: cannot watch its directory {}: {}", path, dir, std::strerror(e));
        // (No such directory, or not one's to read: the input; the system's
        // limits on watches: a failure.)
        if (e == ENOENT || e == EACCES || e == ENOTDIR)
            throw InputError(message);
        throw std::runtime_error(message);
    }
    wake_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (wake_ < 0) {
        const int e = errno;
        ::close(fd_);
        throw std::runtime_error(fmt::format("eventfd: {}", std::strerror(e)));
    }
}

InotifyChanges::~InotifyChanges()
{
    ::close(fd_);
    ::close(wake_);
}

void InotifyChanges::notify()
{
    const uint64_t one = 1;
    // (A full counter already says "changed".)
    [[maybe_unused]] const ssize_t n = ::write(wake_, &one, sizeof one);
}

bool InotifyChanges::wait(std::chrono::milliseconds timeout)
{
    pollfd p[2] = {{fd_, POLLIN, 0}, {wake_, POLLIN, 0}};
    if (::poll(p, 2, int(timeout.count())) <= 0)
        return false;
    bool changed = false;
    if (p[1].revents & POLLIN) {
        uint64_t count = 0;
        changed = ::read(wake_, &count, sizeof count) == ssize_t(sizeof count);
    }
    // Every event queued; a change when one names the file.
    alignas(inotify_event) char buffer[16384];
    for (;;) {
        const ssize_t n = ::read(fd_, buffer, sizeof buffer);
        if (n <= 0)
            break;
        for (ssize_t at = 0; at < n;) {
            const auto* e = reinterpret_cast<const inotify_event*>(buffer + at);
            if (e->mask & (IN_DELETE_SELF | IN_MOVE_SELF | IN_IGNORED))
                throw std::runtime_error(fmt::format(
                    "{}: its directory was removed or moved: the file can no longer be watched",
                    path_));
            if ((e->mask & IN_Q_OVERFLOW) || (e->len > 0 && name_ == e->name))
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
    // is `quiet` old.  `stop` interrupts too.
    std::mutex mutex;
    std::condition_variable woken;
    bool pending = true;  // (the first picture)
    Clock::time_point last = Clock::now() - options.quiet;
    std::atomic<bool> interrupt{false}, done{false};
    std::exception_ptr failure;  // what the change source threw
    std::thread watcher([&] {
        try {
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
        } catch (...) {
            std::lock_guard<std::mutex> lock(mutex);
            failure = std::current_exception();
            interrupt.store(true);
        }
        if (stop.load())
            interrupt.store(true);
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
    bool idleWork = bool(options.idle);
    for (;;) {
        {
            std::unique_lock<std::mutex> lock(mutex);
            // A change, then quiet; background work while there is none.
            for (;;) {
                if (stop.load() || failure)
                    break;
                if (pending && Clock::now() - last >= options.quiet)
                    break;
                if (pending) {
                    woken.wait_until(lock, last + options.quiet);
                } else if (idleWork) {
                    interrupt.store(stop.load());  // (a stop raised meanwhile kept)
                    lock.unlock();
                    idleWork = options.idle(&interrupt);
                    lock.lock();
                } else {
                    woken.wait_for(lock, std::chrono::milliseconds(50));
                }
            }
            if (failure)
                std::rethrow_exception(failure);
            if (stop.load())
                break;
            pending = false;
            interrupt.store(stop.load());
            // (After a change there may be background work again.)
            idleWork = bool(options.idle);
        }
        const PreviewUpdate u = session.update(&interrupt);
        if (options.updated)
            options.updated(u);
    }
}

}  // namespace cambium
