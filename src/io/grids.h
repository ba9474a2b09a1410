// cambium — the grids a baked file holds, and their names: defined once for
// the writer, the readers and every command.
#pragma once

#include <openvdb/openvdb.h>

#include <memory>

// The two grid types cambium makes are compiled once, in io/grids.cpp and
// io/grids_vec3f.cpp.  A source that creates a grid would otherwise compile
// every virtual member of Grid and Tree for it at -O3 (src/bake/assembly.cpp:
// 33 s, 650 KB of code; with these declarations 14 s, 114 KB).  Every source
// that includes OpenVDB includes it through this header.
extern template class openvdb::tree::Tree<openvdb::FloatTree::RootNodeType>;
extern template class openvdb::tree::Tree<openvdb::Vec3fTree::RootNodeType>;
extern template class openvdb::Grid<openvdb::FloatTree>;
extern template class openvdb::Grid<openvdb::Vec3fTree>;

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
