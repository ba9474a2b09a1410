// cambium — timing with the monotonic clock.
#pragma once

#include <chrono>

namespace cambium {

using Clock = std::chrono::steady_clock;

/// Seconds elapsed since `start`.
inline double secondsSince(Clock::time_point start)
{
    return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace cambium
