// cambium — `cambium shape` as a library call: a shape file synthesised and
// written as a mesh, or baked into a level set.
#pragma once

#include "bake/levelset.h"
#include "core/system.h"

#include <functional>
#include <optional>
#include <string>

namespace cambium {

struct ShapeRequest {
    std::string input;                ///< the shape file
    std::string output;               ///< .vdb (a level set), .obj or .ply (a mesh)
    std::optional<double> voxelSize;  ///< default: 512 voxels across the mesh
    int levels = -1;                  ///< overrides the file's (>= 0)
    double halfWidth = 3.0;
    bool fog = false, half = false;
    Device device = Device::OpenCL;  ///< bakes of captured models
};

struct ShapeCallbacks {
    std::function<void(const char*, double)> progress;
};

struct ShapeReport {
    int levels = 0;
    size_t vertices = 0, faces = 0;
    double synthesisSeconds = 0.0, bakeSeconds = 0.0, writeSeconds = 0.0;
    bool levelSet = false;
    double voxelSize = 0.0;
    bool autoVoxelSize = false;
    BakeStats stats;                  ///< of the bake (level sets)
    double area = 0.0, volume = 0.0;  ///< of the mesh (volume: closed meshes)
    double peakMemoryBytes = 0.0;
};

/// Checks everything first (the shape file, the output path and format, the
/// levels, the voxel size and the memory both steps need: InputError naming
/// the problem), then synthesises, and writes the mesh or bakes the level set
/// (`surface` and `Cd`, cambium metadata) through the checked writer.
ShapeReport runShape(const ShapeRequest& request, const ShapeCallbacks& callbacks = {});

}  // namespace cambium
