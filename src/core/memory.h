// cambium — large scratch arrays whose pages all threads fault in and release.
#pragma once

#include <tbb/parallel_for.h>

#include <sys/mman.h>

#include <cstddef>
#include <cstdint>
#include <algorithm>
#include <memory>
#include <new>
#include <type_traits>

namespace cambium {

/// parallelArray's alignment: OpenCL devices can use such memory as it is
/// (CL_MEM_USE_HOST_PTR; PoCL asks for 128 bytes).
constexpr size_t kParallelArrayAlignment = 128;

/// Deleter of parallelArray: the pages go back to the kernel from all threads
/// (freeing a few hundred MB costs the kernel tens of milliseconds on one
/// thread), then the block is freed.
template <class T>
struct ParallelRelease {
    size_t bytes = 0;
    void operator()(T* p) const
    {
        constexpr uintptr_t page = 4096, chunk = uintptr_t(4) << 20;
        const uintptr_t lo = (reinterpret_cast<uintptr_t>(p) + page - 1) & ~(page - 1);
        const uintptr_t hi = (reinterpret_cast<uintptr_t>(p) + bytes) & ~(page - 1);
        if (hi > lo + chunk)  // whole pages inside the block: the allocator keeps its headers
            tbb::parallel_for(lo, hi, chunk, [&](uintptr_t a) {
                madvise(reinterpret_cast<void*>(a), std::min(chunk, hi - a), MADV_DONTNEED);
            });
        ::operator delete[](p, std::align_val_t(kParallelArrayAlignment));
    }
};

template <class T>
using ParallelArray = std::unique_ptr<T[], ParallelRelease<T>>;

/// An array of n T, left uninitialised (T trivial), its pages touched by all
/// threads: a fresh page costs the kernel a fault and a clear, about 0.3 s per
/// GB on one thread, and would otherwise be paid by whichever single thread
/// writes first (a zero-initialising std::vector, a copy from OpenCL).
template <class T>
ParallelArray<T> parallelArray(size_t n)
{
    static_assert(std::is_trivial_v<T>, "parallelArray holds trivial types only");
    const size_t size = n * sizeof(T);
    ParallelArray<T> a(static_cast<T*>(::operator new[](std::max<size_t>(size, 1),
                                                        std::align_val_t(kParallelArrayAlignment))),
                       ParallelRelease<T>{size});
    constexpr size_t page = 4096;
    char* bytes = reinterpret_cast<char*>(a.get());
    tbb::parallel_for(size_t(0), (size + page - 1) / page, [&](size_t p) { bytes[p * page] = 0; });
    return a;
}

}  // namespace cambium
