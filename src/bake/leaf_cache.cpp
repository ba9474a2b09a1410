// cambium — bake stage 2 in sequences: the values of leaves whose program
// is unchanged since the last frame are copied, not sampled.
#include "bake/stages.h"

#include "core/hash.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>

namespace cambium {

namespace {

uint64_t packOrigin(const int32_t* o)
{
    return nodeKey(o[0], o[1], o[2], 3);
}

}  // namespace

LeafValueCache startReuse(const BandTopology& topo, double h)
{
    LeafValueCache next;
    next.voxelSize = h;
    next.programs.resize(topo.leaves.size());
    next.values.resize(topo.leaves.size() * kLeafVoxels);
    return next;
}

void finishReuse(const BandTopology& topo, LeafValueCache& next, LeafValueCache& cache)
{
    const size_t n = topo.leaves.size();
    next.slot.reserve(n);
    for (size_t l = 0; l < n; ++l)
        next.slot[packOrigin(topo.leaves[l].origin)] = l;
    cache = std::move(next);
}

void sampleWithReuse(const FieldProgram& program, FieldSampler& sampler, const BandTopology& topo,
                     size_t begin, size_t end, double h, const LeafValueCache& cache,
                     LeafValueCache& next, uint16_t* value, size_t& reused)
{
    std::vector<uint8_t> have(end - begin, 0);
    const bool usable = cache.voxelSize == h;
    tbb::enumerable_thread_specific<std::vector<double>> scratch;
    tbb::parallel_for(begin, end, [&](size_t l) {
        const LeafJob& job = topo.leaves[l];
        std::vector<double>& canonical = scratch.local();
        canonical.clear();
        program.canonical(Code(topo.pool.data() + job.codeOffset, size_t(job.codeLength)),
                          canonical);
        next.programs[l] = hash128(canonical.data(), canonical.size());
        if (!usable)
            return;
        const auto it = cache.slot.find(packOrigin(job.origin));
        if (it != cache.slot.end() && cache.programs[it->second] == next.programs[l]) {
            std::memcpy(value + (l - begin) * kLeafVoxels,
                        cache.values.data() + it->second * kLeafVoxels,
                        kLeafVoxels * sizeof(uint16_t));
            have[l - begin] = 1;
        }
    });
    std::vector<LeafJob> todo;
    std::vector<size_t> where;
    for (size_t l = begin; l < end; ++l)
        if (!have[l - begin]) {
            todo.push_back(topo.leaves[l]);
            where.push_back(l - begin);
        }
    reused += (end - begin) - todo.size();
    std::vector<uint16_t> batch(std::min<size_t>(kBatchLeaves, todo.size()) * kLeafVoxels);
    for (size_t b0 = 0; b0 < todo.size(); b0 += kBatchLeaves) {
        const size_t b1 = std::min(todo.size(), b0 + kBatchLeaves);
        sampler.sampleValues(todo, b0, b1, h, batch.data());
        for (size_t k = b0; k < b1; ++k)
            std::memcpy(value + where[k] * kLeafVoxels, batch.data() + (k - b0) * kLeafVoxels,
                        kLeafVoxels * sizeof(uint16_t));
    }
    std::copy(value, value + (end - begin) * kLeafVoxels,
              next.values.begin() + long(begin * kLeafVoxels));
}

}  // namespace cambium
