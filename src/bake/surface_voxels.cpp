// cambium — bake stage 3b: the voxels next to a sign change of F - T, and
// the distance to the nearest crossing along their edges.
#include "bake/stages.h"

#include "core/clock.h"

#include <tbb/parallel_for.h>

#include <cmath>

namespace cambium {

const int kFaceDirections[6][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                   {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};

void findInsideBits(LeafState& state, LeafList list)
{
    tbb::parallel_for(size_t(0), list.size, [&](size_t k) {
        const size_t l = list.index[k];
        const uint16_t* v = state.value[l];
        for (int z = 0; z < 8; ++z) {
            uint64_t m = 0;
            for (int i = 0; i < 64; ++i)
                m |= uint64_t(halfPositive(v[64 * z + i])) << i;
            state.inside[l][size_t(z)] = m;
        }
    });
}

SurfaceVoxels findSurfaceVoxels(LeafList list, const std::vector<LeafNeighbours>& nb,
                                LeafState& state, BakeTimings& timings)
{
    const auto start = Clock::now();
    SurfaceVoxels out;
    const std::vector<InsideBits>& insideBits = state.inside;
    // The voxels of leaf l with a face neighbour on the other side of the
    // surface, per plane z and direction (the order of dirs), by shifting the
    // inside bits; a missing neighbour leaf (no surface within a voxel of it)
    // counts as the same side.  Returns how many voxels have one.
    auto crossings = [&](size_t l, uint64_t across[8][6]) {
        constexpr uint64_t col0 = 0x0101010101010101ull, col7 = col0 << 7, row0 = 0xFFull,
                           row7 = row0 << 56;
        const auto& M = insideBits[l];
        auto plane = [&](int k, int z) -> const uint64_t* {
            const int32_t m = nb[l][size_t(k)];
            return m < 0 ? nullptr : &insideBits[size_t(m)][size_t(z)];
        };
        size_t count = 0;
        for (int z = 0; z < 8; ++z) {
            const uint64_t m = M[size_t(z)];
            const uint64_t* xp = plane(kNeighbourXPlus, z);
            const uint64_t* xm = plane(kNeighbourXMinus, z);
            const uint64_t* yp = plane(kNeighbourYPlus, z);
            const uint64_t* ym = plane(kNeighbourYMinus, z);
            const uint64_t nxp = ((m >> 1) & ~col7) | (xp ? (*xp & col0) << 7 : m & col7);
            const uint64_t nxm = ((m << 1) & ~col0) | (xm ? (*xm & col7) >> 7 : m & col0);
            const uint64_t nyp = (m >> 8) | (yp ? (*yp & row0) << 56 : m & row7);
            const uint64_t nym = (m << 8) | (ym ? (*ym & row7) >> 56 : m & row0);
            const uint64_t* zp = z < 7 ? &M[size_t(z + 1)] : plane(kNeighbourZPlus, 0);
            const uint64_t* zm = z > 0 ? &M[size_t(z - 1)] : plane(kNeighbourZMinus, 7);
            const uint64_t nzp = zp ? *zp : m, nzm = zm ? *zm : m;
            const uint64_t d[6] = {m ^ nxp, m ^ nxm, m ^ nyp, m ^ nym, m ^ nzp, m ^ nzm};
            for (int k = 0; k < 6; ++k)
                across[z][k] = d[k];
            count += size_t(__builtin_popcountll(d[0] | d[1] | d[2] | d[3] | d[4] | d[5]));
        }
        return count;
    };
    // The surface voxels of the leaves in one array, leaf by leaf: counted,
    // then written (one block: no allocation per leaf).
    std::vector<size_t>& first = out.first;
    first.assign(list.size + 1, 0);
    tbb::parallel_for(size_t(0), list.size, [&](size_t k) {
        uint64_t across[8][6];
        const size_t l = list.index[k];
        state.count[l] = uint32_t(crossings(l, across));
        first[k + 1] = state.count[l];
    });
    for (size_t k = 0; k < list.size; ++k)
        first[k + 1] += first[k];
    const size_t np = first[list.size];
    out.count = np;
    out.edges = parallelArray<SurfaceEdge>(np);
    out.queries = parallelArray<SurfaceQuery>(np);
    SurfaceEdge* edges = out.edges.get();
    SurfaceQuery* queries = out.queries.get();
    tbb::parallel_for(size_t(0), list.size, [&](size_t m) {
        const size_t l = list.index[m];
        const uint16_t* own = state.value[l];
        uint64_t across[8][6];
        crossings(l, across);
        size_t j = first[m];
        for (int z = 0; z < 8; ++z) {
            const uint64_t* d = across[z];
            uint64_t change = d[0] | d[1] | d[2] | d[3] | d[4] | d[5];
            while (change) {
                const int bit = __builtin_ctzll(change);
                change &= change - 1;
                const int x = bit & 7, y = bit >> 3;
                const int i = vox(x, y, z);
                const float fv = halfToFloat(own[i]);
                float edge = INFINITY;
                int e = 0;
                // Branch-free over the six directions (whether a direction
                // crosses is a coin toss for the branch predictor): one that
                // does not reads the voxel itself and is ignored.
#pragma GCC unroll 6
                for (int k = 0; k < 6; ++k) {
                    const bool cross =
                        (d[k] >> bit) & 1;  // a neighbour leaf exists where it is set
                    const int* dir = kFaceDirections[k];
                    const int nx = x + dir[0], ny = y + dir[1], nz = z + dir[2];
                    const int ox = nx < 0 ? -1 : (nx > 7), oy = ny < 0 ? -1 : (ny > 7),
                              oz = nz < 0 ? -1 : (nz > 7);
                    const int32_t nl =
                        (ox | oy | oz) ? nb[l][size_t(neighbourSlot(ox, oy, oz))] : int32_t(l);
                    const uint16_t* at =
                        cross ? state.value[size_t(nl)] + vox(nx - 8 * ox, ny - 8 * oy, nz - 8 * oz)
                              : own + i;
                    const float fu = halfToFloat(*at);
                    const float tc = cross ? fv / (fv - fu) : INFINITY;
                    e = tc < edge ? k : e;
                    edge = tc < edge ? tc : edge;
                }
                // Across a sign change fv / (fv - fu) lies in [0, 1].
                edges[j] = {uint16_t(i), uint8_t(e), std::min(edge, 1.0f), fv};
                queries[j] = {int32_t(l), uint16_t(i)};
                ++j;
            }
        }
        // Voxels come out plane by plane in x + 8 y order: voxel order.
    });
    timings.signChanges += secondsSince(start);
    return out;
}

}  // namespace cambium
