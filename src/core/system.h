// cambium — what this machine has: memory available and used.
#pragma once

#include <string>

namespace cambium {

/// Bytes of memory available to this process (MemAvailable).
double availableMemoryBytes();
/// Peak resident memory of this process so far.
double peakMemoryBytes();
/// "1.5 GB": bytes in decimal units, three significant digits.
std::string formatBytes(double bytes);

}  // namespace cambium
