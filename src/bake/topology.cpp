// cambium — narrow-band topology by interval subdivision.
#include "bake/topology.h"

#include "bake/stages.h"
#include "core/error.h"
#include "core/system.h"

#include <fmt/format.h>

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>

namespace cambium {

namespace {

constexpr int kTile = 128;  // an OpenVDB internal node of 16^3 leaves

struct Search {
    const FieldProgram& prog;
    double h, pad, T;
    std::atomic<size_t> boxes{0};
    /// The leaves' programs so far, and the most they may hold.
    std::atomic<size_t> instructions{0}, leavesFound{0};
    size_t maxInstructions = 0;
    double room = 0.0;
    std::string source = {};

    /// A leaf's program of `n` instructions counted; InputError past the
    /// most.
    void count(size_t n)
    {
        const size_t total = instructions += n, found = ++leavesFound;
        if (total > maxInstructions)
            throw InputError(fmt::format(
                "{}: the band's leaves' programs would take more than half the {} this "
                "process has available ({} leaves so far, {:.0f} instructions each, {} held; "
                "the other half is the bake's): {}",
                source, formatBytes(room), found, double(total) / double(found),
                formatBytes(kBytesPerInstruction * double(total)),
                double(total) / double(found) < kFewInstructions
                    ? "the band is far larger than the primitives' sizes suggest (fields "
                      "that sum reach far): use a larger voxel size"
                    : "many primitives reach every leaf (many overlapping children under "
                      "one operator, or nested warps whose bounds are loose): use a larger "
                      "voxel size, fewer children under one operator or fewer nested warps"));
    }
    /// Instructions a leaf below which its program is not the cause.
    static constexpr double kFewInstructions = 64.0;
    /// An instruction held in a tile's pool and copied into the whole one.
    static constexpr double kBytesPerInstruction = 2.0 * sizeof(Instr);

    /// World box of the voxel centres of the cube [o, o + size)^3.
    Box centres(const int o[3], int size) const
    {
        return Box(glm::dvec3(o[0], o[1], o[2]) * h,
                   glm::dvec3(o[0] + size - 1, o[1] + size - 1, o[2] + size - 1) * h);
    }

    /// One buffer per level of the descent, reused from box to box.
    struct Scratch {
        std::vector<Instr> level[8];
    };

    void descend(Code code, const int o[3], int size, int depth, Scratch& scratch,
                 std::vector<LeafJob>& leaves, std::vector<Instr>& pool)
    {
        std::vector<Instr>& spec = scratch.level[depth];
        spec.clear();
        ++boxes;
        const Interval iv = prog.specialize(code, centres(o, size).padded(pad), &spec);
        if (!iv.contains(T))
            return;  // no surface within the band of this cube
        if (size == 8) {
            LeafJob job{{o[0], o[1], o[2]}, int32_t(pool.size()), 0};
            // The voxels' box and a surface sample's reach beyond it.
            prog.specialize(spec, centres(o, 8).padded(kSurfaceReach * h), &pool);
            job.codeLength = int32_t(pool.size()) - job.codeOffset;
            count(size_t(job.codeLength));
            leaves.push_back(job);
            return;
        }
        const int half = size / 2;
        for (int c = 0; c < 8; ++c) {
            const int oc[3] = {o[0] + (c & 1) * half, o[1] + ((c >> 1) & 1) * half,
                               o[2] + ((c >> 2) & 1) * half};
            descend(spec, oc, half, depth + 1, scratch, leaves, pool);
        }
    }
};

/// A cube of the coarse levels (above the tiles) with its specialised program.
struct Coarse {
    int o[3];
    std::vector<Instr> code;
};

long long floorDiv(long long a, long long b)
{
    return a >= 0 ? a / b : -((-a + b - 1) / b);
}

}  // namespace

namespace {

/// The 128-voxel layers (first, count) of the band's box on each axis.
void layersOf(const FieldProgram& program, double h, double halfWidth, long long t0[3],
              long long nt[3])
{
    long long lo[3], hi[3];
    bandIndexBounds(program, h, halfWidth, lo, hi);
    for (int k = 0; k < 3; ++k) {
        t0[k] = floorDiv(lo[k], kTile);
        nt[k] = floorDiv(hi[k], kTile) - t0[k] + 1;
    }
}

}  // namespace

long long bandLayers(const FieldProgram& program, double voxelSize, double halfWidth)
{
    if (program.positiveBounds().empty())
        return 0;
    long long t0[3], nt[3];
    layersOf(program, voxelSize, halfWidth, t0, nt);
    return std::max({nt[0], nt[1], nt[2]});
}

void bandIndexBounds(const FieldProgram& program, double h, double halfWidth, long long lo[3],
                     long long hi[3])
{
    const Box b = program.positiveBounds().padded(halfWidth * h);
    for (int k = 0; k < 3; ++k) {
        lo[k] = floorDiv((long long)std::floor(b.lo[k] / h), 8) * 8;
        hi[k] = floorDiv((long long)std::ceil(b.hi[k] / h), 8) * 8 + 7;
    }
}

namespace {

/// A tile's bake: its run of layers across `axis`, balanced by the leaves
/// the search finds in each (counted in a first descent that keeps nothing:
/// about the topology's time again), into out.ownedLo and ownedHi; then
/// only the nodes of `level` that reach into the run or its halo stay.
void keepTileRun(Search& search, std::vector<Coarse>& level,
                 tbb::enumerable_thread_specific<Search::Scratch>& scratch, const long long t0[3],
                 const long long nt[3], int axis, BandTile tile, BandTopology& out)
{
    std::vector<size_t> leavesOf(level.size());
    tbb::enumerable_thread_specific<std::pair<std::vector<LeafJob>, std::vector<Instr>>> count;
    tbb::parallel_for(size_t(0), level.size(), [&](size_t t) {
        auto& [jobs, code] = count.local();
        jobs.clear();
        code.clear();
        search.descend(level[t].code, level[t].o, kTile, 0, scratch.local(), jobs, code);
        leavesOf[t] = jobs.size();
    });
    std::vector<size_t> perLayer(static_cast<size_t>(nt[axis]), 0);
    double total = 0.0;
    for (size_t t = 0; t < level.size(); ++t) {
        perLayer[size_t(level[t].o[axis] / kTile - t0[axis])] += leavesOf[t];
        total += double(leavesOf[t]);
    }
    double before = 0.0;
    long long first = -1, last = -1;  // the tile's layers [first, last)
    for (size_t L = 0; L < perLayer.size(); ++L) {
        const int owner = std::min(
            tile.count - 1,
            int(double(tile.count) * (before + 0.5 * double(perLayer[L])) / std::max(total, 1.0)));
        before += double(perLayer[L]);
        if (owner == tile.index) {
            if (first < 0)
                first = (long long)L;
            last = (long long)L + 1;
        }
    }
    if (first < 0)
        first = last = 0;  // an empty tile (more tiles than layers)
    out.ownedLo = (t0[axis] + first) * kTile;
    out.ownedHi = (t0[axis] + last) * kTile;
    const long long keepLo = out.ownedLo - kTileHalo, keepHi = out.ownedHi + kTileHalo;
    level.erase(std::remove_if(level.begin(), level.end(),
                               [&](const Coarse& c) {
                                   return first == last || c.o[axis] + kTile <= keepLo ||
                                          c.o[axis] >= keepHi;
                               }),
                level.end());
}

}  // namespace

BandTopology findBandLeaves(const FieldProgram& program, double h, double halfWidth,
                            const std::function<void(double)>& progress, BandTile tile,
                            const std::string& source)
{
    BandTopology out;
    if (program.positiveBounds().empty())
        return out;
    long long lo[3], hi[3];
    bandIndexBounds(program, h, halfWidth, lo, hi);
    // Tiles of 128^3 voxels aligned to OpenVDB's internal nodes cover the
    // box.  Above them, coarse cubes of 2^k tiles are specialised level by
    // level, so that a tile starts from the few primitives near it rather
    // than from all of them (20,000 cones: a third of the search's time).
    long long t0[3], nt[3];
    layersOf(program, h, halfWidth, t0, nt);
    int span = 1;  // tiles per side of the root cube
    while (span < nt[0] || span < nt[1] || span < nt[2])
        span *= 2;
    Search search{program, h, halfWidth * h, program.threshold()};
    // Half the room for the programs (the leaves' values and grids take the
    // rest), and offsets within int32.
    search.room = availableMemoryBytes();
    search.maxInstructions = size_t(std::min(0.5 * search.room / Search::kBytesPerInstruction,
                                             double(std::numeric_limits<int32_t>::max())));
    search.source = source;
    std::vector<Coarse> level(1);
    for (int k = 0; k < 3; ++k)
        level[0].o[k] = int(t0[k] * kTile);
    level[0].code = program.code();
    for (int size = span * kTile; size > kTile; size /= 2) {
        // Children of every cube, inside the covered box; those that can hold
        // band voxels go on with their specialised programs.
        const int half = size / 2;
        std::vector<Coarse> next(level.size() * 8);
        tbb::parallel_for(size_t(0), next.size(), [&](size_t i) {
            const Coarse& parent = level[i / 8];
            const int c = int(i % 8);
            Coarse& child = next[i];
            for (int k = 0; k < 3; ++k)
                child.o[k] = parent.o[k] + ((c >> k) & 1) * half;
            for (int k = 0; k < 3; ++k)
                if (child.o[k] > hi[k])
                    return;  // beyond the box: left empty
            ++search.boxes;
            const Interval iv = program.specialize(
                parent.code, search.centres(child.o, half).padded(search.pad), &child.code);
            if (!iv.contains(search.T))
                child.code.clear();
        });
        level.clear();
        for (Coarse& c : next)
            if (!c.code.empty())
                level.push_back(std::move(c));
    }
    // The slab axis: the box's longest, in tiles.
    const int axis = int(std::max_element(nt, nt + 3) - nt), a = (axis + 1) % 3, b = (axis + 2) % 3;
    out.slabAxis = axis;
    tbb::enumerable_thread_specific<Search::Scratch> scratch;
    if (tile.count > 0)
        keepTileRun(search, level, scratch, t0, nt, axis, tile, out);
    const size_t tiles = level.size();
    std::vector<std::vector<LeafJob>> tileLeaves(tiles);
    std::vector<std::vector<Instr>> tilePools(tiles);
    std::atomic<size_t> done{0};
    tbb::parallel_for(size_t(0), tiles, [&](size_t t) {
        search.descend(level[t].code, level[t].o, kTile, 0, scratch.local(), tileLeaves[t],
                       tilePools[t]);
        const size_t d = ++done;
        if (progress)
            progress(double(d) / double(tiles));
    });
    // (Reserved: growing by doubling copied and faulted in the programs'
    // pool, 23 MB on the 20k benchmark tree, twice over.)
    std::vector<LeafJob> found;
    size_t leafCount = 0, poolSize = out.pool.size();
    for (size_t t = 0; t < tiles; ++t) {
        leafCount += tileLeaves[t].size();
        poolSize += tilePools[t].size();
    }
    found.reserve(leafCount);
    if (tile.count == 0)
        out.pool.reserve(poolSize);
    for (size_t t = 0; t < tiles; ++t) {
        const int32_t base = int32_t(out.pool.size());
        for (LeafJob job : tileLeaves[t]) {
            // A tile's bake keeps the leaves of its run and halo only (the
            // programs of the others are dropped below).
            if (tile.count > 0 && (job.origin[axis] + 8 <= out.ownedLo - kTileHalo ||
                                   job.origin[axis] >= out.ownedHi + kTileHalo))
                continue;
            if (tile.count > 0) {
                const auto from = tilePools[t].begin() + job.codeOffset;
                job.codeOffset = int32_t(out.pool.size());
                out.pool.insert(out.pool.end(), from, from + job.codeLength);
            } else {
                job.codeOffset += base;
            }
            found.push_back(job);
        }
        if (tile.count == 0)
            out.pool.insert(out.pool.end(), tilePools[t].begin(), tilePools[t].end());
        tileLeaves[t] = {};
        tilePools[t] = {};
    }
    // Slab order: the 64^3 cubes (each one run of the depth-first descent)
    // sorted by their coordinate across the longest axis first, so that a
    // bake can finish slab after slab and free what it no longer needs.
    const std::vector<size_t> cube = cubeRuns(found, 6);
    std::vector<size_t> order(cube.size() - 1);
    for (size_t i = 0; i < order.size(); ++i)
        order[i] = i;
    auto key = [&](size_t i) {
        const int32_t* o = found[cube[i]].origin;
        return std::array<int32_t, 3>{o[axis] >> 6, o[a] >> 6, o[b] >> 6};
    };
    std::sort(order.begin(), order.end(), [&](size_t i, size_t j) { return key(i) < key(j); });
    out.leaves.reserve(found.size());
    for (size_t i : order)
        out.leaves.insert(out.leaves.end(), found.begin() + long(cube[i]),
                          found.begin() + long(cube[i + 1]));
    out.boxesTested = search.boxes;
    return out;
}

}  // namespace cambium
