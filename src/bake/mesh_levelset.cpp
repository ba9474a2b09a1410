// cambium — closed triangle meshes into narrow-band level sets.
//
// Memory is touched once and kept small (first touches of fresh pages
// dominate on small machines): triangles in index space in single
// precision, the mesh's own indices, leaves binned by counting.
#include "bake/mesh_levelset.h"

#include "bake/stages.h"
#include "core/clock.h"
#include "core/error.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>

namespace cambium {

namespace {

using glm::dvec3;

/// A triangle in index space (world / h), in the mesh's single precision,
/// and its unit normal (zero for a triangle of no area, which is skipped).
struct Tri {
    glm::vec3 a, b, c, n;
};

/// The mesh's triangles and what the signs need: the triangle across each
/// edge (ab, bc, ca) and the angle-weighted pseudo-normal of every point.
struct Triangles {
    const TriangleMesh* mesh = nullptr;
    std::vector<Tri> tris;
    std::vector<std::array<uint32_t, 3>> across;
    std::vector<glm::vec3> corner;
};

enum Feature : uint8_t { kFace = 0, kEdgeAB, kEdgeBC, kEdgeCA, kCornerA, kCornerB, kCornerC };

/// The nearest point of triangle (a, b, c) to p and the feature it lies on
/// (Ericson, Real-Time Collision Detection 5.1.5, by Voronoi regions): in
/// float for the search, in double for the band's values.
template <class V, class T = typename V::value_type>
V closestOnTriangle(const V& p, const V& a, const V& b, const V& c, Feature& f)
{
    const V ab = b - a, ac = c - a, ap = p - a;
    const T d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= T(0) && d2 <= T(0))
        return f = kCornerA, a;
    const V bp = p - b;
    const T d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= T(0) && d4 <= d3)
        return f = kCornerB, b;
    const T vc = d1 * d4 - d3 * d2;
    if (vc <= T(0) && d1 >= T(0) && d3 <= T(0))
        return f = kEdgeAB, a + ab * (d1 / (d1 - d3));
    const V cp = p - c;
    const T d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= T(0) && d5 <= d6)
        return f = kCornerC, c;
    const T vb = d5 * d2 - d1 * d6;
    if (vb <= T(0) && d2 >= T(0) && d6 <= T(0))
        return f = kEdgeCA, a + ac * (d2 / (d2 - d6));
    const T va = d3 * d6 - d5 * d4;
    if (va <= T(0) && (d4 - d3) >= T(0) && (d5 - d6) >= T(0))
        return f = kEdgeBC, b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const T denom = T(1) / (va + vb + vc);
    f = kFace;
    return a + ab * (vb * denom) + ac * (vc * denom);
}

/// Squared distance from p to the triangle, in float.
float distance2(const glm::vec3& p, const Tri& t)
{
    Feature f;
    const glm::vec3 d = p - closestOnTriangle(p, t.a, t.b, t.c, f);
    return glm::dot(d, d);
}

/// The pseudo-normal of feature f of triangle i: its normal, the sum of the
/// normals beside an edge, or the corner's angle-weighted sum.
dvec3 pseudoNormal(const Triangles& T, size_t i, Feature f)
{
    if (f == kFace)
        return dvec3(T.tris[i].n);
    if (f <= kEdgeCA)
        return dvec3(T.tris[i].n) + dvec3(T.tris[T.across[i][f - kEdgeAB]].n);
    return dvec3(T.corner[T.mesh->triangles[i][size_t(f - kCornerA)]]);
}

/// Barycentric weights of q in (a, b, c).
dvec3 barycentric(const dvec3& q, const dvec3& a, const dvec3& b, const dvec3& c)
{
    const dvec3 v0 = b - a, v1 = c - a, v2 = q - a;
    const double d00 = glm::dot(v0, v0), d01 = glm::dot(v0, v1), d11 = glm::dot(v1, v1);
    const double d20 = glm::dot(v2, v0), d21 = glm::dot(v2, v1);
    const double den = d00 * d11 - d01 * d01;
    if (!(den > 0.0))
        return {1.0 / 3, 1.0 / 3, 1.0 / 3};
    const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    return {1.0 - v - w, v, w};
}

/// The problem at triangle i's edges, named.
[[noreturn]] void refuseEdge(const TriangleMesh& mesh, const std::vector<uint32_t>& start,
                             const std::vector<uint32_t>& around, size_t i, const std::string& what)
{
    const auto& t = mesh.triangles[i];
    for (int k = 0; k < 3; ++k) {
        const uint32_t a = t[size_t(k)], b = t[size_t(k + 1) % 3];
        size_t faces = 1;
        for (uint32_t j = start[a]; j < start[a + 1]; ++j)
            if (around[j] != i) {
                const auto& u = mesh.triangles[around[j]];
                faces += (u[0] == b || u[1] == b || u[2] == b) ? 1 : 0;
            }
        if (faces != 2)
            throw InputError(fmt::format(
                "{}: the edge between points {} and {} has {} triangle{}: {} (a level set needs "
                "a closed surface; write a mesh instead)",
                what, std::min(a, b), std::max(a, b), faces, faces == 1 ? "" : "s",
                faces == 1 ? "the surface is open" : "the surface is not a 2-manifold"));
    }
    throw InputError(
        fmt::format("{}: the triangles beside triangle {} are not oriented as it is "
                    "(a level set needs a consistently oriented closed surface)",
                    what, i));
}

/// Each triangle in index space with its normal; the triangles around each
/// point; every edge's neighbour (InputError unless each edge a -> b has
/// exactly one triangle running b -> a beside it: open, not a 2-manifold,
/// or not consistently oriented); the corners' pseudo-normals.
Triangles prepareTriangles(const TriangleMesh& mesh, double h, const std::string& what)
{
    const size_t nt = mesh.triangles.size(), np = mesh.points.size();
    for (size_t i = 0; i < nt; ++i)
        for (uint32_t v : mesh.triangles[i])
            if (v >= np)
                throw InputError(
                    fmt::format("{}: triangle {} uses point {} of {}", what, i, v, np));
    Triangles T;
    T.mesh = &mesh;
    T.tris.resize(nt);
    const float scale = float(1.0 / h);
    tbb::parallel_for(size_t(0), nt, [&](size_t i) {
        Tri& t = T.tris[i];
        glm::vec3* p[3] = {&t.a, &t.b, &t.c};
        for (int k = 0; k < 3; ++k) {
            const openvdb::Vec3s& s = mesh.points[mesh.triangles[i][size_t(k)]];
            *p[k] = glm::vec3(s.x(), s.y(), s.z()) * scale;
        }
        const dvec3 n = glm::cross(dvec3(t.b) - dvec3(t.a), dvec3(t.c) - dvec3(t.a));
        const double len = glm::length(n);
        t.n = len > 1e-20 ? glm::vec3(n / len) : glm::vec3(0.0f);
    });
    // The triangles around each point (compressed rows).
    std::vector<uint32_t> start(np + 1, 0), around(3 * nt);
    for (const auto& t : mesh.triangles)
        for (uint32_t v : t)
            ++start[v + 1];
    for (size_t v = 0; v < np; ++v)
        start[v + 1] += start[v];
    {
        std::vector<uint32_t> fill(start.begin(), start.end() - 1);
        for (size_t i = 0; i < nt; ++i)
            for (uint32_t v : mesh.triangles[i])
                around[fill[v]++] = uint32_t(i);
    }
    // Corners: the faces' normals weighted by their angles there.
    T.corner.resize(np);
    tbb::parallel_for(size_t(0), np, [&](size_t v) {
        dvec3 s(0.0);
        for (uint32_t k = start[v]; k < start[v + 1]; ++k) {
            const Tri& t = T.tris[around[k]];
            const auto& idx = mesh.triangles[around[k]];
            const int c = idx[0] == v ? 0 : idx[1] == v ? 1 : 2;
            const dvec3 q[3] = {dvec3(t.a), dvec3(t.b), dvec3(t.c)};
            const dvec3 e1 = q[(c + 1) % 3] - q[c], e2 = q[(c + 2) % 3] - q[c];
            const double l1 = glm::length(e1), l2 = glm::length(e2);
            if (l1 > 0.0 && l2 > 0.0)
                s += std::acos(std::clamp(glm::dot(e1, e2) / (l1 * l2), -1.0, 1.0)) * dvec3(t.n);
        }
        T.corner[v] = glm::vec3(s);
    });
    // Edges: a -> b has exactly one triangle running b -> a beside it.
    T.across.resize(nt);
    std::atomic<size_t> firstBad{nt};
    tbb::parallel_for(size_t(0), nt, [&](size_t i) {
        const auto& t = mesh.triangles[i];
        for (int k = 0; k < 3; ++k) {
            const uint32_t a = t[size_t(k)], b = t[size_t(k + 1) % 3];
            int sides = 0;
            uint32_t other = uint32_t(i);
            for (uint32_t j = start[a]; j < start[a + 1]; ++j) {
                if (around[j] == i)
                    continue;
                const auto& u = mesh.triangles[around[j]];
                for (int m = 0; m < 3; ++m)
                    if (u[size_t(m)] == a && u[size_t(m + 1) % 3] == b) {
                        sides += 100;  // the same way: not oriented, or a third face
                    } else if (u[size_t(m)] == b && u[size_t(m + 1) % 3] == a) {
                        ++sides;
                        other = around[j];
                    }
            }
            if (sides != 1) {
                size_t cur = firstBad.load();
                while (i < cur && !firstBad.compare_exchange_weak(cur, i)) {
                }
            }
            T.across[i][size_t(k)] = other;
        }
    });
    if (firstBad < nt)
        refuseEdge(mesh, start, around, firstBad, what);
    if (std::all_of(T.tris.begin(), T.tris.end(),
                    [](const Tri& t) { return t.n == glm::vec3(0.0f); }))
        throw InputError(fmt::format("{}: the mesh has no triangles of any area", what));
    return T;
}

/// The voxels (index space, centres at integers) within `r` of the
/// triangle's bounding box.
void voxelRange(const Tri& t, double r, openvdb::Coord& lo, openvdb::Coord& hi)
{
    for (int k = 0; k < 3; ++k) {
        lo[k] = int(std::ceil(double(std::min({t.a[k], t.b[k], t.c[k]})) - r));
        hi[k] = int(std::floor(double(std::max({t.a[k], t.b[k], t.c[k]})) + r));
    }
}

/// The leaves a band of half-width W around the triangles touches, and the
/// triangles of each: leaf l's are tri[first[l] .. first[l + 1]).  Counted
/// into a dense grid of leaves over the triangles' bounds (or, where that
/// grid would be large, sorted by leaf), so the bins are 4 bytes each.
class LeafBins {
public:
    LeafBins(const std::vector<Tri>& tris, double W)
    {
        // The bounds in leaves.
        struct Bounds {
            openvdb::Coord lo{std::numeric_limits<int>::max()}, hi{std::numeric_limits<int>::min()};
        };
        const Bounds b = tbb::parallel_reduce(
            tbb::blocked_range<size_t>(0, tris.size(), 8192), Bounds(),
            [&](const tbb::blocked_range<size_t>& r, Bounds acc) {
                for (size_t i = r.begin(); i != r.end(); ++i) {
                    if (tris[i].n == glm::vec3(0.0f))
                        continue;
                    openvdb::Coord lo, hi;
                    voxelRange(tris[i], W, lo, hi);
                    acc.lo.minComponent(lo >> 3);
                    acc.hi.maxComponent(hi >> 3);
                }
                return acc;
            },
            [](Bounds x, const Bounds& y) {
                x.lo.minComponent(y.lo);
                x.hi.maxComponent(y.hi);
                return x;
            });
        lo_ = b.lo;
        dim_ = b.hi - b.lo + openvdb::Coord(1);
        const double cells = double(dim_.x()) * dim_.y() * dim_.z();
        if (cells <= double(kDenseCells))
            binDense(tris, W, size_t(cells));
        else
            binSparse(tris, W);
    }

    size_t size() const { return origin_.size(); }
    const openvdb::Coord& origin(size_t l) const { return origin_[l]; }
    const uint32_t* begin(size_t l) const { return tri_.data() + first_[l]; }
    const uint32_t* end(size_t l) const { return tri_.data() + first_[l + 1]; }
    size_t binned() const { return tri_.size(); }

    /// The leaf with origin o, or -1.
    int32_t find(const openvdb::Coord& o) const
    {
        if (!dense_.empty()) {
            const openvdb::Coord c = (o >> 3) - lo_;
            if (c.x() < 0 || c.y() < 0 || c.z() < 0 || c.x() >= dim_.x() || c.y() >= dim_.y() ||
                c.z() >= dim_.z())
                return -1;
            return dense_[cell(c)];
        }
        const auto it = std::lower_bound(origin_.begin(), origin_.end(), o, less);
        return it != origin_.end() && *it == o ? int32_t(it - origin_.begin()) : -1;
    }

private:
    static constexpr size_t kDenseCells = size_t(1) << 22;  // 16 MB of leaf slots

    static bool less(const openvdb::Coord& a, const openvdb::Coord& b)
    {
        return a.x() != b.x() ? a.x() < b.x() : a.y() != b.y() ? a.y() < b.y() : a.z() < b.z();
    }
    size_t cell(const openvdb::Coord& c) const
    {
        return (size_t(c.x()) * size_t(dim_.y()) + size_t(c.y())) * size_t(dim_.z()) +
               size_t(c.z());
    }
    template <class F>
    static void forEachLeaf(const Tri& t, double W, const F& f)
    {
        openvdb::Coord lo, hi;
        voxelRange(t, W, lo, hi);
        lo = lo >> 3;
        hi = hi >> 3;
        for (int x = lo.x(); x <= hi.x(); ++x)
            for (int y = lo.y(); y <= hi.y(); ++y)
                for (int z = lo.z(); z <= hi.z(); ++z)
                    f(openvdb::Coord(x, y, z));
    }

    void binDense(const std::vector<Tri>& tris, double W, size_t cells)
    {
        std::vector<uint32_t> count(cells, 0);
        for (const Tri& t : tris)
            if (t.n != glm::vec3(0.0f))
                forEachLeaf(t, W, [&](const openvdb::Coord& c) { ++count[cell(c - lo_)]; });
        dense_.assign(cells, -1);
        first_.push_back(0);
        for (size_t c = 0; c < cells; ++c)
            if (count[c]) {
                dense_[c] = int32_t(origin_.size());
                const size_t z = c % size_t(dim_.z()),
                             y = (c / size_t(dim_.z())) % size_t(dim_.y()),
                             x = c / (size_t(dim_.z()) * size_t(dim_.y()));
                origin_.push_back((openvdb::Coord(int(x), int(y), int(z)) + lo_) << 3);
                first_.push_back(first_.back() + count[c]);
            }
        tri_.resize(first_.back());
        std::vector<size_t> fill(first_.begin(), first_.end() - 1);
        for (size_t i = 0; i < tris.size(); ++i)
            if (tris[i].n != glm::vec3(0.0f))
                forEachLeaf(tris[i], W, [&](const openvdb::Coord& c) {
                    tri_[fill[size_t(dense_[cell(c - lo_)])]++] = uint32_t(i);
                });
    }

    void binSparse(const std::vector<Tri>& tris, double W)
    {
        std::vector<std::pair<openvdb::Coord, uint32_t>> pairs;
        for (size_t i = 0; i < tris.size(); ++i)
            if (tris[i].n != glm::vec3(0.0f))
                forEachLeaf(tris[i], W, [&](const openvdb::Coord& c) {
                    pairs.push_back({c << 3, uint32_t(i)});
                });
        tbb::parallel_sort(pairs.begin(), pairs.end(), [](const auto& a, const auto& b) {
            return less(a.first, b.first) || (a.first == b.first && a.second < b.second);
        });
        tri_.resize(pairs.size());
        for (size_t i = 0; i < pairs.size(); ++i) {
            if (i == 0 || pairs[i].first != pairs[i - 1].first) {
                origin_.push_back(pairs[i].first);
                first_.push_back(i);
            }
            tri_[i] = pairs[i].second;
        }
        first_.push_back(pairs.size());
    }

    openvdb::Coord lo_, dim_;
    std::vector<int32_t> dense_;  ///< leaf of each cell of the dense grid, or -1
    std::vector<openvdb::Coord> origin_;
    std::vector<size_t> first_;
    std::vector<uint32_t> tri_;
};

/// A set of a leaf's voxels, one bit each (word x, bit 8 y + z).
using VoxelMask = std::array<uint64_t, kLeafVoxels / 64>;

bool test(const VoxelMask& m, int v)
{
    return (m[size_t(v >> 6)] >> (v & 63)) & 1u;
}

void set(VoxelMask& m, int v)
{
    m[size_t(v >> 6)] |= uint64_t(1) << (v & 63);
}

/// Every voxel's nearest triangle so far (kLeafVoxels per leaf; -1 where
/// none is known), and the voxels where it is exact (pass 1's).  Distances
/// are not kept: recomputing one costs less than the memory of all.
struct Nearest {
    std::vector<int32_t> tri;
    std::vector<VoxelMask> exact;
};

/// Pass 1, exact near the surface: each leaf's voxels within `r1` of a
/// triangle's bounding box measured against that triangle (its plane's
/// distance first: it bounds the triangle's from below).
void nearPass(const std::vector<Tri>& tris, const LeafBins& bins, double r1, Nearest& nearest)
{
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, bins.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t l = r.begin(); l != r.end(); ++l) {
                const openvdb::Coord o = bins.origin(l);
                float best[kLeafVoxels];
                std::fill(best, best + kLeafVoxels, float(r1 * r1));
                int32_t* bestTri = nearest.tri.data() + l * kLeafVoxels;
                for (const uint32_t* it = bins.begin(l); it != bins.end(l); ++it) {
                    const Tri& t = tris[*it];
                    openvdb::Coord lo, hi;
                    voxelRange(t, r1, lo, hi);
                    const int x0 = std::max(lo.x(), o.x()), x1 = std::min(hi.x(), o.x() + 7);
                    const int y0 = std::max(lo.y(), o.y()), y1 = std::min(hi.y(), o.y() + 7);
                    const int z0 = std::max(lo.z(), o.z()), z1 = std::min(hi.z(), o.z() + 7);
                    for (int x = x0; x <= x1; ++x)
                        for (int y = y0; y <= y1; ++y)
                            for (int z = z0; z <= z1; ++z) {
                                const int v = ((x - o.x()) << 6) | ((y - o.y()) << 3) | (z - o.z());
                                const glm::vec3 p{float(x), float(y), float(z)};
                                const float dp = glm::dot(p - t.a, t.n);
                                if (dp * dp >= best[v])
                                    continue;
                                const float d2 = distance2(p, t);
                                if (d2 < best[v]) {
                                    best[v] = d2;
                                    bestTri[v] = int32_t(*it);
                                }
                            }
                }
                VoxelMask& exact = nearest.exact[l];
                exact.fill(0);
                for (int v = 0; v < kLeafVoxels; ++v)
                    if (bestTri[v] >= 0)
                        set(exact, v);
            }
        });
}

bool any(const VoxelMask& m)
{
    return (m[0] | m[1] | m[2] | m[3] | m[4] | m[5] | m[6] | m[7]) != 0;
}

/// The voxels of a leaf next to (across a face) a voxel set in `own` (bit
/// shifts: word x, bit 8 y + z) or in the neighbours' masks `nb` (+x, -x,
/// +y, -y, +z, -z; null where there is none).
VoxelMask beside(const VoxelMask& own, const std::array<const VoxelMask*, 6>& nb)
{
    constexpr uint64_t kZ0 = 0x0101010101010101ull, kZ7 = kZ0 << 7;
    VoxelMask out;
    for (size_t x = 0; x < 8; ++x) {
        const uint64_t w = own[x];
        uint64_t d = ((w << 1) & ~kZ0) | ((w >> 1) & ~kZ7) | (w << 8) | (w >> 8);
        if (x > 0)
            d |= own[x - 1];
        if (x < 7)
            d |= own[x + 1];
        out[x] = d;
    }
    if (nb[0])
        out[7] |= (*nb[0])[0];
    if (nb[1])
        out[0] |= (*nb[1])[7];
    for (size_t x = 0; x < 8; ++x) {
        if (nb[2])
            out[x] |= ((*nb[2])[x] & 0xFFull) << 56;
        if (nb[3])
            out[x] |= (*nb[3])[x] >> 56;
        if (nb[4])
            out[x] |= ((*nb[4])[x] & kZ0) << 7;
        if (nb[5])
            out[x] |= ((*nb[5])[x] & kZ7) >> 7;
    }
    return out;
}

/// Pass 2, out to the band's edge (squared distances below `limit2`), in
/// rounds: each voxel not yet exact tries the nearest triangles of its six neighbours that
/// changed since its leaf was last visited.  Each round visits the leaves in
/// two halves, a checkerboard of leaves, so that no leaf is written while a
/// neighbour reads it: in place, and the same whatever the threads.  (The
/// nearest point may have moved across an edge from the neighbours':
/// makeLeaves finishes the search.)
void farPass(const Triangles& T, const LeafBins& bins, int rounds, float limit2, Nearest& nearest)
{
    const size_t n = bins.size();
    std::vector<std::array<int32_t, 6>> faceNb(n);
    std::vector<VoxelMask> before(n), now(n);  // changes in the last round, in this one
    std::vector<uint32_t> half[2];
    for (size_t l = 0; l < n; ++l) {
        const openvdb::Coord o = bins.origin(l) >> 3;
        half[(o.x() + o.y() + o.z()) & 1].push_back(uint32_t(l));
    }
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        const openvdb::Coord o = bins.origin(l);
        for (int k = 0; k < 6; ++k) {
            openvdb::Coord c = o;
            c[k / 2] += (k % 2 ? -8 : 8);
            faceNb[l][size_t(k)] = bins.find(c);
        }
        const int32_t* t = nearest.tri.data() + l * kLeafVoxels;
        now[l].fill(0);
        for (int v = 0; v < kLeafVoxels; ++v)
            if (t[v] >= 0)
                now[l][size_t(v >> 6)] |= uint64_t(1) << (v & 63);
    });
    auto visit = [&](size_t l, int phase) {
        // Neighbours of the other half changed last round (phase 0) or in
        // this round's first half (phase 1); this leaf, at its last visit.
        const std::vector<VoxelMask>& theirs = phase == 0 ? before : now;
        std::array<const VoxelMask*, 6> nb;
        bool near = any(before[l]);
        for (int k = 0; k < 6; ++k) {
            const int32_t j = faceNb[l][size_t(k)];
            nb[size_t(k)] = j >= 0 ? &theirs[size_t(j)] : nullptr;
            near = near || (j >= 0 && any(theirs[size_t(j)]));
        }
        now[l].fill(0);
        if (!near)
            return;
        const VoxelMask front = beside(before[l], nb);
        const openvdb::Coord o = bins.origin(l);
        int32_t* bestTri = nearest.tri.data() + l * kLeafVoxels;
        for (size_t word = 0; word < front.size(); ++word)
            for (uint64_t bits = front[word] & ~nearest.exact[l][word]; bits; bits &= bits - 1) {
                const int v = int(word * 64) + __builtin_ctzll(bits);
                const int c[3] = {v >> 6, (v >> 3) & 7, v & 7};
                int32_t cand[6];
                int nc = 0;
                for (int k = 0; k < 6; ++k) {
                    int q[3] = {c[0], c[1], c[2]};
                    q[k / 2] += k % 2 ? -1 : 1;
                    size_t leaf = l;
                    const VoxelMask* mask = &before[l];
                    if (q[k / 2] < 0 || q[k / 2] > 7) {
                        if (!nb[size_t(k)])
                            continue;
                        leaf = size_t(faceNb[l][size_t(k)]);
                        mask = nb[size_t(k)];
                        q[k / 2] &= 7;
                    }
                    const int w = (q[0] << 6) | (q[1] << 3) | q[2];
                    if (!test(*mask, w))
                        continue;
                    const int32_t t = nearest.tri[leaf * kLeafVoxels + size_t(w)];
                    if (t < 0 || t == bestTri[v] || std::find(cand, cand + nc, t) != cand + nc)
                        continue;
                    cand[nc++] = t;
                }
                if (nc == 0)
                    continue;
                const glm::vec3 p{float(o.x() + c[0]), float(o.y() + c[1]), float(o.z() + c[2])};
                float best = bestTri[v] >= 0 ? distance2(p, T.tris[size_t(bestTri[v])]) : limit2;
                for (int i = 0; i < nc; ++i) {
                    const float d2 = distance2(p, T.tris[size_t(cand[i])]);
                    if (d2 < best) {
                        best = d2;
                        bestTri[v] = cand[i];
                        set(now[l], v);
                    }
                }
            }
    };
    for (int round = 0; round < rounds; ++round) {
        std::swap(before, now);
        for (int phase = 0; phase < 2; ++phase)
            tbb::parallel_for(size_t(0), half[phase].size(),
                              [&](size_t i) { visit(half[phase][i], phase); });
    }
}

/// From triangle i, across edges to a nearer triangle while there is one:
/// the nearest triangle to p when, as in the band beyond pass 1, i is one
/// of its neighbours' nearest.
size_t descend(const Triangles& T, const dvec3& p, size_t i)
{
    auto dist2 = [&](size_t j) {
        const Tri& t = T.tris[j];
        Feature f;
        const dvec3 d = p - closestOnTriangle(p, dvec3(t.a), dvec3(t.b), dvec3(t.c), f);
        return glm::dot(d, d);
    };
    double best = dist2(i);
    for (int step = 0; step < 64; ++step) {
        size_t next = i;
        for (uint32_t u : T.across[i])
            if (T.tris[u].n != glm::vec3(0.0f)) {
                const double d = dist2(u);
                if (d < best)
                    best = d, next = u;
            }
        if (next == i)
            break;
        i = next;
    }
    return i;
}

/// The band voxels (distance below W) into grid leaves: signed distances in
/// world units (the sign from the nearest feature's pseudo-normal), colours
/// at the nearest points.
BandLeaves makeLeaves(const Triangles& T, const LeafBins& bins, const Nearest& nearest, double h,
                      double W, float background)
{
    const TriangleMesh& mesh = *T.mesh;
    const size_t n = bins.size();
    const bool coloured = mesh.colors.size() == mesh.points.size();
    BandLeaves band;
    band.surface.assign(n, nullptr);
    band.color.assign(n, nullptr);
    band.active.assign(n, 0);
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        const int32_t* tri = nearest.tri.data() + l * kLeafVoxels;
        if (std::all_of(tri, tri + kLeafVoxels, [](int32_t t) { return t < 0; }))
            return;
        const openvdb::Coord o = bins.origin(l);
        auto* leaf = new openvdb::FloatTree::LeafNodeType(o, background);
        openvdb::Vec3fTree::LeafNodeType* cleaf =
            coloured ? new openvdb::Vec3fTree::LeafNodeType(o, openvdb::Vec3f(0.0f)) : nullptr;
        size_t active = 0;
        for (int v = 0; v < kLeafVoxels; ++v) {
            if (tri[v] < 0)
                continue;
            size_t i = size_t(tri[v]);
            const dvec3 p(o.x() + (v >> 6), o.y() + ((v >> 3) & 7), o.z() + (v & 7));
            if (!test(nearest.exact[l], v))
                i = descend(T, p, i);
            const Tri& t = T.tris[i];
            const dvec3 a(t.a), b(t.b), cc(t.c);
            Feature f;
            const dvec3 c = closestOnTriangle(p, a, b, cc, f);
            const dvec3 d = p - c;
            const double dist = std::sqrt(glm::dot(d, d));
            if (!(dist < W))
                continue;
            ++active;
            const bool inside = glm::dot(d, pseudoNormal(T, i, f)) < 0.0;
            leaf->setValueOn(openvdb::Index(v), float((inside ? -dist : dist) * h));
            if (cleaf) {
                const dvec3 bc = barycentric(c, a, b, cc);
                const auto& idx = mesh.triangles[i];
                cleaf->setValueOn(openvdb::Index(v), mesh.colors[idx[0]] * float(bc.x) +
                                                         mesh.colors[idx[1]] * float(bc.y) +
                                                         mesh.colors[idx[2]] * float(bc.z));
            }
        }
        if (active == 0) {
            delete leaf;
            delete cleaf;
            return;
        }
        band.surface[l] = leaf;
        band.color[l] = cleaf;
        band.active[l] = active;
    });
    return band;
}

}  // namespace

double meshExtent(const TriangleMesh& mesh)
{
    if (mesh.points.empty())
        return 0.0;
    openvdb::Vec3s lo = mesh.points[0], hi = mesh.points[0];
    for (const auto& p : mesh.points) {
        lo = openvdb::math::minComponent(lo, p);
        hi = openvdb::math::maxComponent(hi, p);
    }
    const openvdb::Vec3s s = hi - lo;
    return double(std::max({s.x(), s.y(), s.z()}));
}

BakedGrids bakeMeshLevelSet(const TriangleMesh& mesh, const MeshBakeOptions& opt,
                            const std::string& what)
{
    const auto start = Clock::now();
    const double h = opt.voxelSize, W = opt.halfWidth;
    if (!(h > 0.0) || !(W >= 1.0))
        throw InputError(
            fmt::format("{}: voxel size {} and half-width {} (need > 0 and >= 1)", what, h, W));
    if (mesh.triangles.empty())
        throw InputError(fmt::format("{}: the mesh has no triangles", what));
    auto progress = [&](const char* stage, double f) {
        if (opt.progress)
            opt.progress(stage, f);
    };
    const Triangles T = prepareTriangles(mesh, h, what);
    const LeafBins bins(T.tris, W);
    progress("binning", 1.0);

    // Exact within kNearVoxels of the surface; beyond, out to W, from the
    // neighbours' nearest triangles (each round reaches a voxel further
    // along an axis: sqrt(3) rounds per voxel of distance along a diagonal).
    constexpr double kNearVoxels = 1.0;
    const double r1 = std::min(kNearVoxels, W);
    Nearest nearest;
    nearest.tri.assign(bins.size() * kLeafVoxels, -1);
    nearest.exact.resize(bins.size());
    nearPass(T.tris, bins, r1, nearest);
    progress("distances", 0.5);
    // (Kept a little beyond W: the last search in makeLeaves may bring a
    // voxel inside.)
    farPass(T, bins, int(std::ceil((W - r1) * std::sqrt(3.0))) + 1, float((W + 0.5) * (W + 0.5)),
            nearest);
    progress("distances", 1.0);

    const float background = bandBackground(h, W);
    const BandLeaves band = makeLeaves(T, bins, nearest, h, W, background);
    BakedGrids out;
    out.stats.voxelSize = h;
    out.stats.candidateLeaves = bins.size();
    createGrids(out, h, background, openvdb::Vec3f(0.0f));
    assembleGrids(out, band, out.stats, out.stats.timings, /*leafSigns=*/false);
    if (mesh.colors.size() != mesh.points.size())
        out.color.reset();
    if (opt.fog)
        addFog(out);
    out.stats.seconds = secondsSince(start);
    return out;
}

}  // namespace cambium
