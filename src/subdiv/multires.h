// cambium — multi-resolution Catmull-Clark surfaces (paper 004, section 2.2):
// a control mesh, uniform subdivision (OpenSubdiv), and at every finer level
// a detail offset per vertex in the local frame of the subdivided surface.
//
// Synthesis, level by level: subdivide level l (its points and scalars) into
// level l + 1's subdivided points Q; frames from Q; P = Q + (t b n) d; the
// scalar likewise plus its detail.  Analysis is the inverse: given where each
// level's points should be, the details that put them there.  A level's
// frames are computed from Q alone, which depends only on the coarser level:
// editing level l's details never changes level l's frames.
#pragma once

#include "io/mesh_file.h"
#include "subdiv/control_mesh.h"

#include <glm/glm.hpp>

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

namespace cambium {

/// OpenSubdiv's uniform refinement stops at 15 levels.
constexpr int kMaxSubdivisionLevels = 15;

/// A vertex's local frame: unit tangent, bitangent and outward normal,
/// right-handed (b = n x t).  A detail d is the offset d.x t + d.y b + d.z n.
struct Frame {
    glm::dvec3 t{1, 0, 0}, b{0, 1, 0}, n{0, 0, 1};
    glm::dvec3 toWorld(const glm::dvec3& d) const { return d.x * t + d.y * b + d.z * n; }
    glm::dvec3 toLocal(const glm::dvec3& w) const
    {
        return {glm::dot(w, t), glm::dot(w, b), glm::dot(w, n)};
    }
};

/// One level of the surface: its topology (faces, quads above level 0) and
/// what synthesis made of it.
struct SubdivLevel {
    // Topology (fixed when the surface is made).
    std::vector<int> faceSizes, faceVerts;  ///< as in ControlMesh
    std::vector<int> faceStart;             ///< face f's corners: faceVerts[faceStart[f]...]
    std::vector<int> vertexFaceStart,
        vertexFaces;                        ///< faces around vertex v: [start[v], start[v+1])
    std::vector<std::array<int, 2>> edges;  ///< each edge once
    std::vector<int> tangentNeighbour;      ///< per vertex: the far end of its first edge
    std::vector<uint8_t> boundary;          ///< per vertex: on the mesh's boundary
    // Synthesis.
    std::vector<glm::dvec3> subdivided;    ///< Q: the coarser level subdivided (level 0: the base)
    std::vector<double> subdividedScalar;  ///< the coarser scalar subdivided (level 0: the base's)
    std::vector<Frame> frames;             ///< from Q
    std::vector<glm::dvec3> detail;        ///< per vertex, in its frame
    std::vector<double> scalarDetail;      ///< per vertex, added to the subdivided scalar
    std::vector<glm::dvec3> points;        ///< P = Q + frames * detail
    std::vector<double> scalar;            ///< the scalar channel after its detail
    double meanEdgeLength = 0.0;           ///< of Q

    size_t vertexCount() const { return tangentNeighbour.size(); }
    size_t faceCount() const { return faceSizes.size(); }
};

class MultiresSurface {
public:
    /// Refines the topology of `base` (checked by checkControlMesh; a closed
    /// mesh enclosing a negative volume has its faces reversed, so that normals
    /// point outwards; open meshes keep their boundary curves: edges and
    /// corners interpolated) to
    /// `levels` levels (0 to 15; InputError beyond).  All details start at
    /// zero; the points are not synthesised yet.
    MultiresSurface(const ControlMesh& base, int levels, const std::string& what);
    ~MultiresSurface();
    MultiresSurface(const MultiresSurface&) = delete;
    MultiresSurface& operator=(const MultiresSurface&) = delete;

    int levels() const { return int(levels_.size()) - 1; }
    const SubdivLevel& level(int l) const { return levels_[size_t(l)]; }
    SubdivLevel& level(int l) { return levels_[size_t(l)]; }
    const SubdivLevel& finest() const { return levels_.back(); }

    /// Called during synthesis once level l's Q and frames are known and
    /// before its details are added: it may write level l's detail and
    /// scalarDetail (procedural detail reads the evolving surface there).
    using DetailHook = std::function<void(int level, SubdivLevel&)>;

    /// Synthesis of every level from the base points and scalars; `hook`
    /// (optional) sets details on the way.  With all details zero this is
    /// plain Catmull-Clark subdivision, bit for bit.
    void synthesize(const DetailHook& hook = {});
    /// Synthesis of levels from..levels() only (the coarser ones as they
    /// are): an edit of level `from`'s details re-synthesises from there.
    void synthesizeFrom(int from, const DetailHook& hook = {});

    /// Where a level's subdivided point should go (`q`, with its frame and the
    /// level's mean edge length): a point of the fine surface.
    using Target =
        std::function<glm::dvec3(const glm::dvec3& q, const Frame& frame, double edgeLength)>;
    /// Analysis: at each level, details that move each subdivided point to
    /// target(q, ...); synthesis then reproduces those points (to rounding).
    void analyse(const Target& target);

    /// The limit positions of the finest level's vertices (OpenSubdiv's limit
    /// evaluation of the finest points), and their unit limit normals.
    void limit(std::vector<glm::dvec3>& position, std::vector<glm::dvec3>& normal) const;

    /// Pairs of values per vertex of level l - 1 subdivided to level l, as
    /// the scalar channel is (other channels carried through the levels).
    std::vector<glm::dvec2> subdivideValues(int l, const std::vector<glm::dvec2>& coarse) const;

private:
    void subdivide(int l);  // level l's Q and scalar from level l - 1
    void computeFrames(SubdivLevel& lv) const;
    void applyDetails(SubdivLevel& lv) const;

    struct Refiner;
    std::unique_ptr<Refiner> refiner_;
    std::vector<SubdivLevel> levels_;
};

/// Unit, outward vertex normals of a quad (or polygon) mesh level from
/// `points`: the sum of its faces' vector areas at each vertex.
std::vector<glm::dvec3> vertexNormals(const SubdivLevel& topology,
                                      const std::vector<glm::dvec3>& points);

/// A level's synthesised points as a mesh: its faces kept as polygons
/// (quads above level 0), fanned into triangles, unit outward normals
/// (vertexNormals); no colours.  `points` (one per vertex) replace the
/// level's synthesised points when given.
TriangleMesh levelMesh(const SubdivLevel& level, const std::vector<glm::dvec3>* points = nullptr);

}  // namespace cambium
