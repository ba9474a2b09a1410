// cambium — narrow-band level-set assembly from sampled fields.
#include "bake/levelset.h"

#include "bake/topology.h"
#include "core/clock.h"
#include "core/math.h"
#include "core/memory.h"

#include "cb_program.h"

#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <cstdlib>
#include <cstring>
#include <stdexcept>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <array>

namespace cambium {

namespace {

constexpr int kBatchLeaves = 4096;


/// A point on the surface found next to a sign change, in index space.
struct SurfacePoint {
    float p[3];      // position
    float n[3];      // outward unit normal
    uint8_t rgb[3];  // colour
};

inline int vox(int x, int y, int z) { return x + 8 * y + 64 * z; }

/// Chains of consecutive leaves along one axis, leaf by leaf (indices into
/// the tile's local leaves): directional sweeps run along them.
struct Chains {
    std::vector<int> leaf;   ///< chain after chain
    std::vector<int> start;  ///< chain k: leaf[start[k], start[k + 1])
    size_t size() const { return start.empty() ? 0 : start.size() - 1; }
};

#if defined(__clang__)
// clang 14 (the sanitizer and fuzzing build) knows x86-64-v4 neither as a
// target nor as a CPU feature: one portable build of the eight-lane sweeps.
#define CB_SWEEP_NAME sweepAxis8
#define CB_SWEEP_TARGET
#define CB_SWEEP_LINES 1
#include "bake/sweep.inc"

void sweepAxis(const Chains& rows, const std::vector<LeafJob>& local, int axis,
               int32_t* srcAll, float* const pos[3], float limit2, std::vector<float>& turned)
{
    sweepAxis8(rows, local, axis, srcAll, pos, limit2, turned);
}
#else
// The directional sweeps (src/bake/sweep.inc), compiled for AVX-512 with
// vectors of sixteen lanes, and with eight lanes for AVX2 and older CPUs.
#define CB_SWEEP_NAME sweepAxis16
#define CB_SWEEP_TARGET __attribute__((target("arch=x86-64-v4")))
#define CB_SWEEP_LINES 2
#include "bake/sweep.inc"
#define CB_SWEEP_NAME sweepAxis8
#define CB_SWEEP_TARGET __attribute__((target_clones("arch=x86-64-v3", "default")))
#define CB_SWEEP_LINES 1
#include "bake/sweep.inc"

/// `turned`: scratch for the x-sweeps' transposed chains.
void sweepAxis(const Chains& rows, const std::vector<LeafJob>& local, int axis,
               int32_t* srcAll, float* const pos[3], float limit2, std::vector<float>& turned)
{
    static const bool avx512 = __builtin_cpu_supports("x86-64-v4");
    if (avx512)
        sweepAxis16(rows, local, axis, srcAll, pos, limit2, turned);
    else
        sweepAxis8(rows, local, axis, srcAll, pos, limit2, turned);
}
#endif

/// Signed distances (world units) of one leaf's voxels (order x + 8 y + 64 z)
/// from their nearest surface points p (index space, 1e15 where none) with
/// unit normals (nx, ny, nz)[src], and whether each lies in the band.  The tangent plane's
/// distance corrects for the spacing of the surface points (about a voxel)
/// where the surface is smooth: there the nearest point lies near the foot of
/// the perpendicular.  A lateral offset of several voxels means a crease (CSG,
/// a scar's rim) whose nearest point is the point itself: the Euclidean
/// distance takes over from 1.5 to 2.5 voxels of offset; it also takes over
/// where the plane disagrees with the field's sign.  Branch-free, so that it
/// runs as vectors (clones chosen at run time, as for the sweeps; the file is
/// compiled without errno and trapping math, which would keep it scalar).
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"))) int leafDistances(
    const int32_t* origin, const uint16_t* __restrict value, const float* __restrict px,
    const float* __restrict py, const float* __restrict pz, const int32_t* __restrict src,
    const float* __restrict nx, const float* __restrict ny, const float* __restrict nz, float h,
    float background, float* __restrict sd, uint8_t* __restrict on)
{
    const float ox = float(origin[0]), oy = float(origin[1]), oz = float(origin[2]);
    int active = 0;
    for (int i = 0; i < kLeafVoxels; ++i) {
        const float sign = halfPositive(value[i]) ? -1.0f : 1.0f;  // F - T > 0: inside, negative
        const float dx = ox + float(i & 7) - px[i], dy = oy + float((i >> 3) & 7) - py[i],
                    dz = oz + float(i >> 6) - pz[i];
        const float e2 = dx * dx + dy * dy + dz * dz;
        const int32_t j = src[i];  // gathered: the point's normal
        const float plane = dx * nx[j] + dy * ny[j] + dz * nz[j];
        const float euclid = std::sqrt(e2);
        const float l2 = e2 - plane * plane;
        const float lateral = std::sqrt(l2 > 0.0f ? l2 : 0.0f);
        const float b0 = lateral - 1.5f, b1 = b0 > 0.0f ? b0 : 0.0f, b = b1 < 1.0f ? b1 : 1.0f;
        const float flat = std::fabs(plane);
        const float blended = flat + (euclid - flat) * (b * b * (3.0f - 2.0f * b));
        const float mag = (plane < 0.0f) != (sign < 0.0f) ? euclid : blended;
        const float v = sign * mag * h;
        const bool in = std::fabs(v) < background;  // false where there is no point (1e15)
        sd[i] = in ? v : sign * background;
        on[i] = in;
        active += in;
    }
    return active;
}

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

/// The chains of `jobs` along `axis`, through a dense table of the leaves'
/// box (a tile's leaves with their halo span ten leaves a side), line by line.
void buildChains(const std::vector<LeafJob>& jobs, int axis, std::vector<int>& table, Chains& out)
{
    out.leaf.clear();
    out.start.clear();
    if (jobs.empty())
        return;
    int lo[3], hi[3];
    for (int k = 0; k < 3; ++k)
        lo[k] = hi[k] = jobs[0].origin[k] >> 3;
    for (const LeafJob& j : jobs)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], j.origin[k] >> 3);
            hi[k] = std::max(hi[k], j.origin[k] >> 3);
        }
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;
    const size_t nu = size_t(hi[axis] - lo[axis] + 1), nv = size_t(hi[a] - lo[a] + 1), nw = size_t(hi[b] - lo[b] + 1);
    table.assign(nu * nv * nw, -1);
    for (size_t i = 0; i < jobs.size(); ++i) {
        const int* o = jobs[i].origin;
        table[size_t((o[axis] >> 3) - lo[axis]) +
              nu * (size_t((o[a] >> 3) - lo[a]) + nv * size_t((o[b] >> 3) - lo[b]))] = int(i);
    }
    for (size_t line = 0; line < nv * nw; ++line) {
        const int* t = table.data() + line * nu;
        for (size_t u = 0; u < nu; ++u) {
            if (t[u] < 0)
                continue;
            if (u == 0 || t[u - 1] < 0)
                out.start.push_back(int(out.leaf.size()));
            out.leaf.push_back(t[u]);
        }
    }
    out.start.push_back(int(out.leaf.size()));
}

}  // namespace

double autoVoxelSize(const FieldProgram& program, double voxels)
{
    const Box b = program.positiveBounds();
    const glm::dvec3 s = b.size();
    const double extent = std::max({s.x, s.y, s.z});
    return extent > 0.0 ? extent / voxels : 0.0;
}

double estimateBakeBytes(const FieldProgram& program, double h, double halfWidth)
{
    // Surface area of the primitives (an overestimate where they overlap).
    // Each is convex, so the part of it inside a box has at most the box's
    // area: the surface's bounds (a huge sphere that cuts, a saw cut, counts
    // so) and its support box in world space — its own, or under warps the
    // outermost warp's (a unit sphere mapped onto a leaf counts as the leaf).
    auto boxArea = [](const Box& box) {
        const glm::dvec3 b = box.size();
        return 2.0 * (b.x * b.y + b.y * b.z + b.z * b.x);
    };
    const double boundsArea = boxArea(program.positiveBounds());
    double area = 0.0;
    const auto& P = program.params();
    std::vector<const Box*> warps;
    for (const Instr& in : program.code()) {
        if (in.op == CB_I_WARP)
            warps.push_back(&program.supportOf(in));
        else if (in.op == CB_I_UNWARP)
            warps.pop_back();
        const double* q = P.data() + in.a;
        double a = -1.0;
        if (in.op == CB_SPHERE)
            a = 4.0 * M_PI * q[3] * q[3];
        else if (in.op == CB_SEGMENT || in.op == CB_CONE)
            a = M_PI * (q[7] + q[8]) * q[6] + 2.0 * M_PI * std::max(q[7], q[8]) * std::max(q[7], q[8]);
        else if (in.op == CB_CONVOLUTION_SEGMENT) {
            const double r = q[10] / 3.0;  // its window is three times its largest radius
            a = 2.0 * M_PI * r * q[6] + 2.0 * M_PI * r * r;
        }
        if (a >= 0.0)
            area += std::min({a, boundsArea, boxArea(warps.empty() ? program.supportOf(in) : *warps.front())});
    }
    // Band voxels; about three sampled voxels per band voxel, each holding its
    // value (4 bytes), propagation state (8) and a share of the surface points
    // (3); the output grids (16 bytes per band voxel).
    const double bandVoxels = area / (h * h) * 2.0 * halfWidth;
    return bandVoxels * (3.0 * (4.0 + 8.0 + 3.0) + 16.0) + 64e6;
}

namespace {

/// The band's half-width in world units, rounded up so that OpenVDB's checks
/// see at least halfWidth voxels.
float bandBackground(double h, double W)
{
    float background = float(W * h);
    while (double(background) / h < W)
        background = std::nextafter(background, INFINITY);
    return background;
}

/// The grids without voxels: names, class, transform.
void createGrids(BakedGrids& out, double h, float background, const openvdb::Vec3f& colourBackground)
{
    out.surface = openvdb::FloatGrid::create(background);
    out.color = openvdb::Vec3fGrid::create(colourBackground);
    const auto xform = openvdb::math::Transform::createLinearTransform(h);
    out.surface->setTransform(xform);
    out.color->setTransform(xform->copy());
    out.surface->setGridClass(openvdb::GRID_LEVEL_SET);
    out.surface->setName(kSurfaceGrid);
    out.color->setName(kColorGrid);
    out.color->setVectorType(openvdb::VEC_INVARIANT);
}

void addFog(BakedGrids& out)
{
    out.density = out.surface->deepCopy();
    openvdb::tools::sdfToFogVolume(*out.density);
    out.density->setName(kDensityGrid);
}

}  // namespace

BakedGrids emptyLevelSet(const BakeOptions& opt)
{
    BakedGrids out;
    createGrids(out, opt.voxelSize, bandBackground(opt.voxelSize, opt.halfWidth), openvdb::Vec3f(0.0f));
    if (opt.fog)
        addFog(out);
    out.stats.voxelSize = opt.voxelSize;
    return out;
}

namespace {

/// One key for the node of size 2^log2 holding voxel (x, y, z): its
/// coordinates, 21 bits each.
uint64_t nodeKey(int x, int y, int z, int log2)
{
    return (uint64_t(uint32_t(x >> log2) & 0x1FFFFF) << 42) | (uint64_t(uint32_t(y >> log2) & 0x1FFFFF) << 21) |
           uint64_t(uint32_t(z >> log2) & 0x1FFFFF);
}

uint64_t packOrigin(const int32_t* o) { return nodeKey(o[0], o[1], o[2], 3); }

/// Two independent 64-bit hashes of a sequence of doubles' bits (each word
/// mixed with SplitMix64's finaliser into two differently seeded lanes).
std::array<uint64_t, 2> hash128(const std::vector<double>& v)
{
    uint64_t a = 0x243f6a8885a308d3ull ^ v.size(), b = 0x13198a2e03707344ull + v.size();
    for (double d : v) {
        uint64_t x;
        std::memcpy(&x, &d, 8);
        a = mix64(a ^ x) + 0x9e3779b97f4a7c15ull;
        b = mix64(b + x * 0xd6e8feb86659fd93ull) ^ 0xa0761d6478bd642full;
    }
    return {a, b};
}

/// Step 2 with a cache: leaves whose canonical program the cache holds for
/// their origin get its values, the rest are sampled; the cache then holds
/// this bake's leaves.
template <class Progress>
void sampleWithReuse(const FieldProgram& program, FieldSampler& sampler, const BandTopology& topo, double h,
                     LeafValueCache& cache, uint16_t* value, size_t& reused, const Progress& progress)
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
        program.canonical(Code(topo.pool.data() + job.codeOffset, size_t(job.codeLength)), canonical);
        keys[l] = hash128(canonical);
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

}  // namespace

BakedGrids bakeLevelSet(const FieldProgram& program, FieldSampler& sampler,
                        const BakeOptions& opt)
{
    const auto start = Clock::now();
    const double h = opt.voxelSize, W = opt.halfWidth;
    const float background = bandBackground(h, W);
    BakedGrids out;
    BakeStats& st = out.stats;
    st.voxelSize = h;
    auto progress = [&](const char* stage, double f) {
        if (opt.progress)
            opt.progress(stage, f);
    };

    // 1. Topology.
    auto t = Clock::now();
    BandTopology topo = findBandLeaves(program, h, W, [&](double f) { progress("topology", f); });
    st.topologySeconds = secondsSince(t);
    st.boxesTested = topo.boxesTested;
    const size_t n = topo.leaves.size();
    st.candidateLeaves = n;
    st.meanProgramLength = n ? double(topo.pool.size()) / double(n) : 0.0;

    // 2. Values of every voxel of those leaves, in batches.
    t = Clock::now();
    auto value = parallelArray<uint16_t>(n * kLeafVoxels);  // F - T
    sampler.setProgram(program);
    sampler.setLeafCode(topo.pool);
    if (opt.reuse) {
        sampleWithReuse(program, sampler, topo, h, *opt.reuse, value.get(), st.reusedLeaves, progress);
    } else {
        for (size_t b0 = 0; b0 < n; b0 += kBatchLeaves) {
            const size_t b1 = std::min(n, b0 + kBatchLeaves);
            sampler.sampleValues(topo.leaves, b0, b1, h, value.get() + b0 * kLeafVoxels);
            progress("sampling", 0.8 * double(b1) / double(n));
        }
    }
    const double valueSeconds = secondsSince(t);
    const auto tEdges = Clock::now();

    // 3. Neighbours, the voxels next to a sign change of F - T, their
    // gradients and colours, and the surface points they give.
    std::vector<std::array<int32_t, 27>> nb(n);  // (dx+1) + 3 (dy+1) + 9 (dz+1), -1 if absent
    {
        // Leaf origins to indices through the 128^3 tiles the topology grouped
        // them by (each tile's leaves are contiguous): per tile a dense 16^3
        // table, the tiles in a small hash.
        const std::vector<size_t> tileFirst = cubeRuns(topo.leaves, 7);
        const size_t tiles = tileFirst.size() - 1;
        auto tileKey = [](int x, int y, int z) { return nodeKey(x, y, z, 7); };  // of a voxel
        size_t cap = 1;
        while (cap < 2 * tiles + 2)
            cap <<= 1;
        std::vector<uint64_t> keys(cap, ~uint64_t(0));
        std::vector<int32_t> vals(cap, -1);
        auto slot = [&](uint64_t k) { return size_t((k * 0x9E3779B97F4A7C15ull) >> 20) & (cap - 1); };
        for (size_t ti = 0; ti < tiles; ++ti) {
            const int32_t* o = topo.leaves[tileFirst[ti]].origin;
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
                const int32_t* o = topo.leaves[l].origin;
                d[((o[0] >> 3) & 15) + 16 * ((o[1] >> 3) & 15) + 256 * ((o[2] >> 3) & 15)] = int32_t(l);
            }
        });
        tbb::parallel_for(size_t(0), tiles, [&](size_t ti) {
            for (size_t l = tileFirst[ti]; l < tileFirst[ti + 1]; ++l) {
                const int32_t* o = topo.leaves[l].origin;
                for (int k = 0; k < 27; ++k) {
                    const int x = o[0] + 8 * (k % 3 - 1), y = o[1] + 8 * ((k / 3) % 3 - 1), z = o[2] + 8 * (k / 9 - 1);
                    const bool same = (x >> 7) == (o[0] >> 7) && (y >> 7) == (o[1] >> 7) && (z >> 7) == (o[2] >> 7);
                    const int32_t tile = same ? int32_t(ti) : findTile(x, y, z);
                    nb[l][size_t(k)] = tile < 0 ? -1
                                                : dense[size_t(tile) * 4096 + size_t(((x >> 3) & 15) + 16 * ((y >> 3) & 15) +
                                                                                     256 * ((z >> 3) & 15))];
                }
            }
        });
    }
    static const int dirs[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    // Per leaf, its surface voxels in voxel order with the distance (voxels)
    // to the nearest crossing along their edges and that edge's direction.
    struct Edge {
        uint16_t voxel;
        uint8_t dir;
        float t;
        float f;  // F - T at the voxel, kept so that making the point reads no values
    };
    const double tNb = secondsSince(tEdges);
    // Inside bits (F > T) of every leaf: one 64-bit plane (bit x + 8 y) per z.
    std::vector<std::array<uint64_t, 8>> insideBits(n);
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        const uint16_t* v = value.get() + l * kLeafVoxels;
        for (int z = 0; z < 8; ++z) {
            uint64_t m = 0;
            for (int i = 0; i < 64; ++i)
                m |= uint64_t(halfPositive(v[64 * z + i])) << i;
            insideBits[l][size_t(z)] = m;
        }
    });
    const double tBits = secondsSince(tEdges);
    // The voxels of leaf l with a face neighbour on the other side of the
    // surface, per plane z and direction (the order of dirs), by shifting the
    // inside bits; a missing neighbour leaf (no surface within a voxel of it)
    // counts as the same side.  Returns how many voxels have one.
    auto crossings = [&](size_t l, uint64_t across[8][6]) {
        constexpr uint64_t col0 = 0x0101010101010101ull, col7 = col0 << 7, row0 = 0xFFull, row7 = row0 << 56;
        const auto& M = insideBits[l];
        auto plane = [&](int k, int z) -> const uint64_t* {
            const int32_t m = nb[l][size_t(k)];
            return m < 0 ? nullptr : &insideBits[size_t(m)][size_t(z)];
        };
        size_t count = 0;
        for (int z = 0; z < 8; ++z) {
            const uint64_t m = M[size_t(z)];
            const uint64_t* xp = plane(14, z);
            const uint64_t* xm = plane(12, z);
            const uint64_t* yp = plane(16, z);
            const uint64_t* ym = plane(10, z);
            const uint64_t nxp = ((m >> 1) & ~col7) | (xp ? (*xp & col0) << 7 : m & col7);
            const uint64_t nxm = ((m << 1) & ~col0) | (xm ? (*xm & col7) >> 7 : m & col0);
            const uint64_t nyp = (m >> 8) | (yp ? (*yp & row0) << 56 : m & row7);
            const uint64_t nym = (m << 8) | (ym ? (*ym & row7) >> 56 : m & row0);
            const uint64_t* zp = z < 7 ? &M[size_t(z + 1)] : plane(22, 0);
            const uint64_t* zm = z > 0 ? &M[size_t(z - 1)] : plane(4, 7);
            const uint64_t nzp = zp ? *zp : m, nzm = zm ? *zm : m;
            const uint64_t d[6] = {m ^ nxp, m ^ nxm, m ^ nyp, m ^ nym, m ^ nzp, m ^ nzm};
            for (int k = 0; k < 6; ++k)
                across[z][k] = d[k];
            count += size_t(__builtin_popcountll(d[0] | d[1] | d[2] | d[3] | d[4] | d[5]));
        }
        return count;
    };
    // The surface voxels of all leaves in one array, leaf by leaf: counted,
    // then written (one block: no allocation per leaf).
    std::vector<size_t> first(n + 1, 0);
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        uint64_t across[8][6];
        first[l + 1] = crossings(l, across);
    });
    for (size_t l = 0; l < n; ++l)
        first[l + 1] += first[l];
    const size_t np = first[n];
    auto edges = parallelArray<Edge>(np);
    auto queries = parallelArray<SurfaceQuery>(np);
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        const uint16_t* own = value.get() + l * kLeafVoxels;
        // The values were last read long ago (they are out of the caches) and
        // are read here at scattered voxels: fetch the next leaf's ahead.
        if (l + 1 < n)
            for (int i = 0; i < kLeafVoxels; i += 32)
                __builtin_prefetch(own + kLeafVoxels + i);
        uint64_t across[8][6];
        crossings(l, across);
        size_t j = first[l];
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
                    const bool cross = (d[k] >> bit) & 1;  // a neighbour leaf exists where it is set
                    const int nx = x + dirs[k][0], ny = y + dirs[k][1], nz = z + dirs[k][2];
                    const int ox = nx < 0 ? -1 : (nx > 7), oy = ny < 0 ? -1 : (ny > 7), oz = nz < 0 ? -1 : (nz > 7);
                    const int32_t nl = (ox | oy | oz) ? nb[l][size_t((ox + 1) + 3 * (oy + 1) + 9 * (oz + 1))] : int32_t(l);
                    const size_t at = cross ? size_t(nl) * kLeafVoxels + size_t(vox(nx - 8 * ox, ny - 8 * oy, nz - 8 * oz))
                                            : l * kLeafVoxels + size_t(i);
                    const float fu = halfToFloat(value[at]);
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
    const double tEd = secondsSince(tEdges);
    st.timings.neighbours = tNb;
    st.timings.insideBits = tBits - tNb;
    st.timings.signChanges = tEd - tBits;
    t = Clock::now();
    auto surface = parallelArray<SurfaceSample>(np);
    sampler.sampleSurface(topo.leaves, queries.get(), np, h, surface.get());
    queries.reset();
    st.timings.values = valueSeconds;
    st.timings.surfaceSamples = secondsSince(t);
    st.samplingSeconds = valueSeconds + st.timings.surfaceSamples;
    progress("sampling", 1.0);
    topo.pool = {};

    // A surface voxel's point: computed where a tile needs it (tiles share
    // halo leaves, but a point costs less than storing all of them).
    const float invH = float(1.0 / h);
    auto surfacePoint = [&](size_t l, size_t k) {
        const int32_t* o = topo.leaves[l].origin;
        const size_t q = first[l] + k;
        const Edge& ed = edges[q];
        const int i = ed.voxel;
        const float fv = ed.f;
        const bool in = fv > 0.0f;
        const glm::vec3 g(halfToFloat(surface[q].gradient[0]), halfToFloat(surface[q].gradient[1]),
                          halfToFloat(surface[q].gradient[2]));
        const float g2 = glm::dot(g, g);
        // Outward normal: against the gradient (F grows inwards).
        const float inv = g2 > 0.0f ? 1.0f / std::sqrt(g2) : 0.0f;
        glm::vec3 nrm = -inv * g;
        float dist = g2 > 0.0f ? std::abs(fv) * inv * invH : INFINITY;
        if (!(dist <= ed.t)) {  // the crossing along an edge bounds the distance
            dist = ed.t;
            if (!(g2 > 0.0f))
                nrm = (in ? 1.0f : -1.0f) *
                      glm::vec3(float(dirs[ed.dir][0]), float(dirs[ed.dir][1]), float(dirs[ed.dir][2]));
        }
        // Closest point: from outside, inwards along -n; from inside, outwards.
        const glm::vec3 cp = glm::vec3(float(o[0] + (i & 7)), float(o[1] + ((i >> 3) & 7)),
                                       float(o[2] + (i >> 6))) + (in ? dist : -dist) * nrm;
        SurfacePoint sp;
        for (int c = 0; c < 3; ++c) {
            sp.p[c] = cp[c];
            sp.n[c] = nrm[c];
            sp.rgb[c] = surface[q].color[c];
        }
        return sp;
    };
    st.surfacePoints = np;

    // 4 and 5, tile by tile (64^3 voxels: octants of the topology's tiles,
    // whose leaves are contiguous in its depth-first order): propagation over
    // the tile's leaves and a one-leaf halo of their neighbours (a band
    // voxel's nearest point is within halfWidth + 2 voxels, well inside a
    // leaf), then the tile's grid leaves.  A 64^3 tile's state stays in the
    // caches through the twelve sweeps (128^3 tiles: 1.5 times slower).
    t = Clock::now();
    const std::vector<size_t> tileStart = cubeRuns(topo.leaves, 6);
    const float limit2 = float((W + 2.0) * (W + 2.0));
    const bool uniform = program.uniformColor().has_value();
    const glm::dvec3 uniformRgb = program.uniformColor().value_or(glm::dvec3(0.0));
    std::vector<openvdb::FloatTree::LeafNodeType*> sLeaves(n, nullptr);
    std::vector<openvdb::Vec3fTree::LeafNodeType*> cLeaves(n, nullptr);
    std::vector<size_t> activeCount(n, 0);
    std::atomic<size_t> axisNs[3] = {0, 0, 0}, haloNs{0}, pointsNs{0};
    std::atomic<size_t> tilesDone{0}, sweepNs{0}, leavesNs{0}, localLeaves{0};
    struct Scratch {
        std::vector<int32_t> leaves, src;  // src: each voxel's nearest surface point (tile-local index)
        std::vector<float> pos[3];         // its position: the sweeps carry it along without lookups
        std::vector<std::array<uint8_t, 3>> rgb;  // the colours of the tile's points (with its halo's; 0: none)
        std::vector<float> nrm[3];         // their normals, as planes (gathered by index)
        std::vector<float> turned;         // the x-sweeps' transposed chains
        Chains rows[3];                    // the chains along each axis
        std::vector<int> table;            // (building them)
    };
    tbb::enumerable_thread_specific<Scratch> scratch;
    tbb::parallel_for(size_t(0), tileStart.size() - 1, [&](size_t tile) {
        Scratch& S = scratch.local();
        const auto tq0 = Clock::now();
        const size_t t0 = tileStart[tile], t1 = tileStart[tile + 1];
        // The tile's leaves, then its halo.
        S.leaves.resize(t1 - t0);
        std::iota(S.leaves.begin(), S.leaves.end(), int32_t(t0));
        // A neighbour without surface points only carries points from two
        // leaves away, beyond a band voxel's reach (halfWidth + 2 voxels < 8):
        // only neighbours with points join the halo.
        for (size_t l = t0; l < t1; ++l)
            for (int32_t m : nb[l])
                if (m >= 0 && (size_t(m) < t0 || size_t(m) >= t1) && first[size_t(m) + 1] > first[size_t(m)])
                    S.leaves.push_back(m);
        std::sort(S.leaves.begin() + long(t1 - t0), S.leaves.end());
        S.leaves.erase(std::unique(S.leaves.begin() + long(t1 - t0), S.leaves.end()), S.leaves.end());
        const size_t nl = S.leaves.size();
        localLeaves += nl;
        const auto tq1 = Clock::now();
        S.src.resize(nl * kLeafVoxels);
        for (auto& p : S.pos)
            p.resize(nl * kLeafVoxels);
        std::vector<LeafJob> local(nl);
        size_t count = 1;  // point 0: none
        for (size_t k = 0; k < nl; ++k)
            count += first[size_t(S.leaves[k]) + 1] - first[size_t(S.leaves[k])];
        if (!uniform)  // a model of one colour needs no colours per point
            S.rgb.resize(count);
        for (auto& v : S.nrm) {
            v.resize(count);
            v[0] = 0.0f;
        }
        int32_t next = 1;
        for (size_t k = 0; k < nl; ++k) {
            const size_t l = size_t(S.leaves[k]);
            local[k] = topo.leaves[l];
            // The leaf's state, then its points (in the caches: leaf by leaf).
            // Voxels without a point hold point 0 (none, zero normal) placed
            // infinitely far away, so that the sweeps need no branches.
            const size_t lb = k * kLeafVoxels;
            std::fill_n(S.src.begin() + long(lb), kLeafVoxels, 0);
            for (auto& p : S.pos)
                std::fill_n(p.begin() + long(lb), kLeafVoxels, 1e15f);
            for (size_t e = 0; e < first[l + 1] - first[l]; ++e, ++next) {
                const SurfacePoint sp = surfacePoint(l, e);
                const size_t at = k * kLeafVoxels + size_t(edges[first[l] + e].voxel);
                S.src[at] = next;
                if (!uniform)
                    S.rgb[size_t(next)] = {sp.rgb[0], sp.rgb[1], sp.rgb[2]};
                for (int c = 0; c < 3; ++c) {
                    S.nrm[c][size_t(next)] = sp.n[c];
                    S.pos[c][at] = sp.p[c];
                }
            }
        }
        const auto tSweep = Clock::now();
        haloNs += size_t(std::chrono::duration<double>(tq1 - tq0).count() * 1e9);
        pointsNs += size_t(std::chrono::duration<double>(tSweep - tq1).count() * 1e9);
        // Sweeps along each axis in both directions, each voxel offered its
        // predecessor's surface point; two rounds (the second repairs the
        // paths the first could not take: max error 0.25 -> 0.1 voxel,
        // tests/test_bake.cpp).
        float* const pos[3] = {S.pos[0].data(), S.pos[1].data(), S.pos[2].data()};
        // (Both rounds must run over the halo too: without it in the second,
        // the far error of a capsule grows from 0.11 to 0.46 voxel.)
        for (int axis = 0; axis < 3; ++axis)
            buildChains(local, axis, S.table, S.rows[axis]);
        for (int pass = 0; pass < 6; ++pass) {
            const int axis = pass % 3;
            const auto ta = Clock::now();
            sweepAxis(S.rows[axis], local, axis, S.src.data(), pos, limit2, S.turned);
            axisNs[axis] += size_t(secondsSince(ta) * 1e9);
        }
        sweepNs += size_t(secondsSince(tSweep) * 1e9);
        const auto tLeaves = Clock::now();
        // The tile's grid leaves, written straight into their buffers.
        for (size_t k = 0; k < t1 - t0; ++k) {
            const size_t l = t0 + k;
            const int32_t* o = topo.leaves[l].origin;
            float sd[kLeafVoxels];
            uint8_t on[kLeafVoxels];
            const int32_t* src = S.src.data() + k * kLeafVoxels;
            const size_t at = k * kLeafVoxels;
            const int active = leafDistances(o, value.get() + l * kLeafVoxels, S.pos[0].data() + at,
                                             S.pos[1].data() + at, S.pos[2].data() + at, src, S.nrm[0].data(),
                                             S.nrm[1].data(), S.nrm[2].data(), float(h), background, sd, on);
            activeCount[l] = size_t(active);
            if (!active)
                continue;
            const openvdb::Coord origin(o[0], o[1], o[2]);
            // (PartialCreate: the buffer is allocated by data() and not filled:
            // every value is written below.)
            auto* sl = new openvdb::FloatTree::LeafNodeType(openvdb::PartialCreate(), origin, background, false);
            auto* cl = uniform ? nullptr : new openvdb::Vec3fTree::LeafNodeType(origin, openvdb::Vec3f(0.0f), false);
            float* sv = sl->buffer().data();
            openvdb::Vec3f* cv = cl ? cl->buffer().data() : nullptr;
            // VDB leaves index x slowest: offset = 64 x + 8 y + z, so mask
            // word x holds bit 8 y + z.
            // (x innermost and unrolled: the eight words stay in registers.)
            uint64_t words[8] = {};
            for (int yz = 0; yz < 64; ++yz) {
                const int base = 8 * (yz >> 3) + 64 * (yz & 7);  // voxel (0, y, z)
#pragma GCC unroll 8
                for (int x = 0; x < 8; ++x) {
                    sv[64 * x + yz] = sd[base + x];
                    words[x] |= uint64_t(on[base + x]) << yz;
                }
            }
            if (cl)
                for (int i = 0; i < kLeafVoxels; ++i)
                    if (on[i]) {
                        const uint8_t* rgb = S.rgb[size_t(src[i])].data();
                        cv[64 * (i & 7) + 8 * ((i >> 3) & 7) + (i >> 6)] = openvdb::Vec3f(rgb[0], rgb[1], rgb[2]) / 255.0f;
                    }
            for (int x = 0; x < 8; ++x) {
                sl->getValueMask().template getWord<uint64_t>(openvdb::Index(x)) = words[x];
                if (cl)
                    cl->getValueMask().template getWord<uint64_t>(openvdb::Index(x)) = words[x];
            }
            sLeaves[l] = sl;
            cLeaves[l] = cl;
        }
        leavesNs += size_t(secondsSince(tLeaves) * 1e9);
        progress("assembly", double(++tilesDone) / double(tileStart.size() - 1));
    });
    const auto tTree = Clock::now();
    BakeTimings& tm = st.timings;
    tm.propagation = secondsSince(t);
    tm.halos = double(haloNs) * 1e-9;
    tm.points = double(pointsNs) * 1e-9;
    tm.sweeps = double(sweepNs) * 1e-9;
    for (int k = 0; k < 3; ++k)
        tm.sweepAxis[k] = double(axisNs[k]) * 1e-9;
    tm.leaves = double(leavesNs) * 1e-9;
    tm.tiles = tileStart.size() - 1;
    tm.tileLeaves = localLeaves;
    value.reset();
    edges.reset();
    surface.reset();
    const double tFree = secondsSince(tTree);
    // A model of one colour has that colour wherever the surface is: its Cd
    // grid is that colour as the background, without voxels (on the 20k
    // benchmark tree the voxels would take 1.1 GB and a sixth of the time).
    createGrids(out, h, background,
                uniform ? openvdb::Vec3f(float(uniformRgb.x), float(uniformRgb.y), float(uniformRgb.z))
                        : openvdb::Vec3f(0.0f));
    // Through accessors: consecutive leaves mostly share their internal
    // nodes (depth-first order), which the accessors keep at hand.
    openvdb::FloatGrid::Accessor sAcc = out.surface->getAccessor();
    openvdb::Vec3fGrid::Accessor cAcc = out.color->getAccessor();
    for (size_t l = 0; l < n; ++l)
        if (sLeaves[l]) {
            sAcc.addLeaf(sLeaves[l]);
            if (cLeaves[l])
                cAcc.addLeaf(cLeaves[l]);
            ++st.activeLeaves;
            st.activeVoxels += activeCount[l];
        }
    // The leaves' inactive voxels already hold +-background by the field's
    // sign: only the tiles above them need the flood fill (minLevel 1; at the
    // leaf level it would replace those signs by a scan-line guess).
    const double tAdd = secondsSince(tTree);
    openvdb::tools::signedFloodFill(out.surface->tree(), true, 1, 1);
    tm.freeing = tFree;
    tm.tree = tAdd - tFree;
    tm.floodFill = secondsSince(tTree) - tAdd;
    if (opt.fog)
        addFog(out);
    st.seconds = secondsSince(start);
    st.assemblySeconds = st.seconds - st.topologySeconds - st.samplingSeconds;
    progress("assembly", 1.0);
    return out;
}

}  // namespace cambium
