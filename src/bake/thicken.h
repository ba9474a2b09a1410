// cambium — a bake's smallest radius: parts of a model thinner than a few
// voxels (twigs, the sheets of polygon leaves) are thickened to it before
// they are sampled, as OpenVDB's ParticlesToLevelSet has a smallest radius
// (docs/baking.md, "Thin parts").  A level set cannot hold a feature
// thinner than its voxels: one baked as it is comes out as voxel-sized
// blocks, broken twigs and holes, and fails OpenVDB's Eikonal check.
#pragma once

#include "blobtree/blobtree.h"

#include <cstddef>
#include <limits>
#include <string>

namespace cambium {

/// The bake's default smallest radius, in voxels (--min-radius).
constexpr double kDefaultMinRadiusVoxels = 2.0;
/// The largest --min-radius: beyond, a bake thickens what it should resolve
/// (a smaller voxel size does that).
constexpr double kMaxMinRadiusVoxels = 4.0;
/// The most a part is thickened, as a factor of its radius.  A part far
/// thinner than a voxel (a twig of a twentieth of one, baked coarsely) is
/// detail the voxels cannot hold: thickened all the way, a crown of them
/// becomes a mass whose every leaf sums hundreds of primitives (the
/// 27-year Populus at 0.08 on the CPU: 305 instructions a leaf and 5.8 times
/// the bake's time, against 108 as they are).  Capped at 8 it takes 2.8
/// times, 154 a leaf, and the examples stay within 3 % of Eikonal outliers
/// at their automatic voxel sizes (capped at 4 the Populus's twigs came out
/// as broken beads, 13.6 %: docs/baking.md, "Thin parts").
constexpr double kMaxThickening = 8.0;

/// InputError unless a smallest radius (voxels) is from 0 to
/// kMaxMinRadiusVoxels.
void checkMinRadius(double voxels);

struct Thickened {
    size_t parts = 0;     ///< primitives (and leaf transforms) thickened
    size_t positive = 0;  ///< primitives with a surface of their own (positive weight)
    /// The thinnest part's radius before (world units; infinity when none
    /// was thickened).
    double thinnest = std::numeric_limits<double>::infinity();
};

/// Thickens every part of `tree` whose surface is thinner than `minRadius`
/// (world units; 0: none) to it, or to kMaxThickening times its radius where
/// that is less: a primitive's radii (across its axis, in
/// world space: under the transforms and tapers above it), and a sphere that
/// a transform of its own squashes (an ellipsoid: a polygon leaf) along its
/// thin axes only, its length and width kept.  Primitives of negative weight
/// (scars), what a difference subtracts and a bounded blend's bounding field
/// are not surfaces and are left.  Thick models are left unchanged.
Thickened thickenThinParts(BlobTree& tree, double minRadius);

}  // namespace cambium
