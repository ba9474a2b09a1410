// cambium — a parallel loop over indices.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstddef>

namespace cambium {

/// f(i) for every i in [0, n), on all threads, in chunks of `grain`.
template <class F>
void forEachIndex(size_t n, const F& f, size_t grain = 4096)
{
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, grain),
                      [&](const tbb::blocked_range<size_t>& r) {
                          for (size_t i = r.begin(); i != r.end(); ++i)
                              f(i);
                      });
}

}  // namespace cambium
