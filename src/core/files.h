// cambium — output files that appear whole or not at all, through one checked
// writer; the lock that keeps two runs out of one sequence.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <iosfwd>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include <sys/types.h>

namespace cambium {

/// A failure while writing an output (a full disk, an I/O error): the work
/// failed, the request was fine (the CLI exits 1; a farm may retry).
class WriteError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

/// Checks an output path before any work and returns where the file will
/// really be written: `path` itself, or the target of the symbolic link it
/// names (a symlink is written through, the link kept).  InputError naming
/// the path when it is empty, names a directory, a device, a FIFO, a socket
/// or a dangling link, or when its directory does not exist or cannot be
/// written (tried, when `probe`, by creating and removing a file beside it).
/// Where not `follow`, a link is not followed: the file replaces the link.
std::string checkOutputPath(const std::string& path, bool probe = true, bool follow = true);

/// InputError where `path`, one `part` of many outputs (a frame of a
/// sequence, a tile of a farm), is a symbolic link: a single output is
/// written through its link, but one part written through a link can
/// replace another part, or the file two parts' links share (a farm's
/// retries then took turns destroying each other's frame or tile).  The
/// path is remembered as a part: writeFile replaces a link made there since
/// with the part instead of writing through it.
void checkPartIsNoLink(const std::string& path, const char* part);

/// Bytes free to this user on the file system `output` is to be written on
/// (its directory's); infinity when that cannot be told.
double freeDiskBytes(const std::string& output);

/// InputError, before any work, when `bytes` (an estimate of what `what`
/// writes) would not fit in the free space of the file system `output` is
/// to be written on (the estimate and the free space named).
void checkDiskSpace(const std::string& output, double bytes, const std::string& what);

/// Whether `a` and `b` name one existing file (one inode: through links,
/// other spellings and hard links too).
bool sameFile(const std::string& a, const std::string& b);

/// InputError "OUTPUT: is the input INPUT (the output would replace it)"
/// when `output` names, through links or other names, the same file as one
/// of `inputs` (empty names skipped); a command checks it before any work.
void checkOutputIsNoInput(const std::string& output, const std::vector<std::string>& inputs);

/// The same for every output of a sequence, and InputError "OUTPUT: is the
/// same file as OTHER (two outputs would write one file)" where two outputs
/// name one existing file (a frame linked to another frame); then each
/// output is a part, no link (checkPartIsNoLink: a frame's retry by a farm
/// wrote through a link over another frame with exit 0, sweep 25).
void checkSequenceTargets(const std::vector<std::string>& outputs,
                          const std::vector<std::string>& inputs);

/// A key of the bytes of the files `paths` (each name with a 64-bit
/// checksum of its contents; an empty name or a file that cannot be read
/// counts as none): what a sequence's frames depend on besides its main
/// input, so that --resume does not keep frames made from other files.
std::string filesContentKey(const std::vector<std::string>& paths);

/// The temporary file the writer fills beside the real target `path`
/// ("PATH.tmp-PID") before renaming it.
std::string temporaryPathFor(const std::string& path);
/// The target a temporary's name stands for: "a.vdb" of "a.vdb.tmp-123".
std::string temporaryTarget(const std::string& temporary);

/// The one writer of every output file.  `write` fills a seekable stream
/// whose every write is checked; the data go to a temporary file beside the
/// target (checkOutputPath), which is flushed, fsync'ed, closed and renamed
/// over the target, and the directory fsync'ed.  On any failure (a full disk,
/// an exception from `write`) the temporary is removed, an existing file is
/// left as it was, and WriteError "PATH: cannot write the output: REASON"
/// (InputError when `write` threw one) is thrown.  While the temporary exists
/// a SIGINT, SIGTERM or SIGHUP removes it before the process ends
/// (installCleanupOnSignals).
void writeFile(const std::string& path, const std::function<void(std::ostream&)>& write);
/// writeFile for bytes already in memory.
void writeFile(const std::string& path, const void* data, size_t size);

/// The temporary file writeFile has filled, open for reads and writes at
/// any offset before it is synced and renamed (a checksum patched in).
/// Failures throw std::system_error (writeFile reports them as WriteError).
class WrittenFile {
public:
    explicit WrittenFile(int fd) : fd_(fd) {}
    uint64_t size() const;
    void read(uint64_t offset, void* data, size_t n) const;
    void write(uint64_t offset, const void* data, size_t n);
    /// Pieces of bytes one after another from `offset`, a thousand a
    /// system call (pieces of a kilobyte through a stream cost a copy each).
    void write(uint64_t offset, const std::vector<std::string_view>& pieces);

private:
    int fd_;
};

/// writeFile whose `finish` runs on the whole temporary after `write`.
void writeFile(const std::string& path, const std::function<void(std::ostream&)>& write,
               const std::function<void(WrittenFile&)>& finish);

/// Installs handlers that, on SIGINT, SIGTERM or SIGHUP, remove the
/// temporaries and lock files this process has open, then end it by the same
/// signal.  Call once at the start of main.
void installCleanupOnSignals();

/// Temporaries that an earlier, killed process left for the frames of
/// `pattern` (a path with a run of '#'): files "PREFIX<digits>SUFFIX.tmp-<pid>"
/// in its directory, with as many digits as the pattern has '#' or more, and
/// nothing else; for a path without '#', its own "PATH.tmp-<pid>".  Not the
/// temporaries of a cambium process that is running.
std::vector<std::string> staleTemporaries(const std::string& pattern);

/// Directories "PREFIX<pid>" (`prefix` a path; the pid decimal) that a
/// cambium since killed left, by SIGKILL say (a tiled bake's scratch
/// directory of tiles): not those of a cambium process that is running.
std::vector<std::string> staleDirectories(const std::string& prefix);

/// Registers a path to be removed if a signal ends the process while the
/// guard lives (installCleanupOnSignals); release() when it is no longer ours.
class RemoveOnSignal {
public:
    /// What the handler does: removes a file; removes a directory and the
    /// files in it; sends a child's process group the signal (and SIGCONT)
    /// and waits for every child in it to end, before any file is removed.
    enum class Kind { File, Directory, Child };
    explicit RemoveOnSignal(const std::string& path, Kind kind = Kind::File);
    /// (`child`: a child that leads its own process group, runChild's.)
    explicit RemoveOnSignal(pid_t child);
    ~RemoveOnSignal() { release(); }
    RemoveOnSignal(const RemoveOnSignal&) = delete;
    RemoveOnSignal& operator=(const RemoveOnSignal&) = delete;
    void release();

private:
    RemoveOnSignal(const std::string& path, Kind kind, pid_t pid);
    int slot_ = -1;
};

/// An exclusive lock on the outputs of `pattern`, every frame of it
/// ("PATTERN.lock" beside them) or frames [first, last] ("PATTERN.frames-
/// FIRST-LAST.lock"; flock, holding the pid): held while it lives, released
/// and the lock file removed at its end.  InputError naming the holder's pid
/// and frames while another process holds frames of ours; runs of disjoint
/// ranges (the tasks of a farm) write side by side.  A lock file a killed
/// run left is removed.
class OutputLock {
public:
    explicit OutputLock(const std::string& pattern);
    OutputLock(const std::string& pattern, long long first, long long last);
    ~OutputLock();
    OutputLock(const OutputLock&) = delete;
    OutputLock& operator=(const OutputLock&) = delete;
    const std::string& path() const { return path_; }

private:
    std::string path_;
    int fd_ = -1;
    std::unique_ptr<RemoveOnSignal> guard_;
};

/// The lower-case extension of `path`'s file name, without the dot ("" for
/// none): "json" of "trees/Poplar.JSON".
std::string fileExtension(const std::string& path);
/// The lower-case extension of `path` (without the dot) when it is one of
/// `allowed`; else InputError "PATH: unknown KIND format '.EXT' (use .A or .B)".
std::string fileFormat(const std::string& path, const std::vector<std::string>& allowed,
                       const char* kind);

/// A working directory, created (with its parents) now and removed with
/// everything in it when this goes out of scope, however the scope ends,
/// and when a signal ends the process (installCleanupOnSignals: the files
/// directly in it).
class ScratchDirectory {
public:
    explicit ScratchDirectory(std::string path);
    /// TMPDIR/cambium_NAME_PID: a benchmark's or a test run's own.
    static std::string temporaryPath(const std::string& name);
    ~ScratchDirectory();
    ScratchDirectory(const ScratchDirectory&) = delete;
    ScratchDirectory& operator=(const ScratchDirectory&) = delete;
    const std::string& path() const { return path_; }

private:
    std::string path_;
    RemoveOnSignal guard_;  // (its files, on a signal too)
};

}  // namespace cambium
