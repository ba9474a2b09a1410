// cambium — large scratch arrays whose pages all threads fault in.
#pragma once

#include <tbb/parallel_for.h>

#include <cstddef>
#include <memory>
#include <type_traits>

namespace cambium {

/// An array of n T, left uninitialised (T trivial), its pages touched by all
/// threads: a fresh page costs the kernel a fault and a clear, about 0.3 s per
/// GB on one thread, and would otherwise be paid by whichever single thread
/// writes first (a zero-initialising std::vector, a copy from OpenCL).
template <class T>
std::unique_ptr<T[]> parallelArray(size_t n)
{
    static_assert(std::is_trivial_v<T>, "parallelArray holds trivial types only");
    std::unique_ptr<T[]> a(new T[n]);
    constexpr size_t page = 4096;
    char* bytes = reinterpret_cast<char*>(a.get());
    const size_t size = n * sizeof(T);
    tbb::parallel_for(size_t(0), (size + page - 1) / page, [&](size_t p) { bytes[p * page] = 0; });
    return a;
}

}  // namespace cambium
