// cambium — parallelArray's blocks, recycled within one region (memory.h).
#include "core/memory.h"

#include <tbb/parallel_for.h>

#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <map>
#include <mutex>
#include <new>

namespace cambium {
namespace {

constexpr size_t kPage = 4096;

/// f over [lo, lo + bytes) from all threads, `chunk` bytes at a time.
template <class F>
void onPages(char* lo, size_t bytes, size_t chunk, const F& f)
{
    tbb::parallel_for(size_t(0), (bytes + chunk - 1) / chunk, [&](size_t c) {
        char* a = lo + c * chunk;
        f(a, std::min(chunk, size_t(lo + bytes - a)));
    });
}

void dropPages(char* lo, size_t bytes)
{
    onPages(lo, bytes, size_t(4) << 20, [](char* a, size_t n) { madvise(a, n, MADV_DONTNEED); });
}

void touchPages(char* lo, size_t bytes)
{
    // (64 kB at a time: a block of a few hundred kB is faulted in by all
    // threads too; 4 MB at a time kept the 1k benchmark tree's on one.)
    onPages(lo, bytes, size_t(64) << 10, [](char* a, size_t n) {
        for (size_t i = 0; i < n; i += kPage)
            a[i] = 0;
    });
}

/// Blocks outside the region (it is full, or could not be mapped; under
/// AddressSanitizer, which must see every block's bounds): the allocator's,
/// their pages dropped when they are given back.
void* allocateOutside(size_t bytes)
{
    char* p = static_cast<char*>(
        ::operator new[](std::max<size_t>(bytes, 1), std::align_val_t(kParallelArrayAlignment)));
    touchPages(p, bytes);
    return p;
}

void freeOutside(void* block, size_t bytes)
{
    const uintptr_t lo = (reinterpret_cast<uintptr_t>(block) + kPage - 1) & ~(kPage - 1);
    const uintptr_t hi = (reinterpret_cast<uintptr_t>(block) + bytes) & ~(kPage - 1);
    if (hi >
        lo + (size_t(4) << 20))  // whole pages inside the block: the allocator keeps its headers
        dropPages(reinterpret_cast<char*>(lo), hi - lo);
    ::operator delete[](block, std::align_val_t(kParallelArrayAlignment));
}

#if defined(__SANITIZE_ADDRESS__)
#define CB_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define CB_ASAN 1
#endif
#endif
#ifdef CB_ASAN
constexpr bool kUseRegion = false;
#else
constexpr bool kUseRegion = true;
#endif

/// Smaller blocks come from the allocator, which keeps their pages in its
/// heap for the next (it gives back only the pages of large ones).
constexpr size_t kRegionMin = size_t(1) << 20;

/// How many bytes of free pages the region keeps for the blocks to come. A
/// streamed bake's scratch rises and falls by some 60 MB from slab to slab
/// (the 20k benchmark tree), and pages kept beyond what is in use add to
/// the process's peak: on that tree, 32 MB kept took its faults from 250 k
/// to 144 k with the peak 10 MB lower than before (the values freed sooner
/// had lowered it by 27 MB); 64 MB, 125 k and the peak 30 MB higher.
constexpr size_t kKeptFree = size_t(32) << 20;

/// A run of free pages: resident (its pages kept) or dropped.
struct FreeRun {
    size_t length;
    bool resident;
};

/// Address space as large as the machine's memory, reserved once: blocks
/// below `top`, first fit, in pages still resident where there are some.
struct Region {
    std::mutex mutex;
    char* base = nullptr;
    size_t size = 0;
    size_t top = 0;
    std::map<size_t, FreeRun> free;  ///< offset -> run; neighbours differ in residence
    size_t residentFree = 0;
    size_t highWater = 0;  ///< the most bytes in use at once
    ScratchUse use;

    Region()
    {
        // A limit on address space (ulimit -v) would count the whole
        // reservation: then blocks come from the allocator.
        rlimit as{};
        if (!kUseRegion || getrlimit(RLIMIT_AS, &as) != 0 || as.rlim_cur != RLIM_INFINITY)
            return;
        const long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
        if (pages <= 0 || page != long(kPage))
            return;
        const size_t want = size_t(pages) * kPage;
        void* p = mmap(nullptr, want, PROT_READ | PROT_WRITE,
                       MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
        if (p == MAP_FAILED)
            return;
        base = static_cast<char*>(p);
        size = want;
    }
    bool holds(const void* p) const
    {
        return base && static_cast<const char*>(p) >= base &&
               static_cast<const char*>(p) < base + size;
    }

    /// A free run into the map, merged with neighbours of the same residence.
    void addFree(size_t at, size_t n, bool resident)
    {
        if (resident)
            residentFree += n;
        auto next = free.lower_bound(at);
        if (next != free.end() && next->first == at + n && next->second.resident == resident) {
            n += next->second.length;
            next = free.erase(next);
        }
        if (next != free.begin()) {
            auto prev = std::prev(next);
            if (prev->first + prev->second.length == at && prev->second.resident == resident) {
                at = prev->first;
                n += prev->second.length;
                free.erase(prev);
            }
        }
        if (at + n == top && !resident) {  // dropped pages at the top: the top comes down
            top = at;
            return;
        }
        free.emplace(at, FreeRun{n, resident});
    }

    /// [at, at + n) out of the free run at `it`, the rest of it kept free.
    void take(std::map<size_t, FreeRun>::iterator it, size_t n)
    {
        const size_t at = it->first;
        const FreeRun run = it->second;
        free.erase(it);
        if (run.resident)
            residentFree -= run.length;
        if (run.length > n)
            addFree(at + n, run.length - n, run.resident);
    }

    /// Drops resident free pages, the highest first, until at most
    /// kKeptFree stay, and no more than the most ever in use (a small bake
    /// keeps no more than it could use again; a third of it instead made the
    /// 20k benchmark tree fault 170 k pages in, not 138 k, while the growing
    /// crown raised it).
    void keepWithinBudget()
    {
        const size_t budget = std::min(kKeptFree, highWater);
        while (residentFree > budget) {
            auto it = std::find_if(free.rbegin(), free.rend(),
                                   [](const auto& f) { return f.second.resident; });
            const size_t at = it->first, n = it->second.length;
            const size_t drop = std::min(n, residentFree - budget);
            const size_t from = (at + n - drop) & ~(kPage - 1);
            free.erase(std::next(it).base());
            residentFree -= n;
            madvise(base + from, at + n - from, MADV_DONTNEED);
            if (from > at)
                addFree(at, from - at, true);
            addFree(from, at + n - from, false);
        }
    }
};

Region& region()
{
    static Region* r = new Region;  // never unmapped: blocks may be given back during exit
    return *r;
}

size_t pagesOf(size_t bytes)
{
    return (std::max<size_t>(bytes, 1) + kPage - 1) & ~(kPage - 1);
}

}  // namespace

void* acquireScratch(size_t bytes)
{
    Region& R = region();
    if (bytes < kRegionMin)
        return allocateOutside(bytes);
    const size_t n = pagesOf(bytes);
    size_t at = 0;
    bool fresh = false;
    {
        std::lock_guard<std::mutex> lock(R.mutex);
        if (!R.base)
            return allocateOutside(bytes);
        // Resident pages first; then dropped ones; then the top, from the
        // free run that ends there if there is one.
        auto it = std::find_if(R.free.begin(), R.free.end(), [&](const auto& f) {
            return f.second.resident && f.second.length >= n;
        });
        if (it == R.free.end())
            it = std::find_if(R.free.begin(), R.free.end(),
                              [&](const auto& f) { return f.second.length >= n; });
        if (it == R.free.end() && !R.free.empty()) {
            auto last = std::prev(R.free.end());
            if (last->first + last->second.length == R.top)
                it = last;
        }
        at = it != R.free.end() ? it->first : R.top;
        if (at + n > R.size)
            return allocateOutside(bytes);
        if (it != R.free.end()) {
            fresh = !it->second.resident || it->second.length < n;
            R.take(it, std::min(n, it->second.length));
        }
        if (at + n > R.top) {
            R.top = at + n;
            fresh = true;
        }
        R.use.inUse += n;
        R.highWater = std::max(R.highWater, R.use.inUse);
        if (fresh)
            R.use.fresh += n;
    }
    if (fresh)  // (resident pages among them cost nothing to touch)
        touchPages(R.base + at, n);
    return R.base + at;
}

void releaseScratch(void* block, size_t bytes)
{
    if (!block)
        return;
    Region& R = region();
    if (!R.holds(block)) {
        freeOutside(block, bytes);
        return;
    }
    const size_t at = size_t(static_cast<char*>(block) - R.base), n = pagesOf(bytes);
    std::lock_guard<std::mutex> lock(R.mutex);
    R.use.inUse -= n;
    R.addFree(at, n, true);
    R.keepWithinBudget();
}

void trimScratch()
{
    // (Under the lock: another thread may be handed these pages as soon as
    // they count as dropped. The budget keeps them to 32 MB at most.)
    Region& R = region();
    std::lock_guard<std::mutex> lock(R.mutex);
    std::map<size_t, FreeRun> runs;
    runs.swap(R.free);
    R.residentFree = 0;
    for (const auto& [at, run] : runs) {
        if (run.resident)
            madvise(R.base + at, run.length, MADV_DONTNEED);
        R.addFree(at, run.length, false);  // merged again, the top brought down over them
    }
}

size_t scratchAddressSpaceReserved()
{
    Region& R = region();
    std::lock_guard<std::mutex> lock(R.mutex);
    return R.size - R.top;
}

ScratchUse scratchUse()
{
    Region& R = region();
    std::lock_guard<std::mutex> lock(R.mutex);
    ScratchUse u = R.use;
    u.keptFree = R.residentFree;
    u.highWater = R.highWater;
    u.inRegion = R.base != nullptr;
    return u;
}

}  // namespace cambium
