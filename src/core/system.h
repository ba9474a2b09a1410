// cambium — what this machine has and how much of it a run takes: memory
// available and used, threads.
#pragma once

#include <memory>
#include <string>

#include <tbb/global_control.h>

namespace cambium {

/// Bytes of memory available to this process (MemAvailable).
double availableMemoryBytes();
/// Peak resident memory of this process so far.
double peakMemoryBytes();
/// "1.5 GB": bytes in decimal units, three significant digits.
std::string formatBytes(double bytes);


/// Limits TBB and PoCL to `threads` (0: no limit) while it lives.
class ThreadLimit {
public:
    explicit ThreadLimit(int threads);
    ~ThreadLimit();
private:
    std::unique_ptr<tbb::global_control> control_;
};

}  // namespace cambium
