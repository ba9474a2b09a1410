// cambium — `cambium bench read`: what opening a baked frame costs, each way
// a user opens one, as whole processes side by side: OpenVDB's io::File
// (every grid, the level set alone, and with volumeToMesh), cambium's
// reader, and cambium's render, mesh and info of the same file.
#pragma once

#include "bench/process_run.h"

#include <functional>
#include <string>
#include <vector>

namespace cambium {

struct ReadBenchRequest {
    /// Files to measure; none: the growth file's tree at `year` baked at
    /// `voxelSize` twice, its colour on the band (the layout before issue 30)
    /// and on the shell (the default).
    std::vector<std::string> files;
    std::string parameters;
    double year = 27.0, voxelSize = 0.005;
    int repeats = 3;
    int width = 960, height = 720, spp = 4;  ///< the render's picture
};

struct ReadBenchFile {
    std::string label, path;
    double bytes = 0.0;
    struct Row {
        std::string what;
        ProcessSummary run;
    };
    /// In this order: io::File every grid, io::File surface, io::File +
    /// volumeToMesh, cambium's reader, cambium render, cambium mesh (the PLY
    /// written), cambium info.
    std::vector<Row> rows;
};

/// Measures each file (`repeats` rounds of every command in turn, medians),
/// calling `checked` once every --file is checked as render and mesh check
/// them (InputError before), then `done` as each is measured.
void runReadBench(const ReadBenchRequest& request, const std::function<void()>& checked,
                  const std::function<void(const ReadBenchFile&)>& done);

}  // namespace cambium
