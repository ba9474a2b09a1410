// cambium — large scratch arrays whose pages all threads fault in, recycled
// from one use to the next.
#pragma once

#include <cstddef>
#include <memory>
#include <type_traits>

namespace cambium {

/// parallelArray's alignment: OpenCL devices can use such memory as it is
/// (CL_MEM_USE_HOST_PTR; PoCL asks for 128 bytes).
constexpr size_t kParallelArrayAlignment = 128;

/// A block of at least `bytes` bytes, aligned to kParallelArrayAlignment,
/// its pages resident. Blocks come from one region kept apart from other
/// allocations, first fit: a block given back is handed out again, its pages
/// still there (a streamed bake allocates and frees each layer's scratch: on
/// the 20k benchmark tree 820 MB of it, where the most held at once is
/// 110 MB). A fresh page costs the kernel a fault and a clear (about 0.3 s
/// per GB on one thread, several times that in some virtual machines),
/// which new pages have paid by all threads, not by whichever first writes.
void* acquireScratch(size_t bytes);

/// Gives a block back; its pages stay for the blocks to come, up to a
/// budget (32 MB of free pages, and no more than the most ever in use;
/// beyond it the highest go back to the kernel). Blocks under 1 MB come
/// from the allocator, which keeps their pages in its heap.
void releaseScratch(void* block, size_t bytes);

/// Gives the pages of every block given back to the kernel (at most the
/// budget's 32 MB), e.g. at the end of a bake, whose memory what follows can
/// use.
void trimScratch();

/// Address space the region has reserved above its blocks and kept pages:
/// no memory, and not to be counted against a limit on address space that
/// is set after it was made (memoryLimits).
size_t scratchAddressSpaceReserved();

/// What the scratch region holds now, for tests and timings.
struct ScratchUse {
    size_t inUse = 0;       ///< bytes of blocks handed out (whole pages)
    size_t keptFree = 0;    ///< bytes of free pages kept resident
    size_t fresh = 0;       ///< bytes of blocks whose pages were faulted in, in all
    size_t highWater = 0;   ///< the most bytes ever in use at once
    bool inRegion = false;  ///< whether blocks come from the region (not under ASan)
};
ScratchUse scratchUse();

template <class T>
struct ParallelRelease {
    size_t bytes = 0;
    void operator()(T* p) const { releaseScratch(p, bytes); }
};

template <class T>
using ParallelArray = std::unique_ptr<T[], ParallelRelease<T>>;

/// An array of n T, left uninitialised (T trivial), its pages resident
/// (acquireScratch).
template <class T>
ParallelArray<T> parallelArray(size_t n)
{
    static_assert(std::is_trivial_v<T>, "parallelArray holds trivial types only");
    const size_t size = n * sizeof(T);
    return ParallelArray<T>(static_cast<T*>(acquireScratch(size)), ParallelRelease<T>{size});
}

}  // namespace cambium
