// cambium — bake stage 3a: each leaf's neighbours.
#include "bake/stages.h"

#include <tbb/parallel_for.h>

#include <stdexcept>

namespace cambium {

/// Where each run of consecutive leaves inside one cube of 2^shift voxels a
/// side starts, then leaves.size().  The topology lists leaves depth-first
/// within its 128^3 tiles, so each such cube (shift <= 7) is one run.
std::vector<size_t> cubeRuns(const std::vector<LeafJob>& leaves, int shift)
{
    std::vector<size_t> start;
    for (size_t l = 0; l < leaves.size(); ++l) {
        const int32_t* o = leaves[l].origin;
        const int32_t* p = l ? leaves[l - 1].origin : nullptr;
        if (!p || (o[0] >> shift) != (p[0] >> shift) || (o[1] >> shift) != (p[1] >> shift) ||
            (o[2] >> shift) != (p[2] >> shift))
            start.push_back(l);
    }
    start.push_back(leaves.size());
    return start;
}

std::vector<LeafNeighbours> findNeighbours(const std::vector<LeafJob>& leaves)
{
    const size_t n = leaves.size();
    std::vector<LeafNeighbours> nb(n);
    // Leaf origins to indices through the 128^3 tiles the topology grouped
    // them by (each tile's leaves are contiguous): per tile a dense 16^3
    // table, the tiles in a small hash.
    const std::vector<size_t> tileFirst = cubeRuns(leaves, 7);
    const size_t tiles = tileFirst.size() - 1;
    auto tileKey = [](int x, int y, int z) { return nodeKey(x, y, z, 7); };  // of a voxel
    size_t cap = 1;
    while (cap < 2 * tiles + 2)
        cap <<= 1;
    std::vector<uint64_t> keys(cap, ~uint64_t(0));
    std::vector<int32_t> vals(cap, -1);
    auto slot = [&](uint64_t k) { return size_t((k * 0x9E3779B97F4A7C15ull) >> 20) & (cap - 1); };
    for (size_t ti = 0; ti < tiles; ++ti) {
        const int32_t* o = leaves[tileFirst[ti]].origin;
        const uint64_t k = tileKey(o[0], o[1], o[2]);
        size_t i = slot(k);
        while (keys[i] != ~uint64_t(0)) {
            if (keys[i] == k)
                throw std::logic_error("bake: the leaves of a 128^3 tile are not contiguous");
            i = (i + 1) & (cap - 1);
        }
        keys[i] = k;
        vals[i] = int32_t(ti);
    }
    auto findTile = [&](int x, int y, int z) -> int32_t {
        const uint64_t k = tileKey(x, y, z);
        size_t i = slot(k);
        while (keys[i] != k && keys[i] != ~uint64_t(0))
            i = (i + 1) & (cap - 1);
        return keys[i] == k ? vals[i] : -1;
    };
    auto dense = parallelArray<int32_t>(tiles * 4096);
    tbb::parallel_for(size_t(0), tiles, [&](size_t ti) {
        int32_t* d = dense.get() + ti * 4096;
        std::fill(d, d + 4096, -1);
        for (size_t l = tileFirst[ti]; l < tileFirst[ti + 1]; ++l) {
            const int32_t* o = leaves[l].origin;
            d[((o[0] >> 3) & 15) + 16 * ((o[1] >> 3) & 15) + 256 * ((o[2] >> 3) & 15)] = int32_t(l);
        }
    });
    tbb::parallel_for(size_t(0), tiles, [&](size_t ti) {
        for (size_t l = tileFirst[ti]; l < tileFirst[ti + 1]; ++l) {
            const int32_t* o = leaves[l].origin;
            for (int k = 0; k < 27; ++k) {
                const int x = o[0] + 8 * (k % 3 - 1), y = o[1] + 8 * ((k / 3) % 3 - 1),
                          z = o[2] + 8 * (k / 9 - 1);
                const bool same =
                    (x >> 7) == (o[0] >> 7) && (y >> 7) == (o[1] >> 7) && (z >> 7) == (o[2] >> 7);
                const int32_t tile = same ? int32_t(ti) : findTile(x, y, z);
                nb[l][size_t(k)] = tile < 0 ? -1
                                            : dense[size_t(tile) * 4096 +
                                                    size_t(((x >> 3) & 15) + 16 * ((y >> 3) & 15) +
                                                           256 * ((z >> 3) & 15))];
            }
        }
    });
    return nb;
}

}  // namespace cambium
