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
    // Each corner's face and the point its edge runs to.
    std::vector<uint32_t> face(nc), to(nc);
    std::vector<uint8_t> repeats(nf);
    tbb::parallel_for(size_t(0), nf, [&](size_t f) {
        repeats[f] = mesh.repeatsPoint(f);
        const size_t b = mesh.begin(f), e = mesh.end(f);
        for (size_t c = b; c < e; ++c) {
            face[c] = uint32_t(f);
            to[c] = mesh.corner[c + 1 < e ? c + 1 : b];
        }
    });
    // Corner c runs a -> b: its twin is the one corner at b whose edge runs
    // b -> a; another corner at a that runs a -> b is one too many.
    out.twin.assign(nc, HalfEdges::kNone);
    std::atomic<size_t> firstBad{HalfEdges::kNone};
    tbb::parallel_for(size_t(0), nc, [&](size_t c) {
        if (repeats[face[c]])
            return;
        const uint32_t a = mesh.corner[c], b = to[c];
        bool bad = false;
        for (uint32_t k = out.start[a]; k < out.start[a + 1]; ++k) {
            const uint32_t d = out.around[k];
            bad |= d != c && to[d] == b && !repeats[face[d]];
        }
        uint32_t twin = HalfEdges::kNone;
        for (uint32_t k = out.start[b]; k < out.start[b + 1]; ++k) {
            const uint32_t d = out.around[k];
            if (to[d] == a && !repeats[face[d]]) {
                bad |= twin != HalfEdges::kNone;
                twin = d;
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
    return out;
}

}  // namespace cambium
