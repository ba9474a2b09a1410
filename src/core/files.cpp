// cambium — output files that appear whole or not at all.
#include "core/files.h"

#include "core/error.h"
#include "core/frames.h"
#include "core/hash.h"
#include "core/math.h"
#include "core/system.h"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cctype>
#include <cerrno>
#include <climits>
#include <filesystem>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <system_error>
#include <dirent.h>
#include <fcntl.h>
#include <fstream>
#include <limits>
#include <map>
#include <mutex>
#include <ostream>
#include <unordered_set>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <sys/uio.h>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

namespace cambium {

namespace {

// ---- files to remove when a signal ends the process ------------------------
//
// A fixed table that a signal handler can walk without locks or allocation:
// a slot is Free, being Filled, Live (its path to be removed on a signal) or
// Taken by the handler (the process is ending).
constexpr int kSlots = 64;
enum SlotState : int { Free, Filling, Live, Taken };
struct CleanupSlot {
    std::atomic<int> state{Free};
    RemoveOnSignal::Kind kind = RemoveOnSignal::Kind::File;
    pid_t pid = 0;  // (Kind::Child)
    char path[PATH_MAX];
};
CleanupSlot gSlots[kSlots];

/// Unlinks every entry of directory `path` (not its subdirectories) and the
/// directory: raw getdents64, which a signal handler may call.
void removeFlatDirectory(const char* path)
{
    const int fd = ::open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return;
    alignas(8) static char buffer[16384];
    for (;;) {
        const long n = ::syscall(SYS_getdents64, fd, buffer, sizeof buffer);
        if (n <= 0)
            break;
        for (long at = 0; at < n;) {
            // struct linux_dirent64: ino (8), off (8), reclen (2), type (1), name
            unsigned short reclen;
            std::memcpy(&reclen, buffer + at + 16, sizeof reclen);
            const char* name = buffer + at + 19;
            if (!(name[0] == '.' && (name[1] == 0 || (name[1] == '.' && name[2] == 0))))
                ::unlinkat(fd, name, 0);
            at += reclen;
        }
    }
    ::close(fd);
    ::rmdir(path);
}

extern "C" void removeOnSignal(int sig)
{
    // Children first (they remove their own files as they end), then
    // files, then the directories they were in.
    for (auto kind :
         {RemoveOnSignal::Kind::Child, RemoveOnSignal::Kind::File, RemoveOnSignal::Kind::Directory})
        for (CleanupSlot& s : gSlots) {
            int live = Live;
            if (s.kind != kind || !s.state.compare_exchange_strong(live, Taken))
                continue;
            if (kind == RemoveOnSignal::Kind::Child) {
                // Its whole process group (a command and GNU time above it,
                // core/process.h), every member waited for: the command is
                // this process's child once GNU time is gone (subreaper).
                ::kill(-s.pid, sig);
                ::kill(-s.pid, SIGCONT);  // (a stopped child must run to end)
                int status;
                while (::waitpid(-s.pid, &status, 0) > 0 || errno == EINTR) {
                }
            } else if (kind == RemoveOnSignal::Kind::File) {
                ::unlink(s.path);
            } else {
                removeFlatDirectory(s.path);
            }
        }
    ::signal(sig, SIG_DFL);
    ::raise(sig);
}

// ---- a stream buffer whose every write is checked --------------------------

/// A seekable output buffer over a file descriptor.  The first failed write
/// or seek records errno and fails every later operation, so the stream goes
/// bad (and, with exceptions on badbit, throws at once).
class CheckedFileBuf : public std::streambuf {
public:
    explicit CheckedFileBuf(int fd) : fd_(fd), buffer_(size_t(1) << 18) { resetBuffer(); }
    int error() const { return error_; }
    bool flush() { return flushBuffer(); }

protected:
    int_type overflow(int_type c) override
    {
        if (!flushBuffer())
            return traits_type::eof();
        if (!traits_type::eq_int_type(c, traits_type::eof())) {
            *pptr() = traits_type::to_char_type(c);
            pbump(1);
        }
        return traits_type::not_eof(c);
    }

    std::streamsize xsputn(const char* s, std::streamsize n) override
    {
        if (n <= epptr() - pptr()) {
            std::memcpy(pptr(), s, size_t(n));
            pbump(int(n));
            return n;
        }
        if (!flushBuffer())
            return 0;
        if (n < epptr() - pptr()) {
            std::memcpy(pptr(), s, size_t(n));
            pbump(int(n));
            return n;
        }
        return writeAll(s, size_t(n)) ? n : 0;
    }

    int sync() override { return flushBuffer() ? 0 : -1; }

    pos_type seekoff(off_type off, std::ios_base::seekdir dir,
                     std::ios_base::openmode which) override
    {
        if (!(which & std::ios_base::out) || !flushBuffer())
            return pos_type(off_type(-1));
        const int whence = dir == std::ios_base::beg   ? SEEK_SET
                           : dir == std::ios_base::cur ? SEEK_CUR
                                                       : SEEK_END;
        const off_t at = ::lseek(fd_, off_t(off), whence);
        if (at < 0) {
            error_ = errno;
            return pos_type(off_type(-1));
        }
        return pos_type(off_type(at));
    }

    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }

private:
    void resetBuffer() { setp(buffer_.data(), buffer_.data() + buffer_.size()); }

    bool flushBuffer()
    {
        if (error_)
            return false;
        const size_t n = size_t(pptr() - pbase());
        if (n && !writeAll(pbase(), n))
            return false;
        resetBuffer();
        return true;
    }

    bool writeAll(const char* p, size_t n)
    {
        while (n > 0) {
            const ssize_t w = ::write(fd_, p, n);
            if (w < 0 && errno == EINTR)
                continue;
            if (w <= 0) {
                error_ = w < 0 ? errno : EIO;
                return false;
            }
            p += w;
            n -= size_t(w);
        }
        return true;
    }

    int fd_;
    std::vector<char> buffer_;
    int error_ = 0;
};

std::string directoryOf(const std::string& path)
{
    const size_t slash = path.rfind('/');
    return slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
}

std::string fileKind(mode_t mode)
{
    return S_ISCHR(mode)    ? "character device"
           : S_ISBLK(mode)  ? "block device"
           : S_ISFIFO(mode) ? "FIFO"
           : S_ISSOCK(mode) ? "socket"
                            : "special file";
}

[[noreturn]] void failWrite(const std::string& path, const std::string& why)
{
    throw WriteError(fmt::format("{}: cannot write the output: {}", path, why));
}

}  // namespace

RemoveOnSignal::RemoveOnSignal(const std::string& path, Kind kind) : RemoveOnSignal(path, kind, 0)
{
}

RemoveOnSignal::RemoveOnSignal(pid_t child) : RemoveOnSignal(std::string(), Kind::Child, child) {}

RemoveOnSignal::RemoveOnSignal(const std::string& path, Kind kind, pid_t pid)
{
    if (path.size() >= PATH_MAX)
        return;
    for (int i = 0; i < kSlots; ++i) {
        int free = Free;
        if (gSlots[i].state.compare_exchange_strong(free, Filling)) {
            std::memcpy(gSlots[i].path, path.c_str(), path.size() + 1);
            gSlots[i].kind = kind;
            gSlots[i].pid = pid;
            gSlots[i].state.store(Live);
            slot_ = i;
            return;
        }
    }
}

void RemoveOnSignal::release()
{
    if (slot_ < 0)
        return;
    int live = Live;
    while (!gSlots[slot_].state.compare_exchange_weak(live, Free)) {
        if (live == Taken)  // a signal handler is ending the process
            for (;;)
                std::this_thread::sleep_for(std::chrono::seconds(1));
        live = Live;
    }
    slot_ = -1;
}

namespace {

/// What a temporary's name adds to its file's: "PATH.tmp-PID".
constexpr const char* kTemporaryMark = ".tmp-";

}  // namespace

std::string temporaryPathFor(const std::string& path)
{
    return fmt::format("{}{}{}", path, kTemporaryMark, ::getpid());
}

std::string temporaryTarget(const std::string& temporary)
{
    return temporary.substr(0, temporary.rfind(kTemporaryMark));
}

std::string filesContentKey(const std::vector<std::string>& paths)
{
    std::string key;
    std::vector<char> piece(size_t(1) << 20);
    for (const std::string& path : paths) {
        if (path.empty())
            continue;
        std::ifstream in(path, std::ios::binary);
        Checksum64 sum;
        while (in) {
            in.read(piece.data(), std::streamsize(piece.size()));
            sum.update(piece.data(), size_t(in.gcount()));
        }
        key += fmt::format("{}={:016x};", path, in.eof() ? sum.value() : 0);
    }
    return fmt::format("{:016x}", fnv1a64(key));
}

namespace {

std::filesystem::path outputDirectory(const std::string& output)
{
    const std::filesystem::path dir = std::filesystem::path(output).parent_path();
    return dir.empty() ? std::filesystem::path(".") : dir;
}

}  // namespace

double freeDiskBytes(const std::string& output)
{
    struct statvfs fs {};
    if (::statvfs(outputDirectory(output).c_str(), &fs) != 0)
        return std::numeric_limits<double>::infinity();  // (checkOutputPath names the directory)
    return double(fs.f_bavail) * double(fs.f_frsize);
}

void checkDiskSpace(const std::string& output, double bytes, const std::string& what)
{
    const double free = freeDiskBytes(output);
    if (bytes > free)
        throw InputError(fmt::format(
            "{} would need about {} of disk, and {} has {} free: free some space, write "
            "elsewhere, or bake fewer frames or a larger --voxel-size",
            what, formatBytes(bytes), outputDirectory(output).string(), formatBytes(free)));
}

namespace {

/// An existing file by its device and inode: through links, other
/// spellings and hard links, one file is one id.  False for an empty name
/// or a file that does not exist.
using FileId = std::pair<dev_t, ino_t>;
bool fileId(const std::string& path, FileId& id)
{
    struct stat st {};
    if (path.empty() || ::stat(path.c_str(), &st) != 0)
        return false;
    id = {st.st_dev, st.st_ino};
    return true;
}

}  // namespace

bool sameFile(const std::string& a, const std::string& b)
{
    FileId x, y;
    return fileId(a, x) && fileId(b, y) && x == y;
}

namespace {

/// InputError where an output is an input, or two outputs one file.
void checkNoOutputIsAnInput(const std::vector<std::string>& outputs,
                            const std::vector<std::string>& inputs)
{
    std::map<FileId, const std::string*> read, written;
    FileId id;
    for (const std::string& input : inputs)
        if (fileId(input, id))
            read.emplace(id, &input);
    for (const std::string& output : outputs) {
        if (!fileId(output, id))
            continue;
        if (const auto in = read.find(id); in != read.end())
            throw InputError(fmt::format("{}: is the input {} (the output would replace it)",
                                         output, *in->second));
        if (const auto out = written.emplace(id, &output); !out.second)
            throw InputError(
                fmt::format("{}: is the same file as {} (two outputs would write one file)", output,
                            *out.first->second));
    }
}

}  // namespace

void checkOutputIsNoInput(const std::string& output, const std::vector<std::string>& inputs)
{
    checkNoOutputIsAnInput({output}, inputs);
}

void checkSequenceTargets(const std::vector<std::string>& outputs,
                          const std::vector<std::string>& inputs)
{
    checkNoOutputIsAnInput(outputs, inputs);
    for (const std::string& output : outputs)
        checkPartIsNoLink(output, "frame of a sequence");
}

namespace {

/// The outputs checkPartIsNoLink has seen, parts of many outputs, which the
/// writer never writes through a link: their paths' 64-bit hashes (a
/// million frames' paths would hold some 120 MB as strings; a collision
/// would only replace a link at a single output instead of writing
/// through it).
struct PartPaths {
    std::mutex mutex;
    std::unordered_set<uint64_t> hashes;
};
PartPaths& partPaths()
{
    static PartPaths parts;
    return parts;
}
uint64_t pathHash(const std::string& path)
{
    return mix64(fnv1a64(path));
}
bool isPartOutput(const std::string& path)
{
    PartPaths& p = partPaths();
    const std::lock_guard<std::mutex> lock(p.mutex);
    return p.hashes.count(pathHash(path)) > 0;
}

}  // namespace

void checkPartIsNoLink(const std::string& path, const char* part)
{
    {
        PartPaths& p = partPaths();
        const std::lock_guard<std::mutex> lock(p.mutex);
        p.hashes.insert(pathHash(path));
    }
    struct stat st;
    if (::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode))
        throw InputError(fmt::format(
            "{}: a symbolic link, where a {} is written: it would be written through the link "
            "and could replace another {} or the file the link names (remove the link)",
            path, part, part));
}

std::string checkOutputPath(const std::string& path, bool probe, bool follow)
{
    if (path.empty())
        throw InputError("-o: the output path is empty");
    if (path.back() == '/')
        throw InputError(fmt::format("{}: names a directory, not an output file", path));
    std::string target = path;
    struct stat st;
    if (follow && ::lstat(path.c_str(), &st) == 0 && S_ISLNK(st.st_mode)) {
        // Written through: the link stays, its target gets the new file.
        char* real = ::realpath(path.c_str(), nullptr);
        if (!real)
            throw InputError(fmt::format(
                "{}: a symbolic link whose target cannot be followed ({}): cambium writes "
                "through a link to an existing file only",
                path, std::strerror(errno)));
        target = real;
        std::free(real);
    }
    if ((follow ? ::stat(target.c_str(), &st) : ::lstat(target.c_str(), &st)) != 0) {
        if (errno != ENOENT)
            throw InputError(
                fmt::format("{}: cannot write the output: {}", path, std::strerror(errno)));
    } else if (!S_ISLNK(st.st_mode)) {  // (a link not followed: the file replaces it)
        if (S_ISDIR(st.st_mode))
            throw InputError(fmt::format("{}: is a directory, not an output file", path));
        if (!S_ISREG(st.st_mode))
            throw InputError(
                fmt::format("{}: is a {}, not a regular file: cambium writes only regular files",
                            path, fileKind(st.st_mode)));
    }
    if (!probe)
        return target;
    const std::string test = fmt::format("{}.probe-{}", target, ::getpid());
    const int fd = ::open(test.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0)
        throw InputError(
            fmt::format("{}: cannot write the output: {}", path, std::strerror(errno)));
    ::close(fd);
    ::unlink(test.c_str());
    return target;
}

uint64_t WrittenFile::size() const
{
    struct stat st;
    if (::fstat(fd_, &st) != 0)
        throw std::system_error(errno, std::generic_category(), "fstat");
    return uint64_t(st.st_size);
}

namespace {

/// Repeats `op(offset, done, left)` (a pread or pwrite of the bytes from
/// `done` on) until `n` bytes are done; std::system_error naming `what` on
/// failure (`shortError` when it does no more).
template <class Op>
void positionedAll(uint64_t offset, size_t n, int shortError, const char* what, const Op& op)
{
    for (size_t done = 0; done < n;) {
        const ssize_t r = op(off_t(offset + done), done, n - done);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            throw std::system_error(r < 0 ? errno : shortError, std::generic_category(), what);
        done += size_t(r);
    }
}

}  // namespace

void WrittenFile::read(uint64_t offset, void* data, size_t n) const
{
    char* p = static_cast<char*>(data);
    positionedAll(offset, n, EIO, "pread", [&](off_t at, size_t done, size_t left) {
        return ::pread(fd_, p + done, left, at);
    });
}

void WrittenFile::write(uint64_t offset, const void* data, size_t n)
{
    const char* p = static_cast<const char*>(data);
    positionedAll(offset, n, ENOSPC, "pwrite", [&](off_t at, size_t done, size_t left) {
        return ::pwrite(fd_, p + done, left, at);
    });
}

void WrittenFile::write(uint64_t offset, const std::vector<std::string_view>& pieces)
{
    std::vector<iovec> batch;
    for (size_t first = 0; first < pieces.size();) {
        const size_t last = std::min(pieces.size(), first + size_t(IOV_MAX));
        batch.clear();
        size_t bytes = 0;
        for (size_t k = first; k < last; ++k) {
            batch.push_back({const_cast<char*>(pieces[k].data()), pieces[k].size()});
            bytes += pieces[k].size();
        }
        // (a short write continues from where it stopped)
        size_t done = 0, at = 0;
        while (done < bytes) {
            const ssize_t r =
                ::pwritev(fd_, batch.data() + at, int(batch.size() - at), off_t(offset + done));
            if (r < 0 && errno == EINTR)
                continue;
            if (r <= 0)
                throw std::system_error(r < 0 ? errno : ENOSPC, std::generic_category(), "pwritev");
            done += size_t(r);
            for (size_t left = size_t(r); left > 0;) {
                const size_t take = std::min(left, batch[at].iov_len);
                batch[at].iov_base = static_cast<char*>(batch[at].iov_base) + take;
                batch[at].iov_len -= take;
                left -= take;
                if (batch[at].iov_len == 0)
                    ++at;
            }
            while (at < batch.size() && batch[at].iov_len == 0)
                ++at;
        }
        offset += bytes;
        first = last;
    }
}

void writeFile(const std::string& path, const std::function<void(std::ostream&)>& write)
{
    writeFile(path, write, {});
}

void writeFile(const std::string& path, const std::function<void(std::ostream&)>& write,
               const std::function<void(WrittenFile&)>& finish)
{
    // A part of many outputs (a frame, a tile) checked before the work is
    // no link (checkPartIsNoLink), and a link made since is replaced by the
    // part, not written through: a link made while a sequence ran replaced
    // the file it named, or another frame (sweep 27).
    const bool part = isPartOutput(path);
    const std::string target = checkOutputPath(path, true, !part);
    struct stat old;
    const bool replacing = ::lstat(target.c_str(), &old) == 0 && S_ISREG(old.st_mode);
    const std::string tmp = temporaryPathFor(target);
    // Registered before the file exists: a signal between its creation and
    // the registration would leave it behind.
    RemoveOnSignal guard(tmp);
    const int fd = ::open(tmp.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd < 0) {
        const int e = errno;
        guard.release();
        failWrite(path, std::strerror(e));
    }
    // (The signal test's seam: stopped here, with the temporary made, until
    // the test sends its signal and SIGCONT; a race before.)
    static const bool stopInWrite = std::getenv("CAMBIUM_TEST_STOP_IN_WRITE") != nullptr;
    if (stopInWrite)
        ::raise(SIGSTOP);
    int open = fd;
    auto abandon = [&] {
        if (open >= 0)
            ::close(open);
        ::unlink(tmp.c_str());
        guard.release();
    };
    CheckedFileBuf buf(fd);
    try {
        std::ostream out(&buf);
        out.exceptions(std::ios::badbit | std::ios::failbit);
        write(out);
        out.flush();
        if (!buf.flush())
            throw std::system_error(buf.error(), std::generic_category(), "write");
        if (finish) {
            WrittenFile file(fd);
            finish(file);
        }
    } catch (const InputError&) {
        abandon();
        throw;
    } catch (const std::exception& e) {
        abandon();
        // (a write at an offset, WrittenFile's, fails with the system's
        // word, as the stream's does: "File too large", not "pwritev: ...")
        const auto* sys = dynamic_cast<const std::system_error*>(&e);
        const int code = buf.error() ? buf.error()
                         : sys && sys->code().category() == std::generic_category()
                             ? sys->code().value()
                             : 0;
        failWrite(path, code ? std::strerror(code) : e.what());
    }
    if (replacing)
        ::fchmod(fd, old.st_mode & 07777);  // the new file keeps the old one's permissions
    if (::fsync(fd) != 0) {
        const int e = errno;
        abandon();
        failWrite(path, std::strerror(e));
    }
    open = -1;
    if (::close(fd) != 0) {
        const int e = errno;
        abandon();
        failWrite(path, std::strerror(e));
    }
    if (std::rename(tmp.c_str(), target.c_str()) != 0) {
        const int e = errno;
        abandon();
        failWrite(path, std::strerror(e));
    }
    guard.release();
    // The rename itself reaches the disk with its directory.
    const int dir = ::open(directoryOf(target).c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir >= 0) {
        const int r = ::fsync(dir), e = errno;
        ::close(dir);
        if (r != 0 && e != EINVAL && e != EROFS)
            failWrite(path, std::strerror(e));
    }
}

void writeFile(const std::string& path, const void* data, size_t size)
{
    writeFile(path, [&](std::ostream& out) {
        out.write(static_cast<const char*>(data), std::streamsize(size));
    });
}

void installCleanupOnSignals()
{
    for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
        struct sigaction old;
        if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_IGN)
            continue;  // e.g. nohup: keep ignoring it
        struct sigaction sa;
        std::memset(&sa, 0, sizeof sa);
        sa.sa_handler = removeOnSignal;
        sigemptyset(&sa.sa_mask);
        ::sigaction(sig, &sa, nullptr);
    }
    // A file size limit (`ulimit -f`, set by batch systems) makes a write
    // past it fail with EFBIG, which the checked writer reports (exit 1, the
    // temporary removed), instead of killing the process by SIGXFSZ with no
    // word and the temporary left behind (sweep 20).
    ::signal(SIGXFSZ, SIG_IGN);
}

namespace {

/// Whether process `pid` (decimal digits) runs and is a cambium other than
/// this one.
bool anotherCambiumRuns(const std::string& pid)
{
    if (pid.empty() || pid.size() >= 10 || std::stoll(pid) == ::getpid())
        return false;
    std::ifstream comm("/proc/" + pid + "/comm");
    std::string command;
    return comm >> command && command == "cambium";
}

}  // namespace

std::vector<std::string> staleDirectories(const std::string& prefix)
{
    const std::string dir = directoryOf(prefix);
    const std::string name =
        prefix.substr(prefix.rfind('/') == std::string::npos ? 0 : prefix.rfind('/') + 1);
    std::vector<std::string> found;
    DIR* d = ::opendir(dir.c_str());
    if (!d)
        return found;
    while (const dirent* e = ::readdir(d)) {
        const std::string f = e->d_name;
        if (f.size() <= name.size() || f.compare(0, name.size(), name) != 0 ||
            !std::all_of(f.begin() + long(name.size()), f.end(),
                         [](unsigned char c) { return std::isdigit(c); }))
            continue;
        struct stat st;
        const std::string path = dir + "/" + f;
        if (::lstat(path.c_str(), &st) != 0 || !S_ISDIR(st.st_mode) ||
            anotherCambiumRuns(f.substr(name.size())))
            continue;
        found.push_back(path);
    }
    ::closedir(d);
    std::sort(found.begin(), found.end());
    return found;
}

std::vector<std::string> staleTemporaries(const std::string& pattern)
{
    const std::string dir = directoryOf(pattern);
    const std::string name =
        pattern.substr(pattern.rfind('/') == std::string::npos ? 0 : pattern.rfind('/') + 1);
    // (A path without '#': its own temporaries, "NAME.tmp-<pid>".)
    const bool frames = name.find('#') != std::string::npos;
    const auto [first, last] =
        frames ? frameRun(name) : std::pair<size_t, size_t>{name.size(), name.size()};
    const size_t hashes = last - first;
    const std::string prefix = name.substr(0, first),
                      suffix = name.substr(first + hashes) + kTemporaryMark;
    std::vector<std::string> found;
    DIR* d = ::opendir(dir.c_str());
    if (!d)
        return found;
    auto digits = [](const std::string& s, size_t from, size_t to) {
        return to > from && std::all_of(s.begin() + long(from), s.begin() + long(to),
                                        [](unsigned char c) { return std::isdigit(c); });
    };
    while (const dirent* e = ::readdir(d)) {
        const std::string f = e->d_name;
        if (f.size() < prefix.size() + hashes + suffix.size() + 1 ||
            f.compare(0, prefix.size(), prefix) != 0)
            continue;
        const size_t tmp = f.rfind(suffix);
        if (tmp == std::string::npos || tmp < prefix.size() + hashes ||
            (frames ? !digits(f, prefix.size(), tmp) : tmp != prefix.size()) ||
            !digits(f, tmp + suffix.size(), f.size()))
            continue;
        // A process that is still running and is a cambium may still be writing it.
        if (anotherCambiumRuns(f.substr(tmp + suffix.size())))
            continue;
        found.push_back(dir + "/" + f);
    }
    ::closedir(d);
    std::sort(found.begin(), found.end());
    return found;
}

namespace {

/// A flock on `path` (created if missing), re-taken when the holder before
/// removed the file between our open and our lock (then the lock would be on
/// a file nobody else sees).  Blocks when `wait`; otherwise returns -1 with
/// what the file holds (its holder's pid) in *holder when another has it.
int lockFile(const std::string& path, bool wait, std::string* holder)
{
    for (;;) {
        const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
        if (fd < 0)
            throw InputError(
                fmt::format("{}: cannot create the lock file: {}", path, std::strerror(errno)));
        if (::flock(fd, wait ? LOCK_EX : LOCK_EX | LOCK_NB) != 0) {
            const int e = errno;
            char text[32] = {};
            const ssize_t n = ::pread(fd, text, sizeof text - 1, 0);
            ::close(fd);
            if (e != EWOULDBLOCK)
                throw InputError(fmt::format("{}: cannot lock: {}", path, std::strerror(e)));
            if (holder)
                *holder = n > 0 ? std::string(text, size_t(n)) : "";
            return -1;
        }
        struct stat mine, named;
        if (::fstat(fd, &mine) == 0 && ::stat(path.c_str(), &named) == 0 &&
            mine.st_ino == named.st_ino && mine.st_dev == named.st_dev)
            return fd;
        ::close(fd);
    }
}

/// The frames [first, last] a lock file of `name` (a pattern's file name)
/// covers: "NAME.lock" all of them, "NAME.frames-A-B.lock" A to B; false for
/// any other file.
bool lockedFrames(const std::string& file, const std::string& name, long long& first,
                  long long& last)
{
    if (file == name + ".lock") {
        first = LLONG_MIN;
        last = LLONG_MAX;
        return true;
    }
    const std::string head = name + ".frames-", tail = ".lock";
    if (file.size() <= head.size() + tail.size() || file.compare(0, head.size(), head) != 0 ||
        file.compare(file.size() - tail.size(), tail.size(), tail) != 0)
        return false;
    const std::string range = file.substr(head.size(), file.size() - head.size() - tail.size());
    const size_t dash = range.find('-');
    auto number = [](const std::string& t) { return allDigits(t, 18); };
    if (dash == std::string::npos || !number(range.substr(0, dash)) ||
        !number(range.substr(dash + 1)))
        return false;
    first = std::stoll(range.substr(0, dash));
    last = std::stoll(range.substr(dash + 1));
    return true;
}

}  // namespace

OutputLock::OutputLock(const std::string& pattern) : OutputLock(pattern, LLONG_MIN, LLONG_MAX) {}

OutputLock::OutputLock(const std::string& pattern, long long first, long long last)
    : path_(first == LLONG_MIN && last == LLONG_MAX
                ? pattern + ".lock"
                : fmt::format("{}.frames-{}-{}.lock", pattern, first, last))
{
    // Looking for the runs that hold frames of ours and taking our lock are
    // one step, under a brief lock of the whole pattern: two runs starting
    // at once cannot both miss each other.
    const std::string scan = pattern + ".locking";
    const int scanFd = lockFile(scan, true, nullptr);
    struct ScanLock {
        const std::string& path;
        int fd;
        ~ScanLock()
        {
            ::unlink(path.c_str());  // while still holding it
            ::close(fd);
        }
    } scanLock{scan, scanFd};
    const size_t slash = pattern.rfind('/');
    const std::string dir = slash == std::string::npos ? "." : pattern.substr(0, slash + 1),
                      name = slash == std::string::npos ? pattern : pattern.substr(slash + 1);
    std::vector<std::string> files;
    if (DIR* d = ::opendir(dir.c_str())) {
        while (const dirent* e = ::readdir(d))
            files.emplace_back(e->d_name);
        ::closedir(d);
    }
    std::sort(files.begin(), files.end());
    for (const std::string& f : files) {
        long long a, b;
        if (!lockedFrames(f, name, a, b) || b < first || a > last)
            continue;
        const std::string other = slash == std::string::npos ? f : dir + f;
        std::string holder;
        const int fd = lockFile(other, false, &holder);
        if (fd >= 0) {  // a killed run's: nobody holds it
            ::unlink(other.c_str());
            ::close(fd);
            continue;
        }
        const bool pid =
            !holder.empty() && holder.find_first_not_of("0123456789\n") == std::string::npos;
        throw InputError(fmt::format(
            "{}: another cambium{} is writing {} of this sequence (lock {}): wait for it to "
            "end, or stop it",
            pattern, pid ? fmt::format(" (pid {})", holder.substr(0, holder.find('\n'))) : "",
            a == LLONG_MIN ? std::string("every frame") : fmt::format("frames {} to {}", a, b),
            other));
    }
    fd_ = lockFile(path_, false, nullptr);
    if (fd_ < 0)  // (we hold the pattern's scan lock: nobody else can)
        throw InputError(fmt::format("{}: cannot lock", path_));
    const std::string pid = fmt::format("{}\n", ::getpid());
    if (::ftruncate(fd_, 0) != 0 ||
        ::pwrite(fd_, pid.data(), pid.size(), 0) != ssize_t(pid.size())) {
        // The lock holds without the pid; only the message naming it suffers.
    }
    guard_ = std::make_unique<RemoveOnSignal>(path_);
}

OutputLock::~OutputLock()
{
    guard_.reset();
    ::unlink(path_.c_str());  // while still holding the lock
    ::close(fd_);
}

std::string fileExtension(const std::string& path)
{
    const size_t dot = path.rfind('.'), slash = path.rfind('/');
    std::string ext = dot == std::string::npos || (slash != std::string::npos && dot < slash)
                          ? ""
                          : path.substr(dot + 1);
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char ch) { return char(std::tolower(ch)); });
    return ext;
}

std::string fileFormat(const std::string& path, const std::vector<std::string>& allowed,
                       const char* kind)
{
    const std::string ext = fileExtension(path);
    if (std::find(allowed.begin(), allowed.end(), ext) != allowed.end())
        return ext;
    std::string list;
    for (size_t i = 0; i < allowed.size(); ++i)
        list += (i == 0 ? "." : (i + 1 == allowed.size() ? " or ." : ", .")) + allowed[i];
    if (path.empty())
        throw InputError(fmt::format("the {} file's path is empty (use {})", kind, list));
    if (ext.empty())
        throw InputError(fmt::format("{}: the name has no extension to tell the {} format (use {})",
                                     path, kind, list));
    throw InputError(fmt::format("{}: unknown {} format '.{}' (use {})", path, kind, ext, list));
}

ScratchDirectory::ScratchDirectory(std::string path)
    : path_(std::move(path)), guard_(path_, RemoveOnSignal::Kind::Directory)
{
    std::filesystem::create_directories(path_);
}

std::string ScratchDirectory::temporaryPath(const std::string& name)
{
    return (std::filesystem::temp_directory_path() / fmt::format("cambium_{}_{}", name, ::getpid()))
        .string();
}

ScratchDirectory::~ScratchDirectory()
{
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
}

}  // namespace cambium
