// cambium — bake stage 4: propagation.  Each tile's surface points swept
// through its leaves and a halo (bake/sweep.inc), then its signed distances
// and grid leaves.
#include "bake/stages.h"

#include "core/clock.h"

#include "cb_primitives.h"

#include <glm/glm.hpp>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <numeric>
#include <optional>

namespace cambium {

namespace {

/// A surface voxel's point from its edge and the sampler's answer: the
/// sampler's Newton step (cb_surface_step) and a second from where it landed,
/// with the gradient there for the normal.  Where F is far from linear
/// across a voxel (a twig a voxel or two thick, whose falloff spans two to
/// four voxels; the fillets of blends) the first step alone is off by up to
/// a fifth of a voxel, the second by a fiftieth; and the gradient at the
/// landing point is the surface's normal, where the voxel's may lean (in a
/// blend the gradient turns along its way to the surface).
/// |grad F| near a skeletal primitive's surface also tells its radius (the
/// falloff's argument grows by xT over it: radius = xT |w'(xT)| / |grad F|,
/// sigma 1): the surface's radius of curvature across it, which decides how
/// far its tangent plane holds (leafDistances: within 0.1 voxel up to a
/// lateral offset of sqrt(0.2 rho); never beyond 1.5 voxels, as for flat
/// surfaces).  On a convolution segment it comes out about half the radius:
/// its planes give way a little early.
SurfacePoint surfacePoint(const SurfaceEdge& ed, const SurfaceSample& sample, float invH,
                          float radiusScale)
{
    const bool inside = ed.f > 0.0f;
    const glm::vec3 g(halfToFloat(sample.gradient[0]), halfToFloat(sample.gradient[1]),
                      halfToFloat(sample.gradient[2]));
    const float g2 = glm::dot(g, g);
    // Outward normal: against the gradient (F grows inwards).
    const float inv = g2 > 0.0f ? 1.0f / std::sqrt(g2) : 0.0f;
    glm::vec3 nrm = -inv * g;
    // The second step, bounded like the first (voxels).
    const glm::vec3 landed(halfToFloat(sample.step[0]), halfToFloat(sample.step[1]),
                           halfToFloat(sample.step[2]));
    const float r = halfToFloat(sample.value);
    const float second = std::min(std::abs(r) * inv * invH, float(kSurfaceReach));
    glm::vec3 at = landed + (r > 0.0f ? second : -second) * nrm;
    // The crossing along an edge bounds the voxel's distance: a point whose
    // tangent plane lies further (a step gone astray), or one without a
    // gradient (outside every primitive's support, next to a surface made by
    // a neighbour's), gives way to one at that distance along the normal.
    if (!(g2 > 0.0f && std::abs(glm::dot(at, nrm)) <= ed.t)) {
        if (!(g2 > 0.0f)) {
            const int* dir = kFaceDirections[ed.dir];
            nrm = (inside ? 1.0f : -1.0f) * glm::vec3(float(dir[0]), float(dir[1]), float(dir[2]));
        }
        // From outside the point lies inwards, along -n; from inside, outwards.
        at = (inside ? ed.t : -ed.t) * nrm;
    }
    const float bend = radiusScale > 0.0f && g2 > 0.0f
                           ? std::min(1.5f, std::sqrt(0.2f * radiusScale * inv))
                           : 1.5f;
    SurfacePoint sp;
    for (int c = 0; c < 3; ++c) {
        sp.n[c] = floatToHalf(nrm[c]);
        sp.at[c] = floatToHalf(at[c]);
        sp.rgb[c] = sample.color[c];
    }
    sp.voxel = ed.voxel;
    sp.bend = floatToHalf(bend);
    return sp;
}

/// A tile's scratch vector holds at least n (what it held beyond a smaller
/// tile's is overwritten before it is read): resize would clear the elements
/// past a smaller tile's size again for every tile (3 % of the bake's time).
template <class V>
void growTo(V& v, size_t n)
{
    if (v.size() < n)
        v.resize(n);
}

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

void sweepAxis(const Chains& rows, const std::vector<LeafJob>& local, int axis, int32_t* srcAll,
               float* const pos[3], float limit2, std::vector<float>& turned)
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
void sweepAxis(const Chains& rows, const std::vector<LeafJob>& local, int axis, int32_t* srcAll,
               float* const pos[3], float limit2, std::vector<float>& turned)
{
    static const bool avx512 = __builtin_cpu_supports("x86-64-v4");
    if (avx512)
        sweepAxis16(rows, local, axis, srcAll, pos, limit2, turned);
    else
        sweepAxis8(rows, local, axis, srcAll, pos, limit2, turned);
}
#endif

/// Signed distances (world units) of one leaf's voxels (order x + 8 y + 64 z;
/// the sign from its inside bits, so that its values need not be held until
/// its slab is propagated) from their nearest surface points p (index space, 1e15 where none) with
/// unit normals (nx, ny, nz)[src], and whether each lies in the band.  The tangent plane's
/// distance corrects for the spacing of the surface points (about a voxel)
/// where the surface is smooth: there the nearest point lies near the foot of
/// the perpendicular.  A lateral offset of several voxels means a crease (CSG,
/// a scar's rim) whose nearest point is the point itself, and on a surface
/// curved as tightly as a thin twig the plane falls short by l^2 / 2 rho at
/// lateral offset l: the Euclidean distance takes over from bend[src] (1.5
/// voxels, less where the point's radius of curvature rho is small) to a voxel
/// further; it also takes over where the plane disagrees with the field's
/// sign.  Branch-free, so that it
/// runs as vectors (clones chosen at run time, as for the sweeps; the file is
/// compiled without errno and trapping math, which would keep it scalar).
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"))) int leafDistances(
    const int32_t* origin, const uint64_t* __restrict inside, const float* __restrict px,
    const float* __restrict py, const float* __restrict pz, const int32_t* __restrict src,
    const float* __restrict nx, const float* __restrict ny, const float* __restrict nz,
    const float* __restrict bend, float h, float background, float* __restrict sd,
    uint8_t* __restrict on)
{
    const float ox = float(origin[0]), oy = float(origin[1]), oz = float(origin[2]);
    float signs[kLeafVoxels];  // F - T > 0: inside, negative
    for (int w = 0; w < 8; ++w)
        for (int b = 0; b < 64; ++b)
            signs[64 * w + b] = (inside[w] >> b) & 1u ? -1.0f : 1.0f;
    int active = 0;
    for (int i = 0; i < kLeafVoxels; ++i) {
        const float sign = signs[i];
        const float dx = ox + float(i & 7) - px[i], dy = oy + float((i >> 3) & 7) - py[i],
                    dz = oz + float(i >> 6) - pz[i];
        const float e2 = dx * dx + dy * dy + dz * dz;
        const int32_t j = src[i];  // gathered: the point's normal
        const float plane = dx * nx[j] + dy * ny[j] + dz * nz[j];
        const float euclid = std::sqrt(e2);
        const float l2 = e2 - plane * plane;
        const float lateral = std::sqrt(l2 > 0.0f ? l2 : 0.0f);
        const float b0 = lateral - bend[j], b1 = b0 > 0.0f ? b0 : 0.0f, b = b1 < 1.0f ? b1 : 1.0f;
        const float flat = std::fabs(plane);
        const float blended = flat + (euclid - flat) * (b * b * (3.0f - 2.0f * b));
        const float mag = (plane < 0.0f) != (sign < 0.0f) ? euclid : blended;
        // (inside strictly negative, as OpenVDB's tools take it: a voxel on
        // the surface inside would be -0.0, outside for volumeToMesh)
        const float v = sign < 0.0f ? std::min(-mag * h, -1e-30f) : mag * h;
        const bool in = std::fabs(v) < background;  // false where there is no point (1e15)
        sd[i] = in ? v : sign * background;
        on[i] = in;
        active += in;
    }
    return active;
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
    const size_t nu = size_t(hi[axis] - lo[axis] + 1), nv = size_t(hi[a] - lo[a] + 1),
                 nw = size_t(hi[b] - lo[b] + 1);
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

/// A tile's working state, one per thread, reused from tile to tile.
struct TileScratch {
    std::vector<int32_t> leaves, src;  // src: each voxel's nearest surface point (tile-local index)
    std::vector<float> pos[3];         // its position: the sweeps carry it along without lookups
    std::vector<std::array<uint8_t, 3>>
        rgb;                     // the colours of the tile's points (with its halo's; 0: none)
    std::vector<float> nrm[3];   // their normals, as planes (gathered by index)
    std::vector<float> bend;     // and where their planes give way
    std::vector<float> turned;   // the x-sweeps' transposed chains
    std::vector<LeafJob> local;  // the tile's leaves, then its halo
    Chains rows[3];              // the chains along each axis
    std::vector<int> table;      // (building them)
    // Packing: leaves to serialise from, and this thread's blocks of bytes.
    std::unique_ptr<openvdb::FloatTree::LeafNodeType> packSurface;
    std::unique_ptr<openvdb::Vec3fTree::LeafNodeType> packColor;
    std::optional<PackedLeaves::Block> surfaceBlock, colorBlock;
};

/// Propagation over the tiles (the topology's 64^3 cubes, whose leaves are
/// contiguous in its order): each tile's leaves
/// and a one-leaf halo of their neighbours (a band voxel's nearest point is
/// within halfWidth + 2 voxels, well inside a leaf), then the tile's grid
/// leaves.  A 64^3 tile's state stays in the caches through the twelve
/// sweeps (128^3 tiles: 1.5 times slower).
class Propagation {
public:
    Propagation(const PropagationInput& in, BandLeaves& out)
        : in_(in),
          out_(out),
          state_(in.state),
          limit2_(float((in.halfWidth + 2.0) * (in.halfWidth + 2.0)))
    {
    }

    void tile(size_t t0, size_t t1, TileScratch& S)
    {
        const auto tq0 = Clock::now();
        gatherLeaves(t0, t1, S);
        const auto tq1 = Clock::now();
        loadPoints(S);
        const auto tSweep = Clock::now();
        haloNs += size_t(std::chrono::duration<double>(tq1 - tq0).count() * 1e9);
        pointsNs += size_t(std::chrono::duration<double>(tSweep - tq1).count() * 1e9);
        sweep(S);
        sweepNs += size_t(secondsSince(tSweep) * 1e9);
        const auto tLeaves = Clock::now();
        writeLeaves(t0, t1, S);
        leavesNs += size_t(secondsSince(tLeaves) * 1e9);
    }

    std::atomic<size_t> axisNs[3] = {0, 0, 0}, haloNs{0}, pointsNs{0}, sweepNs{0}, leavesNs{0},
                        localLeaves{0};

private:
    /// The tile's leaves [t0, t1), then its halo.
    void gatherLeaves(size_t t0, size_t t1, TileScratch& S)
    {
        S.leaves.resize(t1 - t0);
        std::iota(S.leaves.begin(), S.leaves.end(), int32_t(t0));
        // A neighbour without surface points only carries points from two
        // leaves away, beyond a band voxel's reach (halfWidth + 2 voxels < 8):
        // only neighbours with points join the halo.
        for (size_t l = t0; l < t1; ++l)
            for (int32_t m : in_.nb[l])
                if (m >= 0 && (size_t(m) < t0 || size_t(m) >= t1) &&
                    state_.surfaceVoxels(size_t(m)) > 0)
                    S.leaves.push_back(m);
        std::sort(S.leaves.begin() + long(t1 - t0), S.leaves.end());
        S.leaves.erase(std::unique(S.leaves.begin() + long(t1 - t0), S.leaves.end()),
                       S.leaves.end());
        localLeaves += S.leaves.size();
    }

    /// Every local voxel's state and the local leaves' surface points.
    void loadPoints(TileScratch& S) const
    {
        const size_t nl = S.leaves.size();
        growTo(S.src, nl * kLeafVoxels);
        for (auto& p : S.pos)
            growTo(p, nl * kLeafVoxels);
        S.local.resize(nl);
        size_t count = 1;  // point 0: none
        for (size_t k = 0; k < nl; ++k)
            count += state_.surfaceVoxels(size_t(S.leaves[k]));
        if (!in_.uniformColor)  // a model of one colour needs no colours per point
            growTo(S.rgb, count);
        for (auto& v : S.nrm) {
            growTo(v, count);
            v[0] = 0.0f;
        }
        growTo(S.bend, count);
        S.bend[0] = 1.5f;
        int32_t next = 1;
        for (size_t k = 0; k < nl; ++k) {
            const size_t l = size_t(S.leaves[k]);
            S.local[k] = in_.leaves[l];
            // The leaf's state, then its points (in the caches: leaf by leaf).
            // Voxels without a point hold point 0 (none, zero normal) placed
            // infinitely far away, so that the sweeps need no branches.
            const size_t lb = k * kLeafVoxels;
            std::fill_n(S.src.begin() + long(lb), kLeafVoxels, 0);
            for (auto& p : S.pos)
                std::fill_n(p.begin() + long(lb), kLeafVoxels, 1e15f);
            const int32_t* o = in_.leaves[l].origin;
            const SurfacePoint* points = state_.point[l];
            for (size_t e = 0; e < state_.surfaceVoxels(l); ++e, ++next) {
                const SurfacePoint& sp = points[e];
                const int i = sp.voxel;
                const size_t at = lb + size_t(i);
                S.src[at] = next;
                if (!in_.uniformColor)
                    S.rgb[size_t(next)] = {sp.rgb[0], sp.rgb[1], sp.rgb[2]};
                S.bend[size_t(next)] = halfToFloat(sp.bend);
                const float v[3] = {float(o[0] + (i & 7)), float(o[1] + ((i >> 3) & 7)),
                                    float(o[2] + (i >> 6))};
                for (int c = 0; c < 3; ++c) {
                    S.nrm[c][size_t(next)] = halfToFloat(sp.n[c]);
                    S.pos[c][at] = v[c] + halfToFloat(sp.at[c]);
                }
            }
        }
    }

    /// Sweeps along each axis in both directions, each voxel offered its
    /// predecessor's surface point; two rounds (the second repairs the paths
    /// the first could not take: max error 0.25 -> 0.1 voxel,
    /// tests/test_bake.cpp).  (Both rounds must run over the halo too:
    /// without it in the second, the far error of a capsule grows from 0.11
    /// to 0.46 voxel.)
    void sweep(TileScratch& S)
    {
        float* const pos[3] = {S.pos[0].data(), S.pos[1].data(), S.pos[2].data()};
        for (int axis = 0; axis < 3; ++axis)
            buildChains(S.local, axis, S.table, S.rows[axis]);
        for (int pass = 0; pass < 6; ++pass) {
            const int axis = pass % 3;
            const auto ta = Clock::now();
            sweepAxis(S.rows[axis], S.local, axis, S.src.data(), pos, limit2_, S.turned);
            axisNs[axis] += size_t(secondsSince(ta) * 1e9);
        }
    }

    /// The tile's grid leaves, written straight into their buffers.
    void writeLeaves(size_t t0, size_t t1, TileScratch& S)
    {
        const float background = in_.background;
        const bool pack = out_.surfacePack != nullptr;
        if (pack && !S.packSurface) {
            // Packing: the values go into leaves of this thread's, to be serialised.
            S.packSurface = std::make_unique<openvdb::FloatTree::LeafNodeType>(openvdb::Coord(),
                                                                               background, false);
            S.packColor = std::make_unique<openvdb::Vec3fTree::LeafNodeType>(
                openvdb::Coord(), openvdb::Vec3f(0.0f), false);
            S.surfaceBlock.emplace(*out_.surfacePack);
            if (out_.colorPack)
                S.colorBlock.emplace(*out_.colorPack);
        }
        for (size_t k = 0; k < t1 - t0; ++k) {
            const size_t l = t0 + k;
            const int32_t* o = in_.leaves[l].origin;
            float sd[kLeafVoxels];
            uint8_t on[kLeafVoxels];
            const int32_t* src = S.src.data() + k * kLeafVoxels;
            const size_t at = k * kLeafVoxels;
            const int active = leafDistances(
                o, state_.inside[l].data(), S.pos[0].data() + at, S.pos[1].data() + at,
                S.pos[2].data() + at, src, S.nrm[0].data(), S.nrm[1].data(), S.nrm[2].data(),
                S.bend.data(), float(in_.voxelSize), background, sd, on);
            out_.active[l] = size_t(active);
            if (!active)
                continue;
            const openvdb::Coord origin(o[0], o[1], o[2]);
            openvdb::FloatTree::LeafNodeType* sl;
            openvdb::Vec3fTree::LeafNodeType* cl;
            if (pack) {
                sl = S.packSurface.get();
                cl = in_.uniformColor ? nullptr : S.packColor.get();
                if (cl)
                    cl->buffer().fill(openvdb::Vec3f(0.0f));
            } else {
                // (PartialCreate: the buffer is allocated by data() and not
                // filled: every value is written below.)
                sl = new openvdb::FloatTree::LeafNodeType(openvdb::PartialCreate(), origin,
                                                          background, false);
                cl = in_.uniformColor ? nullptr
                                      : new openvdb::Vec3fTree::LeafNodeType(
                                            origin, openvdb::Vec3f(0.0f), false);
            }
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
            // Cd: on the band's voxels, or those of the shell only (and then
            // perhaps one tile or nothing).
            uint64_t colourWords[8] = {};
            if (cl) {
                InsideBits shell;
                const bool onShell = in_.colour == ColourExtent::Shell;
                if (onShell) {
                    const InsideBits* around[27];
                    for (int s = 0; s < 27; ++s) {
                        const int32_t m = in_.nb[l][size_t(s)];
                        around[s] = m >= 0 ? &state_.inside[size_t(m)] : nullptr;
                    }
                    around[neighbourSlot(0, 0, 0)] = &state_.inside[l];
                    shell = colourShell(around);
                }
                for (int i = 0; i < kLeafVoxels; ++i)
                    if (on[i] && (!onShell || ((shell[size_t(i >> 6)] >> (i & 63)) & 1u))) {
                        const uint8_t* rgb = S.rgb[size_t(src[i])].data();
                        const int x = i & 7, yz = i >> 3;  // (VDB order: 64 x + 8 y + z)
                        cv[64 * x + 8 * (yz & 7) + (yz >> 3)] =
                            openvdb::Vec3f(rgb[0], rgb[1], rgb[2]) / 255.0f;
                        colourWords[x] |= uint64_t(1) << (8 * (yz & 7) + (yz >> 3));
                    }
            }
            for (int x = 0; x < 8; ++x) {
                sl->getValueMask().template getWord<uint64_t>(openvdb::Index(x)) = words[x];
                if (cl)
                    cl->getValueMask().template getWord<uint64_t>(openvdb::Index(x)) =
                        in_.colour == ColourExtent::Shell ? colourWords[x] : words[x];
            }
            if (cl && in_.colour == ColourExtent::Shell) {
                // A leaf of one colour is a tile of it; one without colour, none.
                std::optional<openvdb::Vec3f> one;
                if (cl->isEmpty() || (one = nearlyUniform(*cl))) {
                    out_.colorTile[l] = one;
                    if (!pack)
                        delete cl;
                    cl = nullptr;
                }
            }
            if (!pack) {
                out_.surface[l] = sl;
                out_.color[l] = cl;
                continue;
            }
            // Packed: the bytes for the file, and a leaf of the value mask
            // only (no buffer) that names its slot.
            const uint32_t slot = uint32_t(l);
            S.surfaceBlock->add(slot, *sl);
            out_.surface[l] = maskLeaf(*sl, origin, background, slot);
            if (cl) {
                S.colorBlock->add(slot, *cl);
                out_.color[l] = maskLeaf(*cl, origin, openvdb::Vec3f(0.0f), slot);
            }
            out_.ends[l] = leafEnds(sv[0], sv[kLeafVoxels - 1]);
        }
        if (pack)
            S.surfaceBlock->keep();
        if (pack && S.colorBlock)
            S.colorBlock->keep();
    }

    const PropagationInput& in_;
    BandLeaves& out_;
    const LeafState& state_;
    const float limit2_;
};

}  // namespace

void makeSurfacePoints(const PropagationInput& in, LeafList list, SurfaceVoxels& sv,
                       LeafState& state)
{
    sv.points = parallelArray<SurfacePoint>(sv.count);
    const float invH = float(1.0 / in.voxelSize);
    // A skeletal primitive's radius (voxels) is this over |grad F| (see surfacePoint).
    float radiusScale = 0.0f;
    if (in.threshold > 0.0 && in.threshold < 1.0) {
        double dw;
        cb_wyvill(in.xT, &dw);
        radiusScale = float(in.xT * std::abs(dw)) * invH;
    }
    tbb::parallel_for(size_t(0), list.size, [&](size_t k) {
        for (size_t j = sv.first[k]; j < sv.first[k + 1]; ++j)
            sv.points[j] = surfacePoint(sv.edges[j], sv.samples[j], invH, radiusScale);
        state.point[list.index[k]] = sv.points.get() + sv.first[k];
    });
    sv.edges.reset();
    sv.samples.reset();
}

void propagate(const PropagationInput& in, size_t begin, size_t end, BandLeaves& out,
               BakeTimings& timings)
{
    const auto t = Clock::now();
    const std::vector<size_t> tileStart = cubeRuns(in.leaves, 6, begin, end);
    const size_t tiles = tileStart.size() - 1;
    Propagation work(in, out);
    tbb::enumerable_thread_specific<TileScratch> scratch;
    tbb::parallel_for(size_t(0), tiles, [&](size_t tile) {
        work.tile(tileStart[tile], tileStart[tile + 1], scratch.local());
    });
    timings.propagation += secondsSince(t);
    timings.halos += double(work.haloNs) * 1e-9;
    timings.points += double(work.pointsNs) * 1e-9;
    timings.sweeps += double(work.sweepNs) * 1e-9;
    for (int k = 0; k < 3; ++k)
        timings.sweepAxis[k] += double(work.axisNs[k]) * 1e-9;
    timings.leaves += double(work.leavesNs) * 1e-9;
    timings.tiles += tiles;
    timings.tileLeaves += work.localLeaves;
}

}  // namespace cambium
