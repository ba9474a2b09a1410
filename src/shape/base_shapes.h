// cambium — the built-in base shapes of shape files (docs/shape-format.md):
// a control mesh and, for shapes that are not a subdivision surface of their
// own (sphere, torus, fuse), the exact surface that analysis fits every
// level's points to.
#pragma once

#include "subdiv/multires.h"

#include <string>

namespace cambium {

struct BaseShape {
    ControlMesh mesh;
    /// The exact surface: where a subdivided point belongs on it (analytic
    /// bases); empty when the subdivision surface of `mesh` is the shape.
    MultiresSurface::Target target;
};

/// The cube [-size/2, size/2]^3: 8 points, 6 quads (its Catmull-Clark limit
/// has corners at +-size/4 and face centres at +-(68/81) size/2).
BaseShape cubeBase(double size);

/// A sphere of `radius` about the origin: the cube's control mesh (each face
/// a grid of `cells` x `cells` quads) projected onto it, every level fitted
/// to the sphere (points radially projected).
BaseShape sphereBase(double radius, int cells = 1);

/// A torus about the z axis (tube centre `major` from the axis, tube radius
/// `minor`): a grid of `around` x `tube` quads, every level fitted to it
/// (points moved to the nearest point of the torus).
BaseShape torusBase(double major, double minor, int around, int tube);

/// A flat square `size` wide in the z = 0 plane, normal +z, `cells` x `cells`
/// quads, with a boundary (its edges and corners kept by subdivision).
BaseShape planeBase(double size, int cells);

/// The fuse of paper 004, section 6.1: a surface of revolution about the z
/// axis, from z = 0 to `length`, of radius `radius` * fuseProfile(pi z / length).
/// Rings of `around` quads, triangle fans at the two poles; every level
/// fitted to it (points moved radially at their height).
BaseShape fuseBase(double length, double radius, int terms, int around, int rings);

/// The fuse's profile at t in [0, pi]: sin(sum_{i<terms} 2^-i sin(2^i t))
/// (our reading of the paper's garbled formula: docs/shape-format.md).  It is
/// >= 0 on [0, pi] for 1 or 2 terms, and 0 at both ends.
double fuseProfile(double t, int terms);

}  // namespace cambium
