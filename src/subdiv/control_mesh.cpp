// cambium — control mesh checks and measures.
#include "subdiv/control_mesh.h"

#include "core/error.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>
#include <unordered_map>

namespace cambium {

namespace {

uint64_t edgeKey(int a, int b)
{
    return (uint64_t(uint32_t(std::min(a, b))) << 32) | uint32_t(std::max(a, b));
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
            refuse(what, fmt::format("face {} has {} corners (a face needs at least 3)", f,
                                     mesh.faceSizes[f]));
        if (mesh.faceSizes[f] > 255)
            refuse(what, fmt::format("face {} has {} corners (at most 255)", f, mesh.faceSizes[f]));
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
    if (nf == 0)
        refuse(what, "the mesh has no faces");
    for (size_t i = 0; i < nv; ++i) {
        const glm::dvec3& p = mesh.points[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            refuse(what, fmt::format("point {} is not finite", i));
    }
    if (!mesh.scalar.empty() && mesh.scalar.size() != nv)
        refuse(what, fmt::format("{} scalars for {} points", mesh.scalar.size(), nv));
    const std::vector<size_t> first = faceStarts(mesh, what);

    // Each directed edge once; its reverse at most once.
    std::unordered_map<uint64_t, int> uses;  // edge -> +1 per (a<b) run, +2 per (a>b) run
    uses.reserve(mesh.faceVerts.size());
    std::vector<int> valence(nv, 0);
    for (size_t f = 0; f < nf; ++f) {
        const int n = mesh.faceSizes[f];
        for (int k = 0; k < n; ++k) {
            const int a = mesh.faceVerts[first[f] + k];
            const int b = mesh.faceVerts[first[f] + (k + 1) % n];
            if (a < 0 || size_t(a) >= nv)
                refuse(what,
                       fmt::format("face {} uses point {}, but there are {} points", f, a, nv));
            for (int j = 0; j < k; ++j)
                if (mesh.faceVerts[first[f] + j] == a)
                    refuse(what, fmt::format("face {} uses point {} twice", f, a));
            ++valence[a];
            int& u = uses[edgeKey(a, b)];
            const int bit = a < b ? 1 : 2;
            if (u & bit)
                refuse(what, fmt::format("the edge {}-{} is run the same way by two faces (face {} "
                                         "and another): the faces are not consistently oriented, "
                                         "or more than two faces share it (not a 2-manifold)",
                                         a, b, f));
            u |= bit;
        }
    }
    for (size_t i = 0; i < nv; ++i)
        if (valence[i] == 0)
            refuse(what, fmt::format("point {} is used by no face", i));

    MeshTopologyStats st;
    st.vertices = nv;
    st.faces = nf;
    st.edges = uses.size();
    for (const auto& [key, u] : uses)
        if (u != 3)
            ++st.boundaryEdges;

    // The faces around each point must be one fan: walk from a face across
    // shared edges around the point and count the faces reached.
    // outgoing[a] lists (b, face) for each directed edge a -> b.
    std::vector<size_t> start(nv + 1, 0);
    for (size_t i = 0; i < nv; ++i)
        start[i + 1] = start[i] + size_t(valence[i]);
    std::vector<std::pair<int, int>> out(start.back());
    std::vector<size_t> fill(start.begin(), start.end() - 1);
    std::vector<int> prevOf(out.size());  // for edge a->b of face f: the corner before a in f
    for (size_t f = 0; f < nf; ++f) {
        const int n = mesh.faceSizes[f];
        for (int k = 0; k < n; ++k) {
            const int a = mesh.faceVerts[first[f] + k];
            const int b = mesh.faceVerts[first[f] + (k + 1) % n];
            const int p = mesh.faceVerts[first[f] + (k + n - 1) % n];
            prevOf[fill[a]] = p;
            out[fill[a]++] = {b, int(f)};
        }
    }
    for (size_t v = 0; v < nv; ++v) {
        // Around v: the face with outgoing edge v->b also has incoming p->v;
        // the next face around has outgoing edge v->p.
        const size_t s = start[v], e = start[v + 1], n = e - s;
        auto find = [&](int b) -> size_t {
            for (size_t i = s; i < e; ++i)
                if (out[i].first == b)
                    return i;
            return e;
        };
        // Start from a boundary sector if there is one (an outgoing edge whose
        // reverse no face runs), so that an open fan is walked whole.
        size_t i0 = s;
        for (size_t i = s; i < e; ++i) {
            const int b = out[i].first;
            if (uses[edgeKey(int(v), b)] != 3) {
                // Outgoing v->b without b->v: this face begins the fan clockwise.
                bool hasReverse = false;
                for (size_t j = start[b]; j < start[b + 1]; ++j)
                    hasReverse |= out[j].first == int(v);
                if (!hasReverse) {
                    i0 = i;
                    break;
                }
            }
        }
        size_t reached = 0, i = i0;
        do {
            ++reached;
            i = find(prevOf[i]);
        } while (i != e && i != i0 && reached <= n);
        if (reached != n)
            refuse(what, fmt::format("the faces around point {} are not one fan (a non-manifold "
                                     "point: {} of its {} faces are connected)",
                                     v, reached, n));
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
