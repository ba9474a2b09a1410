// cambium — the 3D turtle of "The Algorithmic Beauty of Plants": a derived
// L-system string to a skeleton of internodes.
#pragma once

#include "model/lsystem.h"
#include "model/skeleton.h"

namespace cambium {

/// Interprets a module string (ABOP chapter 1.5 and 2):
///   F(l) draw forward (an internode), f(l) move forward without drawing
///   (default length: `step:`); + - turn left/right about U, & ^ pitch
///   down/up about L, \ / roll left/right about H (default angle: `angle:`);
///   | turn around; [ ] push and pop the state; !(w) or #(w) set the width (a
///   diameter; internodes get radius w/2 at both ends), ! and # without a
///   parameter take or add the width increment; ' or ; add one to the colour
///   index (with a parameter: set it), which colours internodes and polygons
///   (paletteColour); { starts a polygon at the turtle's position, each F or
///   f inside moves and records a vertex (G and g move without one), . records
///   one, } closes it into a leaf blade (an Organ fitted to the polygon); G
///   and g outside a polygon are F and f; ~ and @ are refused; $ roll so that L is
///   horizontal; % cut: the branch's last internode ends in a saw cut (a
///   plane through its end, across its axis) and the rest of the branch is
///   skipped; % before the branch drew anything: the organ was shed, leaving
///   a scar (a stub of radius w/2 along the heading, reaching half its radius
///   beyond the parent's bark, and a negative field at its end); with
///   `tropism: x y z e`, after
///   every F the heading bends towards T by e |H x T|.  Other modules (A, B,
///   L, ...) are not turtle commands and draw nothing.  The turtle starts at the origin heading up
///   (+y) with its left L = +x and up U = -z, so that seen from +z (x right, y up) `+` turns
///   counter-clockwise as in ABOP's planar figures.
/// Each internode records its parent (the last internode drawn before it on
/// the way from the root), its branch order (the number of '[' it is nested
/// in) and the index of the F module that made it.
Skeleton interpretTurtle(const LSystem& system, const ModuleString& modules);

/// The colour of colour index `index`: the file's "color:" entry, else the
/// default palette (0 bark, 1-7 greens from dark to light, 8-11 yellow,
/// orange, red, white; larger indices take the last).
glm::dvec3 paletteColour(const LSystem& system, int index);

}  // namespace cambium
