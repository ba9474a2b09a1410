// cambium — the grids a baked file holds, and their names: defined once for
// the writer, the readers and every command.
#pragma once

#include <openvdb/openvdb.h>

#include <memory>

namespace cambium {

class PackedLeaves;

/// The level set: signed distance in world units, negative inside, class
/// GRID_LEVEL_SET (the name renderers look for).
inline constexpr const char* kSurfaceGrid = "surface";
/// The blended colour on the band (Vec3f, Houdini's attribute name).
inline constexpr const char* kColorGrid = "Cd";
/// The optional fog volume made from the level set (OpenVDB's sdfToFogVolume).
inline constexpr const char* kDensityGrid = "density";

/// The grids of one baked frame; `color` and `density` may be null.
struct LevelSetGrids {
    openvdb::FloatGrid::Ptr surface;
    openvdb::Vec3fGrid::Ptr color;
    openvdb::FloatGrid::Ptr density;
    /// Where set, that grid's leaves hold their value masks only (no values)
    /// and their buffers are here, serialised for the writer (io/vdb.h): a
    /// grid that only writeVdb can use.
    std::shared_ptr<const PackedLeaves> surfacePacked, colorPacked;
};

}  // namespace cambium
