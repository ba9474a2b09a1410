// cambium — control mesh checks and measures.
#include "subdiv/control_mesh.h"

#include "core/error.h"
#include "core/half_edges.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

namespace cambium {

namespace {

/// Point or face i as the mesh's file numbers it (ControlMesh::firstIndex).
size_t numbered(const ControlMesh& mesh, size_t i)
{
    return i + size_t(mesh.firstIndex);
}

[[noreturn]] void refuse(const std::string& what, const std::string& problem)
{
    throw InputError(fmt::format("{}: {}", what, problem));
}

/// Face corners: face f's corners are verts[first[f] .. first[f + 1]).
std::vector<size_t> faceStarts(const ControlMesh& mesh, const std::string& what)
{
    std::vector<size_t> first(mesh.faceSizes.size() + 1, 0);
    for (size_t f = 0; f < mesh.faceSizes.size(); ++f) {
        if (mesh.faceSizes[f] < 3)
            refuse(what, fmt::format("face {} has {} corners (a face needs at least 3)",
                                     numbered(mesh, f), mesh.faceSizes[f]));
        if (mesh.faceSizes[f] > 255)
            refuse(what, fmt::format("face {} has {} corners (at most 255)", numbered(mesh, f),
                                     mesh.faceSizes[f]));
        first[f + 1] = first[f] + size_t(mesh.faceSizes[f]);
    }
    if (first.back() != mesh.faceVerts.size())
        refuse(what, fmt::format("the faces list {} corners but {} are given", first.back(),
                                 mesh.faceVerts.size()));
    return first;
}

}  // namespace

MeshTopologyStats checkControlMesh(const ControlMesh& mesh, const std::string& what)
{
    const size_t nv = mesh.points.size(), nf = mesh.faceSizes.size();
    const auto n = [&](size_t i) { return numbered(mesh, i); };
    if (nf == 0)
        refuse(what, "the mesh has no faces");
    for (size_t i = 0; i < nv; ++i) {
        const glm::dvec3& p = mesh.points[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            refuse(what, fmt::format("point {} is not finite", n(i)));
    }
    if (!mesh.scalar.empty() && mesh.scalar.size() != nv)
        refuse(what, fmt::format("{} scalars for {} points", mesh.scalar.size(), nv));
    const std::vector<size_t> first = faceStarts(mesh, what);
    std::vector<uint32_t> corner(mesh.faceVerts.size());
    for (size_t f = 0; f < nf; ++f)
        for (size_t c = first[f]; c < first[f + 1]; ++c) {
            const int a = mesh.faceVerts[c];
            if (a < 0 || size_t(a) >= nv)
                refuse(what, fmt::format("face {} uses point {}, but there are {} points", n(f),
                                         a + mesh.firstIndex, nv));
            for (size_t j = first[f]; j < c; ++j)
                if (mesh.faceVerts[j] == a)
                    refuse(what, fmt::format("face {} uses point {} twice", n(f), n(size_t(a))));
            corner[c] = uint32_t(a);
        }

    // Every edge run at most once each way (core/half_edges.h).
    const FaceCorners faces{first.data(), nf, 0, corner.data(), nv};
    const HalfEdges he = findHalfEdges(faces);
    if (he.firstBad != HalfEdges::kNone) {
        const size_t c = he.firstBad;
        refuse(what, fmt::format("the edge {}-{} is run the same way by two faces, or shared by "
                                 "more than two (face {} and another): the faces are not "
                                 "consistently oriented, or the mesh is not a 2-manifold",
                                 n(corner[c]), n(corner[faces.next(c)]), n(faces.faceOf(c))));
    }
    for (size_t i = 0; i < nv; ++i)
        if (he.start[i] == he.start[i + 1])
            refuse(what, fmt::format("point {} is used by no face", n(i)));

    MeshTopologyStats st;
    st.vertices = nv;
    st.faces = nf;
    st.boundaryEdges = size_t(std::count(he.twin.begin(), he.twin.end(), HalfEdges::kNone));
    st.edges = (corner.size() + st.boundaryEdges) / 2;

    // The faces around each point must be one fan: walk from a corner at the
    // point to the next face's (across the edge into the point from the
    // corner before it) and count the faces reached.  Start from a boundary
    // sector if there is one (a corner whose edge no face runs back), so
    // that an open fan is walked whole.
    for (size_t v = 0; v < nv; ++v) {
        const uint32_t* at = he.around.data() + he.start[v];
        const size_t count = he.start[v + 1] - he.start[v];
        const uint32_t* open = std::find_if(
            at, at + count, [&](uint32_t c) { return he.twin[c] == HalfEdges::kNone; });
        const uint32_t c0 = open != at + count ? *open : at[0];
        size_t reached = 0;
        uint32_t c = c0;
        do {
            ++reached;
            c = he.twin[faces.previous(c)];
        } while (c != HalfEdges::kNone && c != c0 && reached <= count);
        if (reached != count)
            refuse(what, fmt::format("the faces around point {} are not one fan (a non-manifold "
                                     "point: {} of its {} faces are connected)",
                                     n(v), reached, count));
    }
    return st;
}

double enclosedVolume(const ControlMesh& mesh)
{
    double v = 0.0;
    size_t c = 0;
    for (int n : mesh.faceSizes) {
        const glm::dvec3& a = mesh.points[mesh.faceVerts[c]];
        for (int k = 1; k + 1 < n; ++k)
            v += glm::dot(a, glm::cross(mesh.points[mesh.faceVerts[c + k]],
                                        mesh.points[mesh.faceVerts[c + k + 1]]));
        c += size_t(n);
    }
    return v / 6.0;
}

double surfaceArea(const ControlMesh& mesh)
{
    double a = 0.0;
    size_t c = 0;
    for (int n : mesh.faceSizes) {
        glm::dvec3 s(0.0);
        for (int k = 0; k < n; ++k)
            s += glm::cross(mesh.points[size_t(mesh.faceVerts[c + size_t(k)])],
                            mesh.points[size_t(mesh.faceVerts[c + size_t((k + 1) % n)])]);
        a += 0.5 * glm::length(s);
        c += size_t(n);
    }
    return a;
}

double meanEdgeLength(const ControlMesh& mesh)
{
    double sum = 0.0;
    size_t c = 0;
    for (int n : mesh.faceSizes) {
        for (int k = 0; k < n; ++k)
            sum += glm::length(mesh.points[size_t(mesh.faceVerts[c + size_t(k)])] -
                               mesh.points[size_t(mesh.faceVerts[c + size_t((k + 1) % n)])]);
        c += size_t(n);
    }
    return c ? sum / double(c) : 0.0;
}

void reverseFaces(ControlMesh& mesh)
{
    size_t c = 0;
    for (int n : mesh.faceSizes) {
        std::reverse(mesh.faceVerts.begin() + long(c), mesh.faceVerts.begin() + long(c + n));
        c += size_t(n);
    }
}

}  // namespace cambium
