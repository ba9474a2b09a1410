// cambium — the half-edges of a polygon mesh.
#include "core/half_edges.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>

namespace cambium {

size_t FaceCorners::faceOf(size_t c) const
{
    if (faceSize)
        return c / faceSize;
    return size_t(std::upper_bound(first, first + faces + 1, c) - first) - 1;
}

size_t FaceCorners::next(size_t c) const
{
    const size_t f = faceOf(c);
    return c + 1 < end(f) ? c + 1 : begin(f);
}

size_t FaceCorners::previous(size_t c) const
{
    const size_t f = faceOf(c);
    return c > begin(f) ? c - 1 : end(f) - 1;
}

bool FaceCorners::repeatsPoint(size_t f) const
{
    for (size_t i = begin(f); i < end(f); ++i)
        for (size_t j = begin(f); j < i; ++j)
            if (corner[i] == corner[j])
                return true;
    return false;
}

namespace {

/// Each corner's twin and the first bad corner, with the corners' next,
/// previous and face given as functions (arithmetic for faces of one size).
/// Corner c runs a -> b: its twin is the corner before the one corner at a
/// whose face comes from b (that face runs b -> a); another corner at a
/// that runs a -> b, or a second face coming from b, is one too many.
template <typename Next, typename Previous, typename Face>
void findTwins(const FaceCorners& mesh, const std::vector<uint8_t>& repeats, Next next,
               Previous previous, Face face, HalfEdges& out)
{
    const uint32_t* corner = mesh.corner;
    out.twin.assign(mesh.corners(), HalfEdges::kNone);
    std::atomic<size_t> firstBad{HalfEdges::kNone};
    tbb::parallel_for(size_t(0), mesh.corners(), [&](size_t c) {
        if (repeats[face(c)])
            return;
        const uint32_t a = corner[c], b = corner[next(c)];
        bool bad = false;
        uint32_t twin = HalfEdges::kNone;
        for (uint32_t k = out.start[a]; k < out.start[a + 1]; ++k) {
            const uint32_t d = out.around[k];
            if (d == c || repeats[face(d)])
                continue;
            bad |= corner[next(d)] == b;
            const uint32_t p = uint32_t(previous(d));
            if (corner[p] == b) {
                bad |= twin != HalfEdges::kNone;
                twin = p;
            }
        }
        out.twin[c] = twin;
        if (bad) {
            size_t cur = firstBad.load();
            while (c < cur && !firstBad.compare_exchange_weak(cur, c)) {
            }
        }
    });
    out.firstBad = firstBad;
}

}  // namespace

HalfEdges findHalfEdges(const FaceCorners& mesh)
{
    const size_t nf = mesh.faces, nc = mesh.corners();
    HalfEdges out;
    // The corners at each point.
    out.start.assign(mesh.points + 1, 0);
    for (size_t c = 0; c < nc; ++c)
        ++out.start[mesh.corner[c] + 1];
    for (size_t p = 0; p < mesh.points; ++p)
        out.start[p + 1] += out.start[p];
    out.around.resize(nc);
    {
        std::vector<uint32_t> fill(out.start.begin(), out.start.end() - 1);
        for (size_t c = 0; c < nc; ++c)
            out.around[fill[mesh.corner[c]]++] = uint32_t(c);
    }
    std::vector<uint8_t> repeats(nf);
    tbb::parallel_for(size_t(0), nf, [&](size_t f) { repeats[f] = mesh.repeatsPoint(f); });
    if (mesh.faceSize) {
        const size_t n = mesh.faceSize;
        findTwins(
            mesh, repeats, [n](size_t c) { return c % n == n - 1 ? c + 1 - n : c + 1; },
            [n](size_t c) { return c % n == 0 ? c + n - 1 : c - 1; },
            [n](size_t c) { return c / n; }, out);
        return out;
    }
    // Polygons: each corner's face, next and previous corner.
    std::vector<uint32_t> face(nc), next(nc), previous(nc);
    tbb::parallel_for(size_t(0), nf, [&](size_t f) {
        const size_t b = mesh.begin(f), e = mesh.end(f);
        for (size_t c = b; c < e; ++c) {
            face[c] = uint32_t(f);
            next[c] = uint32_t(c + 1 < e ? c + 1 : b);
            previous[c] = uint32_t(c > b ? c - 1 : e - 1);
        }
    });
    findTwins(
        mesh, repeats, [&](size_t c) { return next[c]; }, [&](size_t c) { return previous[c]; },
        [&](size_t c) { return face[c]; }, out);
    return out;
}

}  // namespace cambium
