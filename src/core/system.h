// cambium — what this machine has and how much of it a run takes: memory
// available and used, threads.
#pragma once

#include <memory>
#include <string>

#include <tbb/global_control.h>

#include <cmath>

namespace cambium {

/// What limits a process's memory: the machine's MemAvailable, the address
/// space left under `ulimit -v` (its limit less what is mapped already),
/// and its cgroup's room (memory.max less memory.current: a Slurm job's
/// allocation).  A limit that is not set is +infinity.
struct MemoryLimits {
    double available = 0.0;
    double addressSpaceLimit = HUGE_VAL, addressSpaceUsed = 0.0;
    double cgroupMax = HUGE_VAL, cgroupCurrent = 0.0;
    /// The least of them: the bytes this process may still take.
    double room() const;
};
MemoryLimits memoryLimits();
/// Bytes of memory available to this process: memoryLimits().room().
double availableMemoryBytes();
/// InputError "WHAT needs about BYTES of memory, and this machine has
/// AVAILABLE available[: REMEDY]" unless `bytes` (an estimate; NaN fails)
/// fits in availableMemoryBytes(): the one check before work that would not fit.
void checkMemoryFits(double bytes, const std::string& what, const std::string& remedy = "");
/// The same against `have` bytes, the room measured before the work began
/// (for a total counted as it grows: the room now excludes what it holds).
void checkMemoryFits(double bytes, double have, const std::string& what, const std::string& remedy);
/// Keeps 64 MB of address space in reserve and makes the first allocation
/// that fails release it as it throws std::bad_alloc: the unwinding that
/// follows then has room for what destructors allocate (OpenVDB's
/// Tree::clear lists a tree's nodes before it frees them; without room it
/// throws from a destructor and the process ends with "terminate called").
/// Called once, first thing in main.
void installMemoryReserve();
/// Where the address space left under `ulimit -v` beside the libraries
/// already mapped could not hold a thread's stack and the start's
/// allocations (40 MB): "out of memory" and exit 1.  Called before any
/// library's initializer (an ELF preinit function of the executable):
/// log4cplus, which OpenVDB loads, starts a thread in its own, and under
/// 124-155 MB every command, --version too, ended in "terminate called",
/// SIGABRT (sweep 27).  System calls only: nothing else is initialised yet.
void checkRoomToStart() noexcept;
/// Peak resident memory of this process so far.
double peakMemoryBytes();
/// Seconds since this process started (the kernel's start time, to its
/// clock tick, 10 ms): what a user waiting for a command sees.
double processAgeSeconds();
/// The directory of this process's executable (where the build puts
/// cambium-ptls and the image codec beside cambium).
std::string executableDirectory();
/// "1.5 GB": bytes in decimal units (kKmMgGtTpPeE: powers of 1000), three
/// significant digits.
std::string formatBytes(double bytes);
/// A size in bytes as options take it, in formatBytes' units: 2000000000,
/// 512M, 8G, 1.5 TB.  InputError naming `option` otherwise.
double parseByteSize(const std::string& text, const char* option);
/// "45 s", "12 min", "3.5 h", "4.2 days": a duration, two significant digits.
std::string formatDuration(double seconds);
/// "1,234,567": a count with thousands separated (rounded to a whole number).
std::string formatCount(double count);

/// Limits TBB and PoCL to `threads` (0: no limit) while it lives.
class ThreadLimit {
public:
    explicit ThreadLimit(int threads);
    ~ThreadLimit();

private:
    std::unique_ptr<tbb::global_control> control_;
};

/// Where fields are sampled and level sets ray-marched: OpenCL kernels (on
/// PoCL here, a GPU's driver elsewhere) or the CPU reference paths.
enum class Device { OpenCL, Cpu };
/// "opencl" or "cpu", the --device option's values.
const char* deviceName(Device device);
/// InputError unless `name` is "opencl" or "cpu".
Device parseDevice(const std::string& name, const char* option = "--device");

}  // namespace cambium
