// cambium — bake stage 3a: each leaf's neighbours.
#include "bake/stages.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <stdexcept>

namespace cambium {

std::vector<size_t> cubeRuns(const std::vector<LeafJob>& leaves, int shift, size_t begin,
                             size_t end)
{
    end = std::min(end, leaves.size());
    std::vector<size_t> start;
    for (size_t l = begin; l < end; ++l) {
        const int32_t* o = leaves[l].origin;
        const int32_t* p = l > begin ? leaves[l - 1].origin : nullptr;
        if (!p || (o[0] >> shift) != (p[0] >> shift) || (o[1] >> shift) != (p[1] >> shift) ||
            (o[2] >> shift) != (p[2] >> shift))
            start.push_back(l);
    }
    start.push_back(end);
    return start;
}

std::vector<size_t> slabRuns(const std::vector<LeafJob>& leaves, int axis)
{
    std::vector<size_t> start;
    for (size_t l = 0; l < leaves.size(); ++l)
        if (l == 0 || (leaves[l].origin[axis] >> 6) != (leaves[l - 1].origin[axis] >> 6))
            start.push_back(l);
    start.push_back(leaves.size());
    return start;
}

std::vector<LeafNeighbours> findNeighbours(const std::vector<LeafJob>& leaves)
{
    const size_t n = leaves.size();
    std::vector<LeafNeighbours> nb(n);
    // Leaf origins to indices through the 64^3 cubes the topology grouped
    // them by (each cube's leaves are contiguous): per cube a dense 8^3
    // table, the cubes in a small hash.
    const std::vector<size_t> cubeFirst = cubeRuns(leaves, 6);
    const size_t cubes = cubeFirst.size() - 1;
    auto cubeKey = [](int x, int y, int z) { return nodeKey(x, y, z, 6); };  // of a voxel
    size_t cap = 1;
    while (cap < 2 * cubes + 2)
        cap <<= 1;
    std::vector<uint64_t> keys(cap, ~uint64_t(0));
    std::vector<int32_t> vals(cap, -1);
    auto slot = [&](uint64_t k) { return size_t((k * 0x9E3779B97F4A7C15ull) >> 20) & (cap - 1); };
    for (size_t ci = 0; ci < cubes; ++ci) {
        const int32_t* o = leaves[cubeFirst[ci]].origin;
        const uint64_t k = cubeKey(o[0], o[1], o[2]);
        size_t i = slot(k);
        while (keys[i] != ~uint64_t(0)) {
            if (keys[i] == k)
                throw std::logic_error("bake: the leaves of a 64^3 cube are not contiguous");
            i = (i + 1) & (cap - 1);
        }
        keys[i] = k;
        vals[i] = int32_t(ci);
    }
    auto findCube = [&](int x, int y, int z) -> int32_t {
        const uint64_t k = cubeKey(x, y, z);
        size_t i = slot(k);
        while (keys[i] != k && keys[i] != ~uint64_t(0))
            i = (i + 1) & (cap - 1);
        return keys[i] == k ? vals[i] : -1;
    };
    auto dense = parallelArray<int32_t>(cubes * 512);
    tbb::parallel_for(size_t(0), cubes, [&](size_t ci) {
        int32_t* d = dense.get() + ci * 512;
        std::fill(d, d + 512, -1);
        for (size_t l = cubeFirst[ci]; l < cubeFirst[ci + 1]; ++l) {
            const int32_t* o = leaves[l].origin;
            d[((o[0] >> 3) & 7) + 8 * ((o[1] >> 3) & 7) + 64 * ((o[2] >> 3) & 7)] = int32_t(l);
        }
    });
    tbb::parallel_for(size_t(0), cubes, [&](size_t ci) {
        for (size_t l = cubeFirst[ci]; l < cubeFirst[ci + 1]; ++l) {
            const int32_t* o = leaves[l].origin;
            for (int k = 0; k < 27; ++k) {
                const int x = o[0] + 8 * (k % 3 - 1), y = o[1] + 8 * ((k / 3) % 3 - 1),
                          z = o[2] + 8 * (k / 9 - 1);
                const bool same =
                    (x >> 6) == (o[0] >> 6) && (y >> 6) == (o[1] >> 6) && (z >> 6) == (o[2] >> 6);
                const int32_t cube = same ? int32_t(ci) : findCube(x, y, z);
                nb[l][size_t(k)] =
                    cube < 0
                        ? -1
                        : dense[size_t(cube) * 512 +
                                size_t(((x >> 3) & 7) + 8 * ((y >> 3) & 7) + 64 * ((z >> 3) & 7))];
            }
        }
    });
    return nb;
}

}  // namespace cambium
