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
                     LeafList list, double h, const LeafValueCache& cache, LeafValueCache& next,
                     uint16_t* value, size_t& reused)
{
    std::vector<uint8_t> have(list.size, 0);
    const bool usable = cache.voxelSize == h;
    tbb::enumerable_thread_specific<std::vector<double>> scratch;
    tbb::parallel_for(size_t(0), list.size, [&](size_t k) {
        const size_t l = list.index[k];
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
            std::memcpy(value + k * kLeafVoxels, cache.values.data() + it->second * kLeafVoxels,
                        kLeafVoxels * sizeof(uint16_t));
            have[k] = 1;
        }
    });
    std::vector<uint32_t> todo;
    for (size_t k = 0; k < list.size; ++k)
        if (!have[k])
            todo.push_back(list.index[k]);
    reused += list.size - todo.size();
    std::vector<uint16_t> batch(todo.size() * kLeafVoxels);
    sampleLeafValues(sampler, topo.leaves, {todo.data(), todo.size()}, h, batch.data());
    for (size_t k = 0, t = 0; k < list.size; ++k) {
        if (!have[k])
            std::memcpy(value + k * kLeafVoxels, batch.data() + t++ * kLeafVoxels,
                        kLeafVoxels * sizeof(uint16_t));
        std::memcpy(next.values.data() + size_t(list.index[k]) * kLeafVoxels,
                    value + k * kLeafVoxels, kLeafVoxels * sizeof(uint16_t));
    }
}

}  // namespace cambium
