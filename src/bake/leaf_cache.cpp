// cambium — bake stage 2 in sequences: the values of leaves whose program
// is unchanged since the last frame are copied, not sampled.
#include "bake/stages.h"

#include "core/hash.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <cstring>

namespace cambium {

namespace {

uint64_t packOrigin(const int32_t* o)
{
    return nodeKey(o[0], o[1], o[2], 3);
}

}  // namespace

void sampleWithReuse(const FieldProgram& program, FieldSampler& sampler, const BandTopology& topo,
                     double h, LeafValueCache& cache, uint16_t* value, size_t& reused,
                     const Progress& progress)
{
    const size_t n = topo.leaves.size();
    std::vector<std::array<uint64_t, 2>> keys(n);
    std::vector<uint8_t> have(n, 0);
    const bool usable = cache.voxelSize == h;
    tbb::enumerable_thread_specific<std::vector<double>> scratch;
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        const LeafJob& job = topo.leaves[l];
        std::vector<double>& canonical = scratch.local();
        canonical.clear();
        program.canonical(Code(topo.pool.data() + job.codeOffset, size_t(job.codeLength)),
                          canonical);
        keys[l] = hash128(canonical.data(), canonical.size());
        if (!usable)
            return;
        const auto it = cache.slot.find(packOrigin(job.origin));
        if (it != cache.slot.end() && cache.programs[it->second] == keys[l]) {
            std::memcpy(value + l * kLeafVoxels, cache.values.data() + it->second * kLeafVoxels,
                        kLeafVoxels * sizeof(uint16_t));
            have[l] = 1;
        }
    });
    std::vector<LeafJob> todo;
    std::vector<size_t> where;
    for (size_t l = 0; l < n; ++l)
        if (!have[l]) {
            todo.push_back(topo.leaves[l]);
            where.push_back(l);
        }
    reused = n - todo.size();
    std::vector<uint16_t> batch(kBatchLeaves * kLeafVoxels);
    for (size_t b0 = 0; b0 < todo.size(); b0 += kBatchLeaves) {
        const size_t b1 = std::min(todo.size(), b0 + kBatchLeaves);
        sampler.sampleValues(todo, b0, b1, h, batch.data());
        for (size_t k = b0; k < b1; ++k)
            std::memcpy(value + where[k] * kLeafVoxels, batch.data() + (k - b0) * kLeafVoxels,
                        kLeafVoxels * sizeof(uint16_t));
        progress("sampling", 0.8 * double(b1) / double(todo.size()));
    }
    cache.voxelSize = h;
    cache.slot.clear();
    cache.slot.reserve(n);
    for (size_t l = 0; l < n; ++l)
        cache.slot[packOrigin(topo.leaves[l].origin)] = l;
    cache.programs = std::move(keys);
    cache.values.assign(value, value + n * kLeafVoxels);
}

}  // namespace cambium
