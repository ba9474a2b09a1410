// cambium — memory available and used.
#include "core/system.h"

#include "core/error.h"
#include "core/memory.h"

#include <tbb/global_control.h>

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <regex>
#include <ctime>
#include <fstream>
#include <iterator>
#include <new>
#include <sstream>
#include <thread>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

namespace cambium {

double MemoryLimits::room() const
{
    return std::max(0.0, std::min({available, addressSpaceLimit - addressSpaceUsed,
                                   cgroupMax - cgroupCurrent}));
}

namespace {

/// The number a one-line file holds ("max" or unreadable: +infinity).
double numberInFile(const std::string& path)
{
    std::ifstream in(path);
    double v;
    return in >> v ? v : HUGE_VAL;
}

}  // namespace

MemoryLimits memoryLimits()
{
    MemoryLimits m;
    m.available = double(::sysconf(_SC_AVPHYS_PAGES)) * double(::sysconf(_SC_PAGESIZE));
    {
        std::ifstream in("/proc/meminfo");
        std::string key, unit;
        double kb;
        while (in >> key >> kb >> unit)
            if (key == "MemAvailable:") {
                m.available = kb * 1024.0;
                break;
            }
    }
    rlimit as{};
    if (::getrlimit(RLIMIT_AS, &as) == 0 && as.rlim_cur != RLIM_INFINITY) {
        m.addressSpaceLimit = double(as.rlim_cur);
        std::ifstream statm("/proc/self/statm");
        double pages = 0.0;
        if (statm >> pages)
            m.addressSpaceUsed = std::max(0.0, pages * double(::sysconf(_SC_PAGESIZE)) -
                                                   double(scratchAddressSpaceReserved()));
    }
    // cgroup v2: "0::/PATH" names this process's group under /sys/fs/cgroup.
    std::ifstream groups("/proc/self/cgroup");
    for (std::string line; std::getline(groups, line);)
        if (line.rfind("0::", 0) == 0) {
            const std::string dir = "/sys/fs/cgroup" + line.substr(3);
            m.cgroupMax = numberInFile(dir + "/memory.max");
            if (std::isfinite(m.cgroupMax)) {
                const double current = numberInFile(dir + "/memory.current");
                m.cgroupCurrent = std::isfinite(current) ? current : 0.0;
            }
        }
    return m;
}

double availableMemoryBytes()
{
    return memoryLimits().room();
}

namespace {

constexpr size_t kMemoryReserveBytes = size_t(64) << 20;
std::atomic<void*> memoryReserve{nullptr};

void releaseReserveAndFail()
{
    if (void* r = memoryReserve.exchange(nullptr))
        ::munmap(r, kMemoryReserveBytes);
    throw std::bad_alloc();
}

}  // namespace

void installMemoryReserve()
{
    // (address space only: its pages are never touched, so they cost no memory)
    void* r = ::mmap(nullptr, kMemoryReserveBytes, PROT_READ | PROT_WRITE,
                     MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (r == MAP_FAILED)
        return;
    memoryReserve.store(r);
    std::set_new_handler(releaseReserveAndFail);
}

namespace {

/// Appends `s` to the message at `at` (bounded by `end`).
char* appendText(char* at, char* end, const char* s)
{
    while (*s && at < end)
        *at++ = *s++;
    return at;
}
char* appendNumber(char* at, char* end, unsigned long long n)
{
    char digits[24];
    int k = 0;
    do {
        digits[k++] = char('0' + n % 10);
        n /= 10;
    } while (n);
    while (k && at < end)
        *at++ = digits[--k];
    return at;
}

}  // namespace

void checkRoomToStart() noexcept
{
    struct rlimit as;
    if (::getrlimit(RLIMIT_AS, &as) != 0 || as.rlim_cur == RLIM_INFINITY)
        return;
    // What is mapped now (the libraries): /proc/self/statm's first field.
    char text[64] = {};
    const int fd = ::open("/proc/self/statm", O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return;
    const ssize_t got = ::read(fd, text, sizeof text - 1);
    ::close(fd);
    unsigned long long pages = 0;
    for (ssize_t i = 0; i < got && text[i] >= '0' && text[i] <= '9'; ++i)
        pages = pages * 10 + static_cast<unsigned long long>(text[i] - '0');
    if (got <= 0 || pages == 0)
        return;
    const unsigned long long used =
        pages * static_cast<unsigned long long>(::sysconf(_SC_PAGESIZE));
    // A thread's stack (what RLIMIT_STACK gives it, at least glibc's 8 MB)
    // and room for the start's allocations: measured here with 118 MB of
    // libraries, --version aborted at 151 MB and ran at 156 MB, and below
    // 165 MB not even the bush L-system's derivation fits.
    unsigned long long stack = 8ull << 20;
    struct rlimit st;
    if (::getrlimit(RLIMIT_STACK, &st) == 0 && st.rlim_cur != RLIM_INFINITY && st.rlim_cur > stack)
        stack = st.rlim_cur;
    const unsigned long long need = stack + (40ull << 20);
    if (as.rlim_cur >= used + need)
        return;
    constexpr unsigned long long MB = 1ull << 20;
    char message[320];
    char *at = message, *end = message + sizeof message;
    at = appendText(at, end,
                    "cambium: failed: out of memory: the address space this process may use "
                    "(ulimit -v) is ");
    at = appendNumber(at, end, as.rlim_cur / MB);
    at = appendText(at, end, " MB, its libraries take ");
    at = appendNumber(at, end, used / MB);
    at = appendText(at, end, " MB of it, and starting needs about ");
    at = appendNumber(at, end, (used + need + MB - 1) / MB);
    at = appendText(at, end, " MB: raise the limit\n");
    const ssize_t written = ::write(2, message, size_t(at - message));
    (void)written;
    ::_exit(1);
}

double peakMemoryBytes()
{
    struct rusage r;
    ::getrusage(RUSAGE_SELF, &r);
    return double(r.ru_maxrss) * 1024.0;
}

double processAgeSeconds()
{
    // Field 22 of /proc/self/stat: the start time in clock ticks after boot
    // (after the command name, which may hold spaces, in parentheses).
    std::ifstream in("/proc/self/stat");
    std::string stat((std::istreambuf_iterator<char>(in)), {});
    const size_t close = stat.rfind(')');
    if (close == std::string::npos)
        return 0.0;
    std::istringstream fields(stat.substr(close + 2));
    std::string field;
    for (int i = 3; i < 22 && fields >> field; ++i) {
    }
    unsigned long long startTicks = 0;
    if (!(fields >> startTicks))
        return 0.0;
    timespec boot{};
    ::clock_gettime(CLOCK_BOOTTIME, &boot);
    const double now = double(boot.tv_sec) + 1e-9 * double(boot.tv_nsec);
    return now - double(startTicks) / double(::sysconf(_SC_CLK_TCK));
}

std::string executableDirectory()
{
    std::error_code ec;
    return std::filesystem::read_symlink("/proc/self/exe", ec).parent_path().string();
}

namespace {

/// The units of formatBytes and parseByteSize: each 1000 times the last.
constexpr const char* kByteUnits[] = {"B", "KB", "MB", "GB", "TB", "PB", "EB"};

}  // namespace

void checkMemoryFits(double bytes, const std::string& what, const std::string& remedy)
{
    checkMemoryFits(bytes, availableMemoryBytes(), what, remedy);
}

void checkMemoryFits(double bytes, double have, const std::string& what, const std::string& remedy)
{
    if (!(bytes <= have))
        throw InputError(fmt::format(
            "{} needs about {} of memory, and this machine has {} available{}", what,
            formatBytes(bytes), formatBytes(have), remedy.empty() ? "" : ": " + remedy));
}

std::string formatBytes(double b)
{
    if (!(b >= 0.0) || b > 1e30)
        return "an unbounded amount";
    int u = 0;
    while (b >= 1000.0 && u < 6) {
        b /= 1000.0;
        ++u;
    }
    return fmt::format("{:.3g} {}", b, kByteUnits[u]);
}

double parseByteSize(const std::string& text, const char* option)
{
    static const std::regex form(R"(\s*([0-9]+(?:\.[0-9]*)?)\s*([kKmMgGtTpPeE]?)[bB]?\s*)");
    std::smatch m;
    if (!std::regex_match(text, m, form))
        throw InputError(fmt::format("{} must be a size such as 8G, 512M or 2000000000 (got '{}')",
                                     option, text));
    int u = 0;  // the unit's power of 1000, from formatBytes' table
    if (m[2].length())
        while (kByteUnits[u][0] != std::toupper(static_cast<unsigned char>(m[2].str()[0])))
            ++u;
    const double bytes = std::stod(m[1].str()) * std::pow(1000.0, u);
    if (!(bytes >= 1.0))
        throw InputError(fmt::format("{} must be more than nothing (got '{}')", option, text));
    return bytes;
}

ThreadLimit::ThreadLimit(int threads)
{
    if (threads <= 0)
        return;
    control_ = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                     size_t(threads));
    // PoCL starts as many threads as it is told, each with its stack: never
    // more than the machine's (--threads 512 aborted in PoCL's scheduler
    // under an 8 GB address-space limit; more threads than cores gain nothing).
    const int cores = int(std::max(1u, std::thread::hardware_concurrency()));
    const std::string n = std::to_string(std::min(threads, cores));
    ::setenv("POCL_MAX_PTHREAD_COUNT", n.c_str(), 1);  // PoCL < 4
    ::setenv("POCL_CPU_MAX_CU_COUNT", n.c_str(), 1);   // PoCL >= 4
}

ThreadLimit::~ThreadLimit() = default;

std::string formatDuration(double seconds)
{
    if (seconds < 60.0)
        return fmt::format("{:.2g} s", seconds);
    if (seconds < 3600.0)
        return fmt::format("{:.2g} min", seconds / 60.0);
    if (seconds < 86400.0 * 2.0)
        return fmt::format("{:.2g} h", seconds / 3600.0);
    return fmt::format("{:.3g} days", seconds / 86400.0);
}

std::string formatCount(double count)
{
    std::string s = fmt::format("{:.0f}", count);
    for (int i = int(s.size()) - 3; i > (s[0] == '-' ? 1 : 0); i -= 3)
        s.insert(size_t(i), ",");
    return s;
}

namespace {

/// --device's words, in Device's order.
const std::vector<std::string> kDeviceNames{"opencl", "cpu"};

}  // namespace

const char* deviceName(Device device)
{
    return kDeviceNames[size_t(device)].c_str();
}

Device parseDevice(const std::string& name, const char* option)
{
    return Device(optionChoice(name, kDeviceNames, option));
}

}  // namespace cambium
