// cambium — `cambium shape` as a library call: a shape file synthesised and
// written as a mesh, or baked into a level set.
#pragma once

#include "bake/options.h"
#include "core/system.h"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace cambium {

struct ShapeRequest {
    std::string input;                ///< the shape file
    std::string output;               ///< .vdb (a level set), .obj or .ply (a mesh)
    std::optional<double> voxelSize;  ///< default: 512 voxels across the mesh
    int levels = -1;                  ///< overrides the file's (>= 0)
    double halfWidth = 3.0;
    bool fog = false, half = false;
    ColourExtent colour = ColourExtent::Shell;  ///< where a .vdb keeps Cd
    Device device = Device::OpenCL;             ///< bakes of captured models
    double time = 0.0;                          ///< the animation time of a single output
    /// A sequence: frames FIRST-LAST[:STEP] (frame f at time f) into an
    /// output pattern with a run of '#'; --resume keeps finished frames.
    std::string frames;
    bool resume = false;
};

struct ShapeFrame {
    long long frame = 0;
    std::string path;
    bool skipped = false;  ///< --resume found it finished
    double seconds = 0.0;
    size_t activeVoxels = 0;
};

struct ShapeCallbacks {
    std::function<void(const char*, double)> progress;
    std::function<void(const std::string&)> notice;  ///< things to know that are not errors
    std::function<void(const ShapeFrame&)> frameDone;
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
    std::vector<ShapeFrame> frames;  ///< a sequence's, in order
    bool animated = false;           ///< the file has keyframed numbers
};

/// Checks everything first (the shape file, the output path and format, the
/// levels, the voxel size and the memory both steps need: InputError naming
/// the problem), then synthesises, and writes the mesh or bakes the level set
/// (`surface` and `Cd`, cambium metadata) through the checked writer.  A
/// sequence (request.frames) reads the file at every frame's time first,
/// refines the base once, sizes the voxels from the first frame (the same
/// for every frame) and writes through the growth bakes' sequence writer
/// (SequenceOutput: lock, atomic frames, --resume, the sequence key).
ShapeReport runShape(const ShapeRequest& request, const ShapeCallbacks& callbacks = {});

/// InputError naming `what` when a mesh's level set, a band of `area` at
/// `voxelSize` and `halfWidth` voxels, would not fit in memory.
void checkBakeMemory(double area, double voxelSize, double halfWidth, const std::string& what);

}  // namespace cambium
