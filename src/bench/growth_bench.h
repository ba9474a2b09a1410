// cambium — `cambium bench growth`: the growth model's trees by year (size of
// the skeleton and the BlobTree, model, bake and write times, memory) and a
// whole sequence, against paper 000's figures for year 27.
#pragma once

#include "core/system.h"

#include <functional>

#include <string>
#include <vector>

namespace cambium {

struct GrowthBenchRequest {
    std::string parameters;  ///< growth parameter file
    std::vector<int> years{5, 10, 20, 27};
    double voxelSize = 0.01;
    double fpsPerYear = 1.0;  ///< the whole sequence's frame rate (0: no sequence)
    Device device = Device::OpenCL;
    bool leaves = false;
};

/// What the run measures before the first year.
struct GrowthBenchSetup {
    size_t branches = 0;
    int years = 0;
    double globalSeconds = 0.0;  ///< the global phase of the growth model
    std::string device;
};

/// One year's tree, built, baked and written.
struct GrowthBenchYear {
    int year = 0;
    size_t internodes = 0, primitives = 0, operators = 0, activeVoxels = 0;
    double modelSeconds = 0.0, bakeSeconds = 0.0, writeSeconds = 0.0;
    double fileBytes = 0.0, peakBytes = 0.0;  ///< the process's peak so far (years ascend)
};

/// The whole sequence at fpsPerYear.
struct GrowthBenchSequence {
    size_t frames = 0, reused = 0, leaves = 0, reusedLeaves = 0;
    double seconds = 0.0, fileBytes = 0.0, peakBytes = 0.0;
    int jobs = 0;
};

/// The last year's bake with the species' bark furrows and without them,
/// in turn (medians of three pairs): what the bark detail costs.
struct GrowthBenchBark {
    int year = 0;
    size_t barkCones = 0;
    double withSeconds = 0.0, withoutSeconds = 0.0;
    size_t withVoxels = 0, withoutVoxels = 0;
    double withGridBytes = 0.0, withoutGridBytes = 0.0;  ///< the grids in memory
};

struct GrowthBenchCallbacks {
    std::function<void(const GrowthBenchSetup&)> setup;
    std::function<void(const GrowthBenchYear&)> year;
    std::function<void(const GrowthBenchBark&)> bark;
    std::function<void(const GrowthBenchSequence&)> sequence;
};

/// Measures one row per year (ascending: the process's peak memory is then
/// that year's) and the sequence of every year's frames baked into
/// `directory`, reporting each as it is done.
void runGrowthBench(const GrowthBenchRequest& request, const std::string& directory,
                    const GrowthBenchCallbacks& callbacks);

}  // namespace cambium
