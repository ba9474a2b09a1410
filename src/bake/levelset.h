// cambium — baking a FieldProgram into an OpenVDB narrow-band level set.
#pragma once

#include "bake/options.h"
#include "field/program.h"
#include "io/grids.h"

namespace cambium {

/// Cd of grids made whole (a photo's colours, a mesh's) kept on the shell
/// of the surface's zero crossing as ColourExtent::Shell says, from the
/// level set's signs.
void keepColourShell(LevelSetGrids& grids);

/// The grids (io/grids.h: `surface`, `Cd` on the band, `density` with
/// BakeOptions::fog) and how the bake went.
struct BakedGrids : LevelSetGrids {
    BakeStats stats;
};

/// Bakes the field's surface F = T into a narrow band of signed distances:
/// world units, negative inside, background halfWidth * voxelSize, class
/// GRID_LEVEL_SET, name `surface`, plus the blended colour `Cd` on the band.
///
/// 1. topology: leaves that can hold band voxels (findBandLeaves);
/// 2. sampling: the value at every voxel of those leaves;
/// 3. surface points: each voxel next to a sign change of F - T is sampled
///    again for gradient and colour, and gets its distance (T - F)/|grad F|
///    (bounded by the crossings along its edges) and the closest surface
///    point and normal that follow;
/// 4. propagation: directional sweeps hand every voxel the nearest of its
///    neighbours' surface points; its distance is measured to that point's
///    tangent plane (exact for planes, second order for curved surfaces);
/// 5. voxels within the band become active; signedFloodFill sets the rest.
BakedGrids bakeLevelSet(const FieldProgram& program, FieldSampler& sampler,
                        const BakeOptions& options);

/// The grids of a bake with nothing in its band (background everywhere,
/// the same names, class and transform): a growth frame with no surface yet.
BakedGrids emptyLevelSet(const BakeOptions& options);

}  // namespace cambium
