// cambium — captured models as bases (paper 004, section 2.2's analysis):
// a fine surface given as a level set (a .vdb, or any cambium model baked
// finely), its coarse base meshed from the same surface at a coarse voxel
// size (volumeToMesh at adaptivity 0: all quads), and each level's points
// projected onto the fine surface.
#pragma once

#include "core/system.h"
#include "io/grids.h"
#include "shape/base_shapes.h"
#include "shape/shape.h"

#include <functional>
#include <string>

namespace cambium {

/// The base of a level set: `fine` meshed at `coarseVoxelSize` (resampled),
/// turned outwards, checked as a control mesh (InputError naming `what` and
/// the voxel size when it is not a 2-manifold), and the projection onto the
/// zero crossing of `fine`: along the frame's normal within one edge length
/// (Newton steps on the trilinear distance), else the closest point
/// (p - phi grad phi, repeated); a point outside the band stays.
/// `progress` hears of the resampling.
BaseShape captureLevelSet(openvdb::FloatGrid::ConstPtr fine, double coarseVoxelSize,
                          const std::string& what,
                          const std::function<void(const char*, double)>& progress = {});

/// The projection onto the zero crossing of `fine` that captureLevelSet uses.
MultiresSurface::Target projectionOnto(openvdb::FloatGrid::ConstPtr fine);

/// A mesh file's faces as a control mesh (quads kept).
ControlMesh readControlMesh(const std::string& path);

/// An analysed base of a shape file: the fine surface is the .vdb read, the
/// mesh file baked (bakeMeshLevelSet) or the model baked, at its fine voxel
/// size on `device` (automatic: 256 voxels across); the coarse base is the
/// `control` mesh when given, else the fine surface meshed at the base voxel
/// size (automatic: 48 voxels across).  `progress` hears the model's bake
/// (a base of many summed primitives baked past a minute in silence).
BaseShape captureBase(const BaseSpec& base, const std::string& source, Device device,
                      const std::function<void(const char*, double)>& progress = {});

}  // namespace cambium
