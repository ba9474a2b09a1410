// cambium — `cambium bench growth`: the growth model's trees by year (size of
// the skeleton and the BlobTree, model, bake and write times, memory) and a
// whole sequence, against paper 000's figures for year 27.
#pragma once

#include <string>
#include <vector>

namespace cambium {

struct GrowthBenchRequest {
    std::string parameters;           ///< growth parameter file
    std::vector<int> years{5, 10, 20, 27};
    double voxelSize = 0.01;
    double fpsPerYear = 1.0;          ///< the whole sequence's frame rate (0: no sequence)
    std::string device = "opencl";
    bool leaves = false;
};

/// Prints one row per year (ascending: the process's peak memory is then
/// that year's) and the sequence of every year's frames baked into a
/// temporary directory.
void runGrowthBench(const GrowthBenchRequest& request, const std::string& directory);

}  // namespace cambium
