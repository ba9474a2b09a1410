// cambium — the benchmarks' summary of repeated runs.
#pragma once

#include <algorithm>
#include <vector>

namespace cambium {

/// The median of the runs' times (the upper one of an even count); v must
/// not be empty.
inline double medianOf(std::vector<double> v)
{
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

}  // namespace cambium
