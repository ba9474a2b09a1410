// cambium — polygon control meshes for Catmull-Clark subdivision: their
// check (a 2-manifold, consistently oriented) and their measures.
#pragma once

#include <glm/glm.hpp>

#include <string>
#include <vector>

namespace cambium {

/// A polygon mesh: faces of any size (at least 3), counter-clockwise seen
/// from outside; `scalar` (empty, or one per point) is the channel a shader
/// reads (Cd of a bake).
struct ControlMesh {
    std::vector<glm::dvec3> points;
    std::vector<int> faceSizes;
    std::vector<int> faceVerts;  ///< each face's corners in turn
    std::vector<double> scalar;
    /// How messages number its points and faces: as its file does (OBJ
    /// from 1; PLY and the built-in shapes from 0).
    int firstIndex = 0;

    size_t faceCount() const { return faceSizes.size(); }
};

/// Edges, boundary edges and the Euler characteristic V - E + F.
struct MeshTopologyStats {
    size_t vertices = 0, edges = 0, faces = 0, boundaryEdges = 0;
    long eulerCharacteristic() const { return long(vertices) - long(edges) + long(faces); }
    bool closed() const { return boundaryEdges == 0; }
};

/// Checks that `mesh` can be subdivided: finite points, faces of 3 or more
/// distinct corners that exist, every point used, every edge shared by at
/// most two faces that run it in opposite directions (a consistently oriented
/// 2-manifold), the faces around each point one fan.  InputError naming
/// `what` (the file or shape) and the first problem, with its face or point
/// (numbered from mesh.firstIndex).
MeshTopologyStats checkControlMesh(const ControlMesh& mesh, const std::string& what);

/// The volume a closed mesh encloses (divergence theorem over its faces
/// fanned from their first corner): positive when the faces face outwards.
double enclosedVolume(const ControlMesh& mesh);

/// The summed area of the faces (each its vector area's length, Newell).
double surfaceArea(const ControlMesh& mesh);

/// The mean length of the faces' edges (an inner edge counted from each side).
double meanEdgeLength(const ControlMesh& mesh);

/// Reverses every face's corner order (outward <-> inward).
void reverseFaces(ControlMesh& mesh);

}  // namespace cambium
