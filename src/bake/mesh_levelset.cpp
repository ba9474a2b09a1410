// cambium — closed triangle meshes into narrow-band level sets.
#include "bake/mesh_levelset.h"

#include "bake/stages.h"
#include "core/clock.h"
#include "core/error.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace cambium {

namespace {

using glm::dvec3;

/// A triangle in index space (world / h) with the pseudo-normals of its
/// seven features: the face, edges ab, bc, ca, corners a, b, c.
struct Tri {
    dvec3 a, b, c;
    dvec3 normal[7];
    uint32_t v[3];
};

enum Feature : uint8_t { kFace = 0, kEdgeAB, kEdgeBC, kEdgeCA, kCornerA, kCornerB, kCornerC };

/// The nearest point of triangle (a, b, c) to p and the feature it lies on
/// (Ericson, Real-Time Collision Detection 5.1.5, by Voronoi regions).
dvec3 closestOnTriangle(const dvec3& p, const Tri& t, Feature& f)
{
    const dvec3 ab = t.b - t.a, ac = t.c - t.a, ap = p - t.a;
    const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0)
        return f = kCornerA, t.a;
    const dvec3 bp = p - t.b;
    const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3)
        return f = kCornerB, t.b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0)
        return f = kEdgeAB, t.a + ab * (d1 / (d1 - d3));
    const dvec3 cp = p - t.c;
    const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6)
        return f = kCornerC, t.c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0)
        return f = kEdgeCA, t.a + ac * (d2 / (d2 - d6));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
        return f = kEdgeBC, t.b + (t.c - t.b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    const double denom = 1.0 / (va + vb + vc);
    f = kFace;
    return t.a + ab * (vb * denom) + ac * (vc * denom);
}

/// Barycentric weights of q in (a, b, c).
dvec3 barycentric(const dvec3& q, const Tri& t)
{
    const dvec3 v0 = t.b - t.a, v1 = t.c - t.a, v2 = q - t.a;
    const double d00 = glm::dot(v0, v0), d01 = glm::dot(v0, v1), d11 = glm::dot(v1, v1);
    const double d20 = glm::dot(v2, v0), d21 = glm::dot(v2, v1);
    const double den = d00 * d11 - d01 * d01;
    if (!(den > 0.0))
        return {1.0 / 3, 1.0 / 3, 1.0 / 3};
    const double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    return {1.0 - v - w, v, w};
}

uint64_t edgeKey(uint32_t a, uint32_t b)
{
    return (uint64_t(std::min(a, b)) << 32) | std::max(a, b);
}

/// The triangles in index space with their pseudo-normals; InputError for an
/// open or non-manifold edge.  Triangles of no area are left out (their
/// edges are their neighbours').
std::vector<Tri> prepareTriangles(const TriangleMesh& mesh, double h, const std::string& what)
{
    const size_t nt = mesh.triangles.size(), np = mesh.points.size();
    std::vector<Tri> tris(nt);
    std::vector<dvec3> corner(np, dvec3(0.0));
    std::vector<uint8_t> used(nt, 0);
    for (size_t i = 0; i < nt; ++i) {
        Tri& t = tris[i];
        dvec3* p[3] = {&t.a, &t.b, &t.c};
        for (int k = 0; k < 3; ++k) {
            t.v[k] = mesh.triangles[i][size_t(k)];
            if (t.v[k] >= np)
                throw InputError(
                    fmt::format("{}: triangle {} uses point {} of {}", what, i, t.v[k], np));
            const openvdb::Vec3s& s = mesh.points[t.v[k]];
            *p[k] = dvec3(s.x(), s.y(), s.z()) / h;
        }
        const dvec3 n = glm::cross(t.b - t.a, t.c - t.a);
        const double len = glm::length(n);
        if (!(len > 1e-20))
            continue;
        used[i] = 1;
        t.normal[kFace] = n / len;
        for (int k = 0; k < 3; ++k) {  // angle-weighted corner normals
            const dvec3 e1 = glm::normalize(*p[(k + 1) % 3] - *p[k]);
            const dvec3 e2 = glm::normalize(*p[(k + 2) % 3] - *p[k]);
            corner[t.v[k]] += std::acos(std::clamp(glm::dot(e1, e2), -1.0, 1.0)) * t.normal[kFace];
        }
    }
    // Edges: each must be shared by exactly two triangles.
    std::vector<std::pair<uint64_t, uint32_t>> edges;
    edges.reserve(3 * nt);
    for (size_t i = 0; i < nt; ++i)
        if (used[i])
            for (int k = 0; k < 3; ++k)
                edges.push_back(
                    {edgeKey(tris[i].v[k], tris[i].v[(k + 1) % 3]), uint32_t(3 * i + k)});
    if (edges.empty())
        throw InputError(fmt::format("{}: the mesh has no triangles of any area", what));
    tbb::parallel_sort(edges.begin(), edges.end());
    for (size_t e = 0; e < edges.size();) {
        size_t f = e + 1;
        while (f < edges.size() && edges[f].first == edges[e].first)
            ++f;
        if (f - e != 2) {
            const uint64_t key = edges[e].first;
            throw InputError(fmt::format(
                "{}: the edge between points {} and {} has {} triangle{}: {} (a level set needs "
                "a closed surface; write a mesh instead)",
                what, key >> 32, key & 0xffffffffu, f - e, f - e == 1 ? "" : "s",
                f - e == 1 ? "the surface is open" : "the surface is not a 2-manifold"));
        }
        const uint32_t i = edges[e].second / 3, j = edges[e + 1].second / 3;
        const dvec3 n = tris[i].normal[kFace] + tris[j].normal[kFace];
        tris[i].normal[1 + edges[e].second % 3] = n;
        tris[j].normal[1 + edges[e + 1].second % 3] = n;
        e = f;
    }
    for (size_t i = 0; i < nt; ++i)
        for (int k = 0; k < 3; ++k)
            tris[i].normal[kCornerA + k] = corner[tris[i].v[k]];
    tris.erase(std::remove_if(tris.begin(), tris.end(),
                              [&](const Tri& t) { return !used[size_t(&t - tris.data())]; }),
               tris.end());
    return tris;
}

int leafOf(int i)
{
    return i >> 3;
}

int sext21(uint64_t v)
{
    return int32_t(uint32_t(v & 0x1FFFFF) << 11) >> 11;
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
    auto progress = [&](const char* stage, double f) {
        if (opt.progress)
            opt.progress(stage, f);
    };
    const std::vector<Tri> tris = prepareTriangles(mesh, h, what);
    const bool coloured = mesh.colors.size() == mesh.points.size();

    // Each triangle into the leaves its band box touches, sorted by leaf.
    std::vector<size_t> count(tris.size() + 1, 0);
    auto leafRange = [&](const Tri& t, int lo[3], int hi[3]) {
        for (int k = 0; k < 3; ++k) {
            const double mn = std::min({t.a[k], t.b[k], t.c[k]}) - W;
            const double mx = std::max({t.a[k], t.b[k], t.c[k]}) + W;
            lo[k] = int(std::ceil(mn));
            hi[k] = int(std::floor(mx));
        }
    };
    tbb::parallel_for(size_t(0), tris.size(), [&](size_t i) {
        int lo[3], hi[3];
        leafRange(tris[i], lo, hi);
        size_t n = 1;
        for (int k = 0; k < 3; ++k)
            n *= size_t(std::max(0, leafOf(hi[k]) - leafOf(lo[k]) + 1));
        count[i + 1] = n;
    });
    for (size_t i = 0; i < tris.size(); ++i)
        count[i + 1] += count[i];
    std::vector<std::pair<uint64_t, uint32_t>> bins(count.back());
    tbb::parallel_for(size_t(0), tris.size(), [&](size_t i) {
        int lo[3], hi[3];
        leafRange(tris[i], lo, hi);
        size_t o = count[i];
        for (int x = leafOf(lo[0]); x <= leafOf(hi[0]); ++x)
            for (int y = leafOf(lo[1]); y <= leafOf(hi[1]); ++y)
                for (int z = leafOf(lo[2]); z <= leafOf(hi[2]); ++z)
                    bins[o++] = {nodeKey(x << 3, y << 3, z << 3, 3), uint32_t(i)};
    });
    tbb::parallel_sort(bins.begin(), bins.end());
    std::vector<size_t> runs;
    for (size_t i = 0; i < bins.size(); ++i)
        if (i == 0 || bins[i].first != bins[i - 1].first)
            runs.push_back(i);
    runs.push_back(bins.size());
    const size_t nLeaves = runs.size() - 1;
    progress("binning", 1.0);

    // Each leaf: the nearest triangle of every voxel within the band.
    const float background = bandBackground(h, W);
    BandLeaves band;
    band.surface.assign(nLeaves, nullptr);
    band.color.assign(nLeaves, nullptr);
    band.active.assign(nLeaves, 0);
    const double w2 = W * W;
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, nLeaves, 16), [&](const tbb::blocked_range<size_t>& r) {
            float best[kLeafVoxels];
            int32_t bestTri[kLeafVoxels];
            for (size_t l = r.begin(); l != r.end(); ++l) {
                const uint64_t key = bins[runs[l]].first;
                const int ox = sext21(key >> 42) << 3, oy = sext21(key >> 21) << 3,
                          oz = sext21(key) << 3;
                std::fill(best, best + kLeafVoxels, float(w2));
                std::fill(bestTri, bestTri + kLeafVoxels, -1);
                for (size_t b = runs[l]; b < runs[l + 1]; ++b) {
                    const Tri& t = tris[bins[b].second];
                    int lo[3], hi[3];
                    leafRange(t, lo, hi);
                    const int x0 = std::max(lo[0], ox), x1 = std::min(hi[0], ox + 7);
                    const int y0 = std::max(lo[1], oy), y1 = std::min(hi[1], oy + 7);
                    const int z0 = std::max(lo[2], oz), z1 = std::min(hi[2], oz + 7);
                    for (int x = x0; x <= x1; ++x)
                        for (int y = y0; y <= y1; ++y)
                            for (int z = z0; z <= z1; ++z) {
                                const int v = ((x - ox) << 6) | ((y - oy) << 3) | (z - oz);
                                const dvec3 p(x, y, z);
                                const double dp = glm::dot(p - t.a, t.normal[kFace]);
                                if (dp * dp >=
                                    double(best[v]))  // the plane is nearer than the triangle
                                    continue;
                                Feature f;
                                const dvec3 c = closestOnTriangle(p, t, f);
                                const dvec3 d = p - c;
                                const double d2 = glm::dot(d, d);
                                if (d2 < double(best[v])) {
                                    best[v] = float(d2);
                                    bestTri[v] = int32_t(bins[b].second);
                                }
                            }
                }
                size_t active = 0;
                for (int v = 0; v < kLeafVoxels; ++v)
                    active += bestTri[v] >= 0;
                if (active == 0)
                    continue;
                auto* leaf =
                    new openvdb::FloatTree::LeafNodeType(openvdb::Coord(ox, oy, oz), background);
                openvdb::Vec3fTree::LeafNodeType* cleaf =
                    coloured ? new openvdb::Vec3fTree::LeafNodeType(openvdb::Coord(ox, oy, oz),
                                                                    openvdb::Vec3f(0.0f))
                             : nullptr;
                for (int v = 0; v < kLeafVoxels; ++v) {
                    if (bestTri[v] < 0)
                        continue;
                    const Tri& t = tris[size_t(bestTri[v])];
                    const dvec3 p(ox + (v >> 6), oy + ((v >> 3) & 7), oz + (v & 7));
                    Feature f;
                    const dvec3 c = closestOnTriangle(p, t, f);
                    const dvec3 d = p - c;
                    const double dist = std::sqrt(glm::dot(d, d));
                    const bool inside = glm::dot(d, t.normal[f]) < 0.0;
                    leaf->setValueOn(openvdb::Index(v), float((inside ? -dist : dist) * h));
                    if (cleaf) {
                        const dvec3 bc = barycentric(c, t);
                        const openvdb::Vec3s col = mesh.colors[t.v[0]] * float(bc.x) +
                                                   mesh.colors[t.v[1]] * float(bc.y) +
                                                   mesh.colors[t.v[2]] * float(bc.z);
                        cleaf->setValueOn(openvdb::Index(v), col);
                    }
                }
                band.surface[l] = leaf;
                band.color[l] = cleaf;
                band.active[l] = active;
            }
            progress("distances", double(r.end()) / double(nLeaves));
        });

    BakedGrids out;
    out.stats.voxelSize = h;
    out.stats.candidateLeaves = nLeaves;
    createGrids(out, h, background, openvdb::Vec3f(0.0f));
    assembleGrids(out, band, out.stats, out.stats.timings, /*leafSigns=*/false);
    if (!coloured)
        out.color.reset();
    if (opt.fog)
        addFog(out);
    out.stats.seconds = secondsSince(start);
    return out;
}

}  // namespace cambium
