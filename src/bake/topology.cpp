// cambium — narrow-band topology by interval subdivision.
#include "bake/topology.h"

#include <tbb/parallel_for.h>

#include <atomic>
#include <cmath>

namespace cambium {

namespace {

constexpr int kTile = 128;  // an OpenVDB internal node of 16^3 leaves

struct Search {
    const FieldProgram& prog;
    double h, pad, T;
    std::atomic<size_t> boxes{0};

    /// World box of the voxel centres of the cube [o, o + size)^3.
    Box centres(const int o[3], int size) const
    {
        return Box(glm::dvec3(o[0], o[1], o[2]) * h,
                   glm::dvec3(o[0] + size - 1, o[1] + size - 1, o[2] + size - 1) * h);
    }

    void descend(Code code, const int o[3], int size, std::vector<LeafJob>& leaves,
                 std::vector<Instr>& pool)
    {
        std::vector<Instr> spec;
        ++boxes;
        const Interval iv = prog.specialize(code, centres(o, size).padded(pad), &spec);
        if (!iv.contains(T))
            return;  // no surface within the band of this cube
        if (size == 8) {
            LeafJob job{{o[0], o[1], o[2]}, int32_t(pool.size()), 0};
            prog.specialize(spec, centres(o, 8), &pool);
            job.codeLength = int32_t(pool.size()) - job.codeOffset;
            leaves.push_back(job);
            return;
        }
        const int half = size / 2;
        for (int c = 0; c < 8; ++c) {
            const int oc[3] = {o[0] + (c & 1) * half, o[1] + ((c >> 1) & 1) * half,
                               o[2] + ((c >> 2) & 1) * half};
            descend(spec, oc, half, leaves, pool);
        }
    }
};

long long floorDiv(long long a, long long b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

}  // namespace

void bandIndexBounds(const FieldProgram& program, double h, double halfWidth, long long lo[3],
                     long long hi[3])
{
    const Box b = program.positiveBounds().padded(halfWidth * h);
    for (int k = 0; k < 3; ++k) {
        lo[k] = floorDiv((long long)std::floor(b.lo[k] / h), 8) * 8;
        hi[k] = floorDiv((long long)std::ceil(b.hi[k] / h), 8) * 8 + 7;
    }
}

BandTopology findBandLeaves(const FieldProgram& program, double h, double halfWidth,
                            const std::function<void(double)>& progress)
{
    BandTopology out;
    if (program.positiveBounds().empty())
        return out;
    long long lo[3], hi[3];
    bandIndexBounds(program, h, halfWidth, lo, hi);
    // Tiles of 128^3 voxels aligned to OpenVDB's internal nodes cover the box.
    long long t0[3], nt[3];
    for (int k = 0; k < 3; ++k) {
        t0[k] = floorDiv(lo[k], kTile);
        nt[k] = floorDiv(hi[k], kTile) - t0[k] + 1;
    }
    const size_t tiles = size_t(nt[0] * nt[1] * nt[2]);
    Search search{program, h, halfWidth * h, program.threshold()};
    std::vector<std::vector<LeafJob>> tileLeaves(tiles);
    std::vector<std::vector<Instr>> tilePools(tiles);
    std::atomic<size_t> done{0};
    tbb::parallel_for(size_t(0), tiles, [&](size_t t) {
        const int o[3] = {int((t0[0] + long(t % size_t(nt[0]))) * kTile),
                          int((t0[1] + long((t / size_t(nt[0])) % size_t(nt[1]))) * kTile),
                          int((t0[2] + long(t / size_t(nt[0] * nt[1]))) * kTile)};
        search.descend(program.code(), o, kTile, tileLeaves[t], tilePools[t]);
        const size_t d = ++done;
        if (progress)
            progress(double(d) / double(tiles));
    });
    for (size_t t = 0; t < tiles; ++t) {
        const int32_t base = int32_t(out.pool.size());
        for (LeafJob job : tileLeaves[t]) {
            job.codeOffset += base;
            out.leaves.push_back(job);
        }
        out.pool.insert(out.pool.end(), tilePools[t].begin(), tilePools[t].end());
    }
    out.boxesTested = search.boxes;
    return out;
}

}  // namespace cambium
