// cambium — closed triangle meshes into narrow-band level sets.
//
// Every band voxel is measured against every triangle within the band's
// half-width of it (exact), eight voxels at a time; memory is touched once
// and kept small (first touches of fresh pages cost more than the
// arithmetic on small machines): triangles in index space in single
// precision, the mesh's own indices, leaves binned by counting.
#include "bake/mesh_levelset.h"

#include "bake/bake.h"
#include "bake/stages.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/half_edges.h"
#include "core/math.h"
#include "core/memory.h"
#include "core/system.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cstring>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <numeric>

namespace cambium {

namespace {

using glm::dvec3;

/// An uninitialised array whose pages all threads fault in (core/memory.h):
/// on a small machine first touches of fresh memory cost more than the
/// arithmetic, and a std::vector would zero it on one thread.
template <class T>
class Scratch {
public:
    Scratch() = default;
    explicit Scratch(size_t n) : data_(parallelArray<T>(n)), size_(n) {}
    size_t size() const { return size_; }
    T* data() { return data_.get(); }
    const T* data() const { return data_.get(); }
    T& operator[](size_t i) { return data_[i]; }
    const T& operator[](size_t i) const { return data_[i]; }
    const T* begin() const { return data_.get(); }
    const T* end() const { return data_.get() + size_; }

private:
    ParallelArray<T> data_;
    size_t size_ = 0;
};

/// A triangle in index space (world / h), in the mesh's single precision,
/// and its unit normal (zero for a triangle of no area, which is skipped).
struct Tri {
    glm::vec3 a, b, c, n;
};

/// The mesh's triangles and what the signs need: the triangle across each
/// edge (ab, bc, ca) and the angle-weighted pseudo-normal of every point.
struct Triangles {
    const TriangleMesh* mesh = nullptr;
    Scratch<Tri> tris;
    Scratch<std::array<uint32_t, 3>> across;
    std::vector<glm::vec3> corner;
    bool inward = false;  ///< faces turned inwards (a negative enclosed volume)
};

enum Feature : uint8_t { kFace = 0, kEdgeAB, kEdgeBC, kEdgeCA, kCornerA, kCornerB, kCornerC };

/// The nearest point of triangle (a, b, c) to p and the feature it lies on
/// (Ericson, Real-Time Collision Detection 5.1.5, by Voronoi regions), for
/// the band's values and signs once exactLeaf has found the triangle.
dvec3 closestOnTriangle(const dvec3& p, const dvec3& a, const dvec3& b, const dvec3& c, Feature& f)
{
    const dvec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0)
        return f = kCornerA, a;
    const dvec3 bp = p - b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3)
        return f = kCornerB, b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0)
        return f = kEdgeAB, a + ab * (d1 / (d1 - d3));
    const dvec3 cp = p - c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6)
        return f = kCornerC, c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0)
        return f = kEdgeCA, a + ac * (d2 / (d2 - d6));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
        return f = kEdgeBC, b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const double denom = 1.0 / (va + vb + vc);
    f = kFace;
    return a + ab * (vb * denom) + ac * (vc * denom);
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
[[noreturn]] void refuseEdge(const TriangleMesh& mesh, const HalfEdges& he, size_t i,
                             const std::string& what)
{
    const auto& t = mesh.triangles[i];
    for (int k = 0; k < 3; ++k) {
        const uint32_t a = t[size_t(k)], b = t[size_t(k + 1) % 3];
        size_t faces = 1;
        for (uint32_t j = he.start[a]; j < he.start[a + 1]; ++j)
            if (he.around[j] / 3 != i) {
                const auto& u = mesh.triangles[he.around[j] / 3];
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
    Triangles T;
    T.mesh = &mesh;
    T.tris = Scratch<Tri>(nt);
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
    // Each edge a -> b has exactly one triangle running b -> a beside it
    // (core/half_edges.h); the corners at each point come with them.
    std::vector<uint32_t> corner(3 * nt);
    tbb::parallel_for(size_t(0), nt, [&](size_t i) {
        for (size_t k = 0; k < 3; ++k)
            corner[3 * i + k] = mesh.triangles[i][k];
    });
    const FaceCorners faces{nullptr, nt, 3, corner.data(), np};
    const HalfEdges he = findHalfEdges(faces);
    corner = {};
    // Corners: the faces' normals weighted by their angles there.
    T.corner.resize(np);
    tbb::parallel_for(size_t(0), np, [&](size_t v) {
        dvec3 s(0.0);
        for (uint32_t k = he.start[v]; k < he.start[v + 1]; ++k) {
            const Tri& t = T.tris[he.around[k] / 3];
            const int c = int(he.around[k] % 3);
            const dvec3 q[3] = {dvec3(t.a), dvec3(t.b), dvec3(t.c)};
            const dvec3 e1 = q[(c + 1) % 3] - q[c], e2 = q[(c + 2) % 3] - q[c];
            const double l1 = glm::length(e1), l2 = glm::length(e2);
            if (l1 > 0.0 && l2 > 0.0)
                s += std::acos(std::clamp(glm::dot(e1, e2) / (l1 * l2), -1.0, 1.0)) * dvec3(t.n);
        }
        T.corner[v] = glm::vec3(s);
    });
    // Each edge's neighbour; a triangle with a point twice has no area and
    // no edges of its own (its neighbours are itself).
    T.across = Scratch<std::array<uint32_t, 3>>(nt);
    std::atomic<size_t> firstOpen{nt};
    tbb::parallel_for(size_t(0), nt, [&](size_t i) {
        const auto& t = mesh.triangles[i];
        const bool repeats = t[0] == t[1] || t[1] == t[2] || t[2] == t[0];
        for (size_t k = 0; k < 3; ++k) {
            const uint32_t twin = he.twin[3 * i + k];
            T.across[i][k] = twin == HalfEdges::kNone ? uint32_t(i) : twin / 3;
            if (twin == HalfEdges::kNone && !repeats) {
                size_t cur = firstOpen.load();
                while (i < cur && !firstOpen.compare_exchange_weak(cur, i)) {
                }
            }
        }
    });
    const size_t firstBad =
        std::min(firstOpen.load(), he.firstBad == HalfEdges::kNone ? nt : size_t(he.firstBad / 3));
    if (firstBad < nt)
        refuseEdge(mesh, he, firstBad, what);
    if (std::all_of(T.tris.begin(), T.tris.end(),
                    [](const Tri& t) { return t.n == glm::vec3(0.0f); }))
        throw InputError(fmt::format("{}: the mesh has no triangles of any area", what));
    // Six times the enclosed volume and twice the area, in one pass.  A
    // closed mesh facing inwards encloses a negative volume: its insides
    // are the pseudo-normals' outsides.
    const glm::dvec2 sums = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, nt, 8192), glm::dvec2(0.0),
        [&](const tbb::blocked_range<size_t>& r, glm::dvec2 s) {
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const dvec3 a(T.tris[i].a), b(T.tris[i].b), c(T.tris[i].c);
                s += glm::dvec2(glm::dot(a, glm::cross(b, c)),
                                glm::length(glm::cross(b - a, c - a)));
            }
            return s;
        },
        std::plus<glm::dvec2>());
    const double volume = sums.x, area = 0.5 * sums.y;
    T.inward = volume < 0.0;
    // A closed mesh around no volume (its faces folded onto one another: a
    // base with a point given twice) has no inside to bake: it made a level
    // set of zero thickness, exit 0.  (A millionth of the isoperimetric
    // scale A^1.5: a sheet a millionth as thick as it is wide.)
    if (!(std::fabs(volume) / 6.0 > 1e-6 * std::pow(area, 1.5)))
        throw InputError(fmt::format(
            "{}: the closed mesh encloses no volume ({:.3g} inside {:.3g} of surface): its faces "
            "fold onto one another (a point given twice?)",
            what, std::fabs(volume) / 6.0 * h * h * h, area * h * h));
    return T;
}

/// The voxels (index space, centres at integers) within `r` of the
/// triangle's bounding box.  (Rounded without the C library: outside the
/// AVX clones, std::ceil and std::floor are calls, and this runs for every
/// triangle of every leaf it is binned to: 8 % of a level-8 shape's bake.)
inline void voxelRange(const Tri& t, double r, openvdb::Coord& lo, openvdb::Coord& hi)
{
    for (int k = 0; k < 3; ++k) {
        const double low = double(std::min({t.a[k], t.b[k], t.c[k]})) - r;
        const double high = double(std::max({t.a[k], t.b[k], t.c[k]})) + r;
        const int l = int(low), h = int(high);  // (toward zero; |values| < 2^21)
        lo[k] = l + int(double(l) < low);
        hi[k] = h - int(double(h) > high);
    }
}

/// The leaves a band of half-width W around the triangles touches, and the
/// triangles of each: leaf l's are tri[first[l] .. first[l + 1]).  Counted
/// into a dense grid of leaves over the triangles' bounds (or, where that
/// grid would be large, a hash of the leaves), so the bins are 4 bytes each.
class LeafBins {
public:
    /// Where the leaves would pass maxLeaves, binning stops there: size()
    /// is then more than maxLeaves and the bins are empty.
    LeafBins(const Scratch<Tri>& tris, double W, size_t maxLeaves)
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
            binDense(tris, W, size_t(cells), maxLeaves);
        else
            binSparse(tris, W, maxLeaves);
    }

    size_t size() const { return origin_.size(); }
    const openvdb::Coord& origin(size_t l) const { return origin_[l]; }
    const uint32_t* begin(size_t l) const { return tri_.data() + first_[l]; }
    const uint32_t* end(size_t l) const { return tri_.data() + first_[l + 1]; }

private:
    static constexpr size_t kDenseCells = size_t(1) << 22;  // 16 MB of leaf slots

    /// The first voxel of leaf c (a multiplication: shifting a negative
    /// coordinate left is undefined).
    static openvdb::Coord leafOrigin(const openvdb::Coord& c)
    {
        return openvdb::Coord(c.x() * 8, c.y() * 8, c.z() * 8);
    }
    static bool less(const openvdb::Coord& a, const openvdb::Coord& b)
    {
        return a.x() != b.x() ? a.x() < b.x() : a.y() != b.y() ? a.y() < b.y() : a.z() < b.z();
    }
    size_t cell(const openvdb::Coord& c) const
    {
        return (size_t(c.x()) * size_t(dim_.y()) + size_t(c.y())) * size_t(dim_.z()) +
               size_t(c.z());
    }
    /// f(leaf) for each leaf of the triangle's band box that its plane's
    /// band reaches (within W of the plane, plus the leaf's half-diagonal:
    /// a large slanted triangle does not claim its whole box).  The leaves
    /// are walked as columns along the normal's largest axis, each column
    /// only across the plane's slab (a few leaves), so the work is the
    /// leaves claimed, not the box's: a slanted sliver 250 leaves long
    /// visited 250^3 leaves to claim 250^2.
    template <class F>
    static void forEachLeaf(const Tri& t, double W, const F& f)
    {
        openvdb::Coord lo, hi;
        voxelRange(t, W, lo, hi);
        lo = lo >> 3;
        hi = hi >> 3;
        const double reach = W + 3.5 * std::sqrt(3.0) + 1e-3;
        const dvec3 a(t.a), n(t.n);
        const int w = std::fabs(n.x) >= std::fabs(n.y) && std::fabs(n.x) >= std::fabs(n.z) ? 0
                      : std::fabs(n.y) >= std::fabs(n.z)                                   ? 1
                                                                                           : 2;
        const int u = (w + 1) % 3, v = (w + 2) % 3;
        auto centre = [](int c) { return 8.0 * c + 3.5; };
        openvdb::Coord c;
        for (c[u] = lo[u]; c[u] <= hi[u]; ++c[u])
            for (c[v] = lo[v]; c[v] <= hi[v]; ++c[v]) {
                // dot(centre - a, n) = d + n[w] * centre(c[w]): the column's
                // leaves within reach, widened by one each way and then
                // tested exactly as a leaf is.
                const double d =
                    n[u] * (centre(c[u]) - a[u]) + n[v] * (centre(c[v]) - a[v]) - n[w] * a[w];
                const double x0 = (-reach - d) / n[w], x1 = (reach - d) / n[w];
                const int first =
                    std::max(lo[w], int(std::floor((std::min(x0, x1) - 3.5) / 8.0)) - 1);
                const int last =
                    std::min(hi[w], int(std::ceil((std::max(x0, x1) - 3.5) / 8.0)) + 1);
                for (c[w] = first; c[w] <= last; ++c[w]) {
                    const dvec3 p(centre(c.x()), centre(c.y()), centre(c.z()));
                    if (std::fabs(glm::dot(p - a, n)) <= reach)
                        f(c);
                }
            }
    }

    void binDense(const Scratch<Tri>& tris, double W, size_t cells, size_t maxLeaves)
    {
        std::vector<uint32_t> count(cells, 0);
        for (const Tri& t : tris)
            if (t.n != glm::vec3(0.0f))
                forEachLeaf(t, W, [&](const openvdb::Coord& c) { ++count[cell(c - lo_)]; });
        const size_t leaves =
            size_t(std::count_if(count.begin(), count.end(), [](uint32_t n) { return n; }));
        if (leaves > maxLeaves) {
            origin_.resize(leaves);
            return;
        }
        std::vector<int32_t> leaf(cells, -1);  // the leaf of each cell, or -1
        first_.push_back(0);
        for (size_t c = 0; c < cells; ++c)
            if (count[c]) {
                leaf[c] = int32_t(origin_.size());
                const size_t z = c % size_t(dim_.z()),
                             y = (c / size_t(dim_.z())) % size_t(dim_.y()),
                             x = c / (size_t(dim_.z()) * size_t(dim_.y()));
                origin_.push_back(leafOrigin(openvdb::Coord(int(x), int(y), int(z)) + lo_));
                first_.push_back(first_.back() + count[c]);
            }
        tri_ = Scratch<uint32_t>(first_.back());
        std::vector<size_t> fill(first_.begin(), first_.end() - 1);
        for (size_t i = 0; i < tris.size(); ++i)
            if (tris[i].n != glm::vec3(0.0f))
                forEachLeaf(tris[i], W, [&](const openvdb::Coord& c) {
                    tri_[fill[size_t(leaf[cell(c - lo_)])]++] = uint32_t(i);
                });
    }

    /// The leaves by a hash of their coordinates, numbered as first met;
    /// counted, then ordered as the dense bins are, then filled.  Stops
    /// when the leaves pass maxLeaves (a frame that cannot fit is refused
    /// without binning it: the pairs of a tentacle 1000 long at voxel 0.5
    /// took 25 s and 2.4 GB to sort before their 49 M leaves were refused).
    void binSparse(const Scratch<Tri>& tris, double W, size_t maxLeaves)
    {
        std::vector<int32_t> slot(size_t(1) << 16, -1);  // leaf numbers, -1 empty
        std::vector<openvdb::Coord> met;
        std::vector<uint32_t> count;
        auto find = [&](const openvdb::Coord& c) -> int32_t& {
            const size_t mask = slot.size() - 1;
            size_t h = (size_t(uint32_t(c.x())) * 73856093u) ^
                       (size_t(uint32_t(c.y())) * 19349663u) ^
                       (size_t(uint32_t(c.z())) * 83492791u);
            for (h &= mask;; h = (h + 1) & mask)
                if (slot[h] < 0 || met[size_t(slot[h])] == c)
                    return slot[h];
        };
        struct Full {};
        try {
            for (const Tri& t : tris) {
                if (t.n == glm::vec3(0.0f))
                    continue;
                forEachLeaf(t, W, [&](const openvdb::Coord& c) {
                    int32_t& s = find(c);
                    const int32_t l = s < 0 ? int32_t(met.size()) : s;
                    if (s < 0) {
                        s = l;
                        met.push_back(c);
                        count.push_back(0);
                        if (2 * met.size() > slot.size()) {  // grow, keeping half empty
                            std::vector<int32_t>(slot.size() * 2, -1).swap(slot);
                            for (size_t k = 0; k < met.size(); ++k)
                                find(met[k]) = int32_t(k);
                        }
                    }
                    ++count[size_t(l)];
                    if (met.size() > maxLeaves)
                        throw Full();
                });
            }
        } catch (const Full&) {
            origin_.resize(met.size());
            return;
        }
        std::vector<uint32_t> order(met.size()), rank(met.size());
        std::iota(order.begin(), order.end(), 0u);
        tbb::parallel_sort(order.begin(), order.end(),
                           [&](uint32_t x, uint32_t y) { return less(met[x], met[y]); });
        first_.push_back(0);
        for (size_t r = 0; r < order.size(); ++r) {
            rank[order[r]] = uint32_t(r);
            origin_.push_back(leafOrigin(met[order[r]]));
            first_.push_back(first_.back() + count[order[r]]);
        }
        tri_ = Scratch<uint32_t>(first_.back());
        std::vector<size_t> fill(first_.begin(), first_.end() - 1);
        for (size_t i = 0; i < tris.size(); ++i)
            if (tris[i].n != glm::vec3(0.0f))
                forEachLeaf(tris[i], W, [&](const openvdb::Coord& c) {
                    tri_[fill[rank[size_t(find(c))]]++] = uint32_t(i);
                });
    }

    openvdb::Coord lo_, dim_;
    std::vector<openvdb::Coord> origin_;
    std::vector<size_t> first_;
    Scratch<uint32_t> tri_;
};

/// Every voxel's nearest triangle within the band (kLeafVoxels per leaf; -1
/// where none is nearer than W).
using Nearest = Scratch<int32_t>;

/// One leaf: every voxel within W of a binned triangle's bounding box
/// measured against that triangle, eight voxels (a row along z) at a time,
/// branch-free: the distance to the plane where the point projects inside
/// the triangle (three edge tests), else to the nearest of its three edges.
/// The whole body is one function on purpose: GCC lowers generic vectors
/// for the target of the function that holds them (bake/sweep.inc says
/// more), and this one is cloned for AVX2.
__attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default"))) void exactLeaf(
    const Tri* tris, const uint32_t* it, const uint32_t* end, openvdb::Coord o, double W,
    int32_t* __restrict bestTri)
{
    typedef float V8 __attribute__((vector_size(32)));
    typedef int32_t I8 __attribute__((vector_size(32)));
    alignas(32) float best[kLeafVoxels];
    const float w2 = float(W * W);
    for (float& b : best)
        b = w2;
    const V8 lane = {0, 1, 2, 3, 4, 5, 6, 7};
    const V8 pz = lane + float(o.z());
    const V8 zero = pz - pz, one = zero + 1.0f;
    for (; it != end; ++it) {
        const Tri& t = tris[*it];
        openvdb::Coord lo, hi;
        voxelRange(t, W, lo, hi);
        const int x0 = std::max(lo.x(), o.x()), x1 = std::min(hi.x(), o.x() + 7);
        const int y0 = std::max(lo.y(), o.y()), y1 = std::min(hi.y(), o.y() + 7);
        if (x0 > x1 || y0 > y1 || lo.z() > o.z() + 7 || hi.z() < o.z())
            continue;
        const glm::vec3 a = t.a, b = t.b, c = t.c, n = t.n;
        const glm::vec3 ab = b - a, bc = c - b, ca = a - c;
        const glm::vec3 eab = glm::cross(n, ab), ebc = glm::cross(n, bc), eca = glm::cross(n, ca);
        const float iab = 1.0f / glm::dot(ab, ab), ibc = 1.0f / glm::dot(bc, bc),
                    ica = 1.0f / glm::dot(ca, ca);
        const V8 za = pz - a.z, zb = pz - b.z, zc = pz - c.z;
        const I8 id = (I8){0, 0, 0, 0, 0, 0, 0, 0} + int32_t(*it);
        // A row whose eight voxels all lie beyond W of the triangle's plane
        // (on one side) is beyond W of the triangle: skipped.  (Its distance
        // to the plane is linear along the row: its ends bound it; the margin
        // keeps every voxel the exact pass could have kept.)
        const float reach = float(W) + 1e-3f, z0 = float(o.z()) - a.z, z7 = z0 + 7.0f;
        for (int x = x0; x <= x1; ++x)
            for (int y = y0; y <= y1; ++y) {
                const float xa = float(x) - a.x, ya = float(y) - a.y;
                const float across = xa * n.x + ya * n.y;
                const float p0 = across + z0 * n.z, p7 = across + z7 * n.z;
                if ((p0 > reach && p7 > reach) || (p0 < -reach && p7 < -reach))
                    continue;
                const float xb = float(x) - b.x, yb = float(y) - b.y;
                const float xc = float(x) - c.x, yc = float(y) - c.y;
                const V8 plane = xa * n.x + ya * n.y + za * n.z;
                const I8 inside = (xa * eab.x + ya * eab.y + za * eab.z >= zero) &
                                  (xb * ebc.x + yb * ebc.y + zb * ebc.z >= zero) &
                                  (xc * eca.x + yc * eca.y + zc * eca.z >= zero);
                V8 s = (xa * ab.x + ya * ab.y + za * ab.z) * iab;
                s = s < zero ? zero : (s > one ? one : s);
                V8 dx = xa - s * ab.x, dy = ya - s * ab.y, dz = za - s * ab.z;
                V8 edge = dx * dx + dy * dy + dz * dz;
                s = (xb * bc.x + yb * bc.y + zb * bc.z) * ibc;
                s = s < zero ? zero : (s > one ? one : s);
                dx = xb - s * bc.x, dy = yb - s * bc.y, dz = zb - s * bc.z;
                V8 d = dx * dx + dy * dy + dz * dz;
                edge = d < edge ? d : edge;
                s = (xc * ca.x + yc * ca.y + zc * ca.z) * ica;
                s = s < zero ? zero : (s > one ? one : s);
                dx = xc - s * ca.x, dy = yc - s * ca.y, dz = zc - s * ca.z;
                d = dx * dx + dy * dy + dz * dz;
                edge = d < edge ? d : edge;
                const V8 d2 = inside ? plane * plane : edge;
                const int row = ((x - o.x()) << 6) | ((y - o.y()) << 3);
                V8 old;
                I8 oldTri;
                std::memcpy(&old, best + row, sizeof old);
                std::memcpy(&oldTri, bestTri + row, sizeof oldTri);
                const I8 nearer = d2 < old;
                const V8 nb = nearer ? d2 : old;
                const I8 nt = nearer ? id : oldTri;
                std::memcpy(best + row, &nb, sizeof nb);
                std::memcpy(bestTri + row, &nt, sizeof nt);
            }
    }
}

/// Every band voxel's nearest triangle, exactly: each leaf measured against
/// the triangles binned to it (exactLeaf).
void exactPass(const Scratch<Tri>& tris, const LeafBins& bins, double W, Nearest& nearest)
{
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, bins.size(), 8), [&](const tbb::blocked_range<size_t>& r) {
            for (size_t l = r.begin(); l != r.end(); ++l) {
                int32_t* tri = nearest.data() + l * kLeafVoxels;
                std::fill_n(tri, kLeafVoxels, -1);
                exactLeaf(tris.data(), bins.begin(l), bins.end(l), bins.origin(l), W, tri);
            }
        });
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
        const int32_t* tri = nearest.data() + l * kLeafVoxels;
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
            const size_t i = size_t(tri[v]);
            const dvec3 p(o.x() + (v >> 6), o.y() + ((v >> 3) & 7), o.z() + (v & 7));
            const Tri& t = T.tris[i];
            const dvec3 a(t.a), b(t.b), cc(t.c);
            Feature f;
            const dvec3 c = closestOnTriangle(p, a, b, cc, f);
            const dvec3 d = p - c;
            const double dist = std::sqrt(glm::dot(d, d));
            if (!(dist < W))
                continue;
            ++active;
            const bool inside = (glm::dot(d, pseudoNormal(T, i, f)) < 0.0) != T.inward;
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

void checkMeshBake(const TriangleMesh& mesh, const MeshBakeOptions& opt, const std::string& what)
{
    const double h = opt.voxelSize, W = opt.halfWidth;
    checkVoxelSize(h, what + ": the voxel size");
    checkHalfWidth(W, what + ": the half-width");
    if (mesh.triangles.empty())
        throw InputError(fmt::format("{}: the mesh has no triangles", what));
    const size_t nt = mesh.triangles.size(), np = mesh.points.size();
    for (size_t i = 0; i < nt; ++i)
        for (uint32_t v : mesh.triangles[i])
            if (v >= np)
                throw InputError(
                    fmt::format("{}: triangle {} uses point {} of {}", what, i, v, np));
    // Positions in single precision a fraction of a voxel apart (and index
    // coordinates well inside int and OpenVDB's index space).
    for (size_t v = 0; v < np; ++v) {
        const openvdb::Vec3s& p = mesh.points[v];
        if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z()))
            throw InputError(fmt::format("{}: point {} is not finite", what, v));
        const double r = double(std::max({std::fabs(p.x()), std::fabs(p.y()), std::fabs(p.z())}));
        // (with the band and a leaf's margin; the message made only for the
        // point refused: formatted for each point it was a tenth of the check)
        if (const double reach = r + (W + 16.0) * h; !(reach / h < kMaxVoxelsFromOrigin))
            checkVoxelsFromOrigin(reach, h, fmt::format("{}: point {}, with its band,", what, v));
    }
    // (a mesh a tiny fraction of a voxel across has index-space triangles
    // of no area in float: it was refused as "no triangles of any area")
    const double extent = meshExtent(mesh);
    if (extent < 1e-3 * h)
        throw InputError(fmt::format(
            "{}: the mesh, {:.3g} across, is less than a thousandth of a voxel of {:g}: "
            "nothing to bake (use a smaller voxel size)",
            what, extent, h));
    // The binning's (triangle, leaf) pairs, 4 bytes each: a triangle claims
    // the leaves of its band box within reach of its plane, about its box's
    // footprint across its normal's largest axis times the band's thickness
    // along it (a sliver's box, not its area).  Refused before binning when
    // they alone would not fit (a tentacle of length 1000 ran silently past
    // a minute, its memory growing).
    const double leaf = 8.0 * h, reach = (W + 3.5 * std::sqrt(3.0)) * h;
    const double pairs = tbb::parallel_deterministic_reduce(
        tbb::blocked_range<size_t>(0, nt, 8192), 0.0,
        [&](const tbb::blocked_range<size_t>& range, double sum) {
            for (size_t i = range.begin(); i != range.end(); ++i) {
                const auto& t = mesh.triangles[i];
                const openvdb::Vec3d p0 = mesh.points[t[0]], p1 = mesh.points[t[1]],
                                     p2 = mesh.points[t[2]];
                const openvdb::Vec3d n = (p1 - p0).cross(p2 - p0);
                if (!(n.length() > 0.0))
                    continue;
                double leaves[3], normal[3];
                for (int k = 0; k < 3; ++k) {
                    const double lo = std::min({p0[k], p1[k], p2[k]}) - W * h,
                                 hi = std::max({p0[k], p1[k], p2[k]}) + W * h;
                    leaves[k] = std::floor(hi / leaf) - std::floor(lo / leaf) + 1.0;
                    normal[k] = std::abs(n[k]) / n.length();
                }
                const int w = normal[0] >= normal[1] && normal[0] >= normal[2] ? 0
                              : normal[1] >= normal[2]                         ? 1
                                                                               : 2;
                sum += leaves[(w + 1) % 3] * leaves[(w + 2) % 3] *
                       std::min(leaves[w], std::max(1.0, 2.0 * reach / (leaf * normal[w])));
            }
            return sum;
        },
        std::plus<double>());
    checkMemoryFits(pairs * 4.0,
                    fmt::format("{}: the band at voxel size {:g} (about {:.3g} triangle-leaf "
                                "pairs to bin)",
                                what, h, pairs),
                    "use a larger voxel size");
}

BakedGrids bakeMeshLevelSet(const TriangleMesh& mesh, const MeshBakeOptions& opt,
                            const std::string& what)
{
    const auto start = Clock::now();
    checkMeshBake(mesh, opt, what);
    const double h = opt.voxelSize, W = opt.halfWidth;
    auto progress = [&](const char* stage, double f) {
        if (opt.progress)
            opt.progress(stage, f);
    };
    const Triangles T = prepareTriangles(mesh, h, what);
    // Each leaf's nearest triangles, then its grid leaf (values, and colours
    // with Cd): refused, while binning, as soon as the leaves cannot fit.
    const double perLeaf = kLeafVoxels * (4.0 + 4.0 + 12.0), have = availableMemoryBytes();
    const LeafBins bins(T.tris, W, size_t(std::min(have / perLeaf, 1e15)));
    // (and the grids' internal nodes: 32 KB and more each, they cost more
    // than the leaves of a long thin band, half again for what assembly
    // holds beside them; measured on a needle 10^6 voxels long, 19 KB a leaf)
    const double need = bins.size() > size_t(have / perLeaf)
                            ? double(bins.size()) * perLeaf
                            : double(bins.size()) * perLeaf +
                                  1.5 * internalNodeBytes(bins.size(), true,
                                                          [&](size_t l) { return bins.origin(l); });
    if (need > have)
        throw InputError(fmt::format(
            "{}: the band at voxel size {:g} has at least {} leaves, which need at least {} of "
            "memory, and this machine has {} available: use a larger voxel size",
            what, h, bins.size(), formatBytes(need), formatBytes(have)));
    progress("binning", 1.0);

    Nearest nearest(bins.size() * kLeafVoxels);
    exactPass(T.tris, bins, W, nearest);
    progress("distances", 1.0);

    const float background = bandBackground(h, W);
    const BandLeaves band = makeLeaves(T, bins, nearest, h, W, background);
    BakedGrids out;
    out.stats.voxelSize = h;
    out.stats.candidateLeaves = bins.size();
    createGrids(out, h, background, openvdb::Vec3f(0.0f));
    assembleGrids(out, band, out.stats, out.stats.timings, /*leafSigns=*/false);
    if (mesh.colors.size() != mesh.points.size() || opt.colour == ColourExtent::None)
        out.color.reset();
    else if (opt.colour == ColourExtent::Shell)
        keepColourShell(out);
    if (opt.fog)
        addFog(out);
    out.stats.seconds = secondsSince(start);
    return out;
}

}  // namespace cambium
