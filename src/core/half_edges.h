// cambium — the half-edges of a polygon mesh: which face runs each edge the
// other way.  One search serves the control meshes of subdivision and the
// closed meshes baked into level sets.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cambium {

/// A polygon mesh as its faces' corners: face f's are corner[begin(f) ..
/// end(f)), from `first` (faces + 1 offsets) or, where faceSize is set, all
/// of that size.  Corner c's edge runs from point corner[c] to the next
/// corner of its face.
struct FaceCorners {
    const size_t* first;  ///< faces + 1 offsets, or null with faceSize
    size_t faces;
    size_t faceSize;  ///< every face's corners, or 0: see first
    const uint32_t* corner;
    size_t points;  ///< every corner < points (the caller checks)

    size_t begin(size_t f) const { return faceSize ? f * faceSize : first[f]; }
    size_t end(size_t f) const { return begin(f + 1); }
    size_t corners() const { return begin(faces); }
    size_t faceOf(size_t c) const;      ///< the face corner c belongs to
    size_t next(size_t c) const;        ///< the next corner of c's face
    size_t previous(size_t c) const;    ///< the corner before c in its face
    bool repeatsPoint(size_t f) const;  ///< face f uses a point twice
};

struct HalfEdges {
    static constexpr uint32_t kNone = UINT32_MAX;
    /// Each corner's twin: the corner whose edge runs the same two points
    /// the other way, or kNone (a boundary edge).  A face that uses a point
    /// twice has no edges of its own: its corners have no twin.
    std::vector<uint32_t> twin;
    /// The corners at each point, as compressed rows: point p's are
    /// around[start[p] .. start[p + 1]) (the faces that use a point twice
    /// included).
    std::vector<uint32_t> start, around;
    /// The first corner (in corner order) whose edge another face runs the
    /// same way, or which more than one face runs the other way (a
    /// non-manifold edge or faces not consistently oriented); kNone if none.
    size_t firstBad = kNone;
};

/// The half-edges of `mesh`, on all cores.
HalfEdges findHalfEdges(const FaceCorners& mesh);

}  // namespace cambium
