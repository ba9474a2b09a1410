// cambium — polygonising a baked level set and writing the mesh.
#include "use/mesh.h"

#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "core/system.h"
#include "io/vdb.h"
#include "use/world_sampler.h"
#include "core/clock.h"

#include <fmt/format.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <functional>

#include <algorithm>
#include <limits>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <cstdio>
#include <iterator>
#include <ostream>
#include <memory>
#include <optional>

namespace cambium {

namespace {

/// Whether a transform only scales and moves along the axes.
bool scalesAndMovesOnly(const openvdb::math::Transform& xf)
{
    using namespace openvdb::math;
    const MapBase& m = *xf.baseMap();
    return m.isType<ScaleMap>() || m.isType<ScaleTranslateMap>() || m.isType<UniformScaleMap>() ||
           m.isType<UniformScaleTranslateMap>() || m.isType<TranslationMap>();
}

/// Asks for `bytes` from `p` to be brought into the cache.
void prefetch(const void* p, size_t bytes)
{
    const char* c = static_cast<const char*>(p);
    for (size_t b = 0; b < bytes; b += 64)
        __builtin_prefetch(c + b);
}

/// A grid's values in small blocks of voxels around points that come leaf
/// by leaf (as volumeToMesh's do), read from the buffers of the leaves: the
/// 3 x 3 x 3 leaves around the point's own, each looked up once while the
/// points stay in its leaf.  A voxel of no leaf (a tile, the background) is
/// read through the accessor.
template <class GridT>
class LeafNeighbourhood {
public:
    using ValueT = typename GridT::ValueType;
    using LeafT = typename GridT::TreeType::LeafNodeType;

    explicit LeafNeighbourhood(const GridT& grid) : accessor_(grid.getConstAccessor()) {}

    /// The N^3 voxels from `lo` into `out`; `lo` is within two voxels of
    /// `near` (whose leaf is the neighbourhood's centre) and N at most 3.
    template <int N>
    void gather(const openvdb::Coord& near, const openvdb::Coord& lo, ValueT (&out)[N][N][N])
    {
        static_assert(N <= 3, "a block reaches at most five voxels from its point");
        const openvdb::Coord centre(near[0] & ~7, near[1] & ~7, near[2] & ~7);
        if (probed_ == 0 || centre != centre_) {
            centre_ = centre;
            probed_ = 0;
        }
        if (((lo[0] & 7) <= 8 - N) && ((lo[1] & 7) <= 8 - N) && ((lo[2] & 7) <= 8 - N) &&
            (lo[0] & ~7) == centre_[0] && (lo[1] & ~7) == centre_[1] &&
            (lo[2] & ~7) == centre_[2]) {
            // (all in the centre's leaf: most blocks)
            constexpr int kCentre = 13;
            if (!(probed_ & (1u << kCentre))) {
                const LeafT* l = accessor_.probeConstLeaf(lo);
                values_[kCentre] = l ? l->buffer().data() : nullptr;
                probed_ |= 1u << kCentre;
            }
            if (const ValueT* v = values_[kCentre]) {
                const ValueT* base = v + LeafT::coordToOffset(lo);
                for (int a = 0; a < N; ++a)
                    for (int b = 0; b < N; ++b)
                        for (int c = 0; c < N; ++c)
                            out[a][b][c] = base[a * 64 + b * 8 + c];
                return;
            }
        }
        int leaf[3][N], offset[3][N];
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < N; ++a) {
                const int v = lo[k] + a;
                leaf[k][a] = ((v - centre_[k]) >> 3) + 1;  // 0, 1 or 2
                offset[k][a] = v & 7;
            }
        for (int a = 0; a < N; ++a)
            for (int b = 0; b < N; ++b)
                for (int c = 0; c < N; ++c) {
                    const int i = leaf[0][a] * 9 + leaf[1][b] * 3 + leaf[2][c];
                    if (!(probed_ & (1u << i))) {
                        const LeafT* l = accessor_.probeConstLeaf(lo.offsetBy(a, b, c));
                        values_[i] = l ? l->buffer().data() : nullptr;
                        probed_ |= 1u << i;
                    }
                    out[a][b][c] =
                        values_[i]
                            ? values_[i][(offset[0][a] << 6) | (offset[1][b] << 3) | offset[2][c]]
                            : accessor_.getValue(lo.offsetBy(a, b, c));
                }
    }

    /// What BoxSampler gives at index point `index`, to the bit.
    ValueT trilinear(const openvdb::Vec3d& index)
    {
        const openvdb::Vec3i i = openvdb::tools::local_util::floorVec3(index);
        const openvdb::Vec3d uvw = index - i;
        const openvdb::Coord lo(i);
        ValueT data[2][2][2];
        gather(lo, lo, data);
        return openvdb::tools::BoxSampler::trilinearInterpolation(data, uvw);
    }

private:
    typename GridT::ConstAccessor accessor_;
    openvdb::Coord centre_;
    uint32_t probed_ = 0;  ///< bit i: values_[i] looked up
    const ValueT* values_[27] = {};
};

/// The differences of a level set's trilinear values half a voxel either
/// side of a point along each axis (what six WorldSampler lookups give: to
/// the bit, or with cubic voxels to rounding, the normals 1.4e-6 apart at
/// most over the 8.8 M points of the year-27 Populus at 0.005), from the
/// 3 x 3 x 3 voxels they all fall in, read at once.
class CentralDifferences {
public:
    CentralDifferences(const openvdb::FloatGrid& grid, double h)
        : grid_(grid),
          voxels_(grid),
          sampler_(grid),
          h_(h),
          axisAligned_(scalesAndMovesOnly(grid.transform()))
    {
        const openvdb::Vec3d voxel = grid.voxelSize();
        for (int k = 0; k < 3; ++k)
            half_[k] = 0.5 * h / voxel[k];
        halfVoxel_ = axisAligned_ && half_ == openvdb::Vec3d(0.5);
    }

    /// Whether index space is world space scaled and moved along its axes:
    /// a point's six samples then lie half a step from its index point.
    bool axisAligned() const { return axisAligned_; }

    /// At world point `p`, whose index point is `index` when axisAligned().
    openvdb::Vec3d operator()(const openvdb::Vec3d& p, const openvdb::Vec3d& index)
    {
        if (halfVoxel_)
            return halfVoxelApart(index);
        openvdb::Vec3d at[6];  // index space: +x, -x, +y, -y, +z, -z
        for (int k = 0; k < 3; ++k) {
            if (axisAligned_) {
                at[2 * k] = at[2 * k + 1] = index;
                at[2 * k][k] += half_[k];
                at[2 * k + 1][k] -= half_[k];
                continue;
            }
            openvdb::Vec3d e(0.0);
            e[k] = 0.5 * h_;
            at[2 * k] = grid_.transform().worldToIndex(p + e);
            at[2 * k + 1] = grid_.transform().worldToIndex(p - e);
        }
        openvdb::Vec3i cell[6];
        openvdb::Vec3i lo(std::numeric_limits<int>::max()), hi(std::numeric_limits<int>::min());
        for (int s = 0; s < 6; ++s) {
            cell[s] = openvdb::tools::local_util::floorVec3(at[s]);
            lo = minComponent(lo, cell[s]);
            hi = maxComponent(hi, cell[s]);
        }
        if (hi[0] - lo[0] > 1 || hi[1] - lo[1] > 1 || hi[2] - lo[2] > 1) {
            // (not around one voxel: a transform with a rotation, say)
            openvdb::Vec3d g;
            for (int k = 0; k < 3; ++k) {
                openvdb::Vec3d e(0.0);
                e[k] = 0.5 * h_;
                g[k] = double(sampler_(p + e)) - double(sampler_(p - e));
            }
            return g;
        }
        float block[3][3][3];
        voxels_.gather(openvdb::Coord(hi), openvdb::Coord(lo), block);
        float v[6];
        for (int s = 0; s < 6; ++s) {
            const openvdb::Vec3d uvw = at[s] - cell[s];
            const int x = cell[s][0] - lo[0], y = cell[s][1] - lo[1], z = cell[s][2] - lo[2];
            float data[2][2][2];
            for (int a = 0; a < 2; ++a)
                for (int b = 0; b < 2; ++b)
                    for (int c = 0; c < 2; ++c)
                        data[a][b][c] = block[x + a][y + b][z + c];
            v[s] = openvdb::tools::BoxSampler::trilinearInterpolation(data, uvw);
        }
        return openvdb::Vec3d(double(v[0]) - double(v[1]), double(v[2]) - double(v[3]),
                              double(v[4]) - double(v[5]));
    }

private:
    /// The same where the samples lie half a voxel from index point `q` along
    /// the axes (a level set's cubic voxels): along axis k both lie in
    /// neighbouring cells at one fraction u_k, and in the cell of q across
    /// it, so each difference is of two linear steps between the bilinear
    /// values of three rows of the 3 x 3 x 3 block (27 interpolations in
    /// double instead of six trilinear ones: equal up to rounding).
    openvdb::Vec3d halfVoxelApart(const openvdb::Vec3d& q)
    {
        const openvdb::Vec3i i = openvdb::tools::local_util::floorVec3(q);
        openvdb::Vec3i lo;
        double f[3], u[3];
        int o[3];  // q's cell in the block
        for (int k = 0; k < 3; ++k) {
            f[k] = q[k] - double(i[k]);
            const bool low = f[k] < 0.5;
            lo[k] = low ? i[k] - 1 : i[k];
            o[k] = low ? 1 : 0;
            u[k] = low ? f[k] + 0.5 : f[k] - 0.5;
        }
        float block[3][3][3];
        voxels_.gather(openvdb::Coord(i), openvdb::Coord(lo), block);
        auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
        // v(k, a, m, n): the block's value at a along axis k and m, n along
        // the other two (in x, y, z order).
        auto v = [&](int k, int a, int m, int n) -> double {
            return k == 0 ? block[a][m][n] : k == 1 ? block[m][a][n] : block[m][n][a];
        };
        openvdb::Vec3d g;
        for (int k = 0; k < 3; ++k) {
            const int j = k == 0 ? 1 : 0, l = k == 2 ? 1 : 2;  // the other axes
            double row[3];
            for (int a = 0; a < 3; ++a)
                row[a] =
                    lerp(lerp(v(k, a, o[j], o[l]), v(k, a, o[j], o[l] + 1), f[l]),
                         lerp(v(k, a, o[j] + 1, o[l]), v(k, a, o[j] + 1, o[l] + 1), f[l]), f[j]);
            g[k] = lerp(row[1], row[2], u[k]) - lerp(row[0], row[1], u[k]);
        }
        return g;
    }

    const openvdb::FloatGrid& grid_;
    LeafNeighbourhood<openvdb::FloatGrid> voxels_;
    const WorldSampler<openvdb::FloatGrid> sampler_;
    const double h_;
    const bool axisAligned_;
    openvdb::Vec3d half_;
    bool halfVoxel_;
};

}  // namespace

double meshingBytes(const openvdb::FloatGrid& surface, bool colour, double perPoint)
{
    using Lower = openvdb::FloatTree::RootNodeType::ChildNodeType::ChildNodeType;
    using Upper = openvdb::FloatTree::RootNodeType::ChildNodeType;
    const std::vector<openvdb::Index32> nodes = surface.tree().nodeCount();
    const double internal = double(nodes[1]) * sizeof(Lower) + double(nodes[2]) * sizeof(Upper),
                 leaves = nodes[0];
    // Points: about one per voxel at the zero crossing, 1.8x a flat band's
    // share of the active voxels (measured: 0.16-0.28 of a band 6 voxels wide).
    const double h = surface.voxelSize()[0], active = double(surface.activeVoxelCount());
    const double width = std::max(1.0, double(surface.background()) / h);
    const double points = std::min(active, 1.8 * active / (2.0 * width));
    // volumeToMesh: its sign, index and intersection trees (3.5x the
    // internal nodes, a kilobyte a leaf); a point: position, normal, colour,
    // two triangles and the quad they came from.
    return 3.5 * internal + 1024.0 * leaves + (72.0 + (colour ? 12.0 : 0.0) + perPoint) * points;
}

void checkMeshingFits(const openvdb::FloatGrid& surface, bool colour, const std::string& what,
                      double perPoint)
{
    checkMemoryFits(meshingBytes(surface, colour, perPoint),
                    fmt::format("meshing {} ({} leaves, {} active voxels)", what,
                                formatCount(double(surface.tree().leafCount())),
                                formatCount(double(surface.activeVoxelCount()))),
                    "mesh it on a machine with more memory, or bake it at a larger voxel size");
}

TriangleMesh meshLevelSet(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                          double adaptivity, MeshTimings* timings)
{
    MeshTimings local;
    MeshTimings& tm = timings ? *timings : local;
    auto t = Clock::now();
    TriangleMesh mesh;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(surface, mesh.points, tris, quads, 0.0,
                                 std::clamp(adaptivity, 0.0, 1.0));
    // volumeToMesh winds its polygons clockwise seen from outside a level set
    // (whose inside is negative): reversed here.
    tm.polygons = secondsSince(t);
    t = Clock::now();
    const size_t nt = tris.size();
    mesh.triangles.resize(nt + 2 * quads.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nt), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i < r.end(); ++i)
            mesh.triangles[i] = {tris[i][2], tris[i][1], tris[i][0]};
    });
    tbb::parallel_for(tbb::blocked_range<size_t>(0, quads.size()),
                      [&](const tbb::blocked_range<size_t>& r) {
                          for (size_t i = r.begin(); i < r.end(); ++i) {
                              const openvdb::Vec4I& q = quads[i];
                              auto* pair = &mesh.triangles[nt + 2 * i];
                              // The shorter diagonal gives the better-shaped pair.
                              const float d02 = (mesh.points[q[0]] - mesh.points[q[2]]).lengthSqr();
                              const float d13 = (mesh.points[q[1]] - mesh.points[q[3]]).lengthSqr();
                              if (d02 <= d13) {
                                  pair[0] = {q[2], q[1], q[0]};
                                  pair[1] = {q[3], q[2], q[0]};
                              } else {
                                  pair[0] = {q[3], q[1], q[0]};
                                  pair[1] = {q[3], q[2], q[1]};
                              }
                          }
                      });
    std::vector<openvdb::Vec3I>().swap(tris);
    std::vector<openvdb::Vec4I>().swap(quads);
    tm.triangles = secondsSince(t);
    t = Clock::now();
    // Normals: central differences of the trilinear level set, half a voxel
    // either side; colours: trilinear Cd.
    const double h = surface.voxelSize()[0];
    const size_t n = mesh.points.size();
    mesh.normals.resize(n);
    if (color)
        mesh.colors.resize(n);
    // (one transform of each point where the grids share an axis-aligned one)
    const openvdb::math::Transform& xf = surface.transform();
    const bool sameIndex = color && color->transform() == xf;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        CentralDifferences d(surface, h);
        const bool aligned = d.axisAligned();
        // (colours in index space from the leaves where the grids share an
        // axis-aligned transform, else by world position)
        std::unique_ptr<LeafNeighbourhood<openvdb::Vec3fGrid>> cv;
        std::unique_ptr<WorldSampler<openvdb::Vec3fGrid>> c;
        if (color && aligned && sameIndex)
            cv = std::make_unique<LeafNeighbourhood<openvdb::Vec3fGrid>>(*color);
        else if (color)
            c = std::make_unique<WorldSampler<openvdb::Vec3fGrid>>(*color);
        // The points come a leaf at a time: on reaching a leaf's first, the
        // next leaf's values are fetched into the cache while this leaf's
        // points are worked on (their first reads missed the cache: half
        // the stage's time).
        auto leafOf = [&](size_t i) {
            const openvdb::Coord v(
                openvdb::tools::local_util::floorVec3(xf.worldToIndex(mesh.points[i])));
            return openvdb::Coord(v.x() & ~7, v.y() & ~7, v.z() & ~7);
        };
        auto surfaceAhead = surface.getConstAccessor();
        std::optional<openvdb::Vec3fGrid::ConstAccessor> colourAhead;
        if (color && sameIndex)
            colourAhead.emplace(color->getConstAccessor());
        size_t next = r.begin();
        for (size_t i = r.begin(); i < r.end(); ++i) {
            if (aligned && i == next) {
                const openvdb::Coord here = leafOf(i);
                next = i + 1;
                while (next < r.end() && next < i + 512 && leafOf(next) == here)
                    ++next;
                if (next < r.end()) {
                    const openvdb::Coord there = leafOf(next);
                    if (const auto* l = surfaceAhead.probeConstLeaf(there))
                        prefetch(l->buffer().data(), sizeof(float) * 512);
                    if (colourAhead)
                        if (const auto* l = colourAhead->probeConstLeaf(there))
                            prefetch(l->buffer().data(), sizeof(openvdb::Vec3f) * 512);
                }
            }
            const openvdb::Vec3d p = mesh.points[i];
            const openvdb::Vec3d index = aligned ? xf.worldToIndex(p) : p;
            const openvdb::Vec3d g = d(p, index);
            const double len = g.length();
            mesh.normals[i] = len > 0.0 ? openvdb::Vec3s(g / len) : openvdb::Vec3s(0.0f);
            if (cv)
                mesh.colors[i] = cv->trilinear(index);
            else if (c)
                mesh.colors[i] = (*c)(p);
        }
    });
    tm.attributes = secondsSince(t);
    return mesh;
}

namespace {

/// The sum of f over the mesh's triangles, on all cores, in an order that
/// does not depend on the threads (the same digits every run).
template <class F>
double sumOverTriangles(const TriangleMesh& m, const F& f)
{
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, m.triangles.size(), 1 << 14), 0.0,
        [&](const tbb::blocked_range<size_t>& r, double sum) {
            for (size_t i = r.begin(); i < r.end(); ++i) {
                const auto& t = m.triangles[i];
                sum += f(openvdb::Vec3d(m.points[t[0]]), openvdb::Vec3d(m.points[t[1]]),
                         openvdb::Vec3d(m.points[t[2]]));
            }
            return sum;
        },
        std::plus<double>());
}

}  // namespace

double meshArea(const TriangleMesh& m)
{
    return sumOverTriangles(
        m, [](const openvdb::Vec3d& p0, const openvdb::Vec3d& p1, const openvdb::Vec3d& p2) {
            return 0.5 * (p1 - p0).cross(p2 - p0).length();
        });
}

double meshVolume(const TriangleMesh& m)
{
    return sumOverTriangles(m, [](const openvdb::Vec3d& p0, const openvdb::Vec3d& p1,
                                  const openvdb::Vec3d& p2) { return p0.dot(p1.cross(p2)) / 6.0; });
}

}  // namespace cambium
