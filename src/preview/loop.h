// cambium — the live preview's loop: a source of file changes (inotify on
// the file's directory, or one a test drives), and the loop that turns each
// burst of changes into one update of the session, interrupting an update
// that a newer change has made stale.
#pragma once

#include "preview/preview.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <string>

namespace cambium {

/// Where the news that the watched file changed (or that the session's view
/// was changed: notify) comes from.
class ChangeSource {
public:
    virtual ~ChangeSource() = default;
    /// Blocks until the file changed or notify was called (true), or
    /// `timeout` passed (false).  Throws when the file can no longer be
    /// watched.
    virtual bool wait(std::chrono::milliseconds timeout) = 0;
    /// A change from elsewhere (the page moved the year or the camera): the
    /// next wait returns true.  Any thread.
    virtual void notify() = 0;
};

/// Changes of one file seen by inotify on its directory: a write closed, or
/// a file moved under its name (editors save by writing a temporary and
/// renaming it over the file); an overflowed event queue counts as a change.
/// InputError when the directory cannot be watched; wait throws
/// std::runtime_error once the directory is removed or moved away.
class InotifyChanges : public ChangeSource {
public:
    explicit InotifyChanges(const std::string& path);
    ~InotifyChanges() override;
    InotifyChanges(const InotifyChanges&) = delete;
    InotifyChanges& operator=(const InotifyChanges&) = delete;
    bool wait(std::chrono::milliseconds timeout) override;
    void notify() override;

private:
    int fd_ = -1;
    int wake_ = -1;     ///< an eventfd that notify writes
    std::string path_;  ///< the file, as given
    std::string name_;  ///< the file's name in its directory
};

/// Changes a test hands over (notify), each seen once.
class ManualChanges : public ChangeSource {
public:
    void notify() override;
    bool wait(std::chrono::milliseconds timeout) override;

private:
    std::mutex mutex_;
    std::condition_variable changed_;
    size_t pending_ = 0;
};

struct PreviewLoopOptions {
    /// A change starts an update once no other has come for this long: a
    /// burst of saves is one update, for the last.
    std::chrono::milliseconds quiet{40};
    /// Called with each update's outcome (also Unchanged and Interrupted),
    /// on the loop's thread.
    std::function<void(const PreviewUpdate&)> updated;
    /// Background work while no change is pending (the session's prebake):
    /// called again while it returns true; a change interrupts it.
    std::function<bool(const std::atomic<bool>* interrupt)> idle;
};

/// Updates the session once, then again after every burst of changes, until
/// `stop` is raised; a change during an update interrupts it (the update
/// after the burst replaces it).  Returns once `stop` is raised and the
/// update in flight, if any, has ended (which `stop` interrupts).  What the
/// change source throws ends the loop and is thrown again here.
void runPreviewLoop(PreviewSession& session, ChangeSource& changes, const std::atomic<bool>& stop,
                    const PreviewLoopOptions& options = {});

}  // namespace cambium
