// cambium — the command layer: one file per command, each parsing its
// options into the library's typed requests, calling the library and
// formatting its report.  tools/cambium.cpp's main is a table of these.
#pragma once

#include "core/system.h"
#include "model/load_model.h"

#include <CLI/CLI.hpp>
#include <glm/glm.hpp>

#include <chrono>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace cambium {

/// What a chosen command runs after parsing: its exit status.
using Action = std::function<int()>;
/// Adds one command to `app`; when the command line chooses it, `action`
/// becomes its work.
using AddCommand = void (*)(CLI::App& app, Action& action);

void addInfoCommand(CLI::App& app, Action& action);
void addEvalCommand(CLI::App& app, Action& action);
void addBakeCommand(CLI::App& app, Action& action);
void addMeshCommand(CLI::App& app, Action& action);
void addRenderCommand(CLI::App& app, Action& action);
void addBenchCommand(CLI::App& app, Action& action);
void addLSystemCommand(CLI::App& app, Action& action);
void addGrowthCommand(CLI::App& app, Action& action);
void addShapeCommand(CLI::App& app, Action& action);
void addVersionCommand(CLI::App& app, Action& action);
void addPrepareCommand(CLI::App& app, Action& action);
void addFarmCommand(CLI::App& app, Action& action);
void addPreviewCommand(CLI::App& app, Action& action);

/// The values of every option of `app` and its commands: none empty, and a
/// number option's decimal text only: "0x10" and "1p3" (which strtold and
/// strtoll read as 16 and 8000) are refused, and an integer's leading zeros
/// dropped ("010" is 10, where strtoll would read 8).  "inf" and "nan" pass
/// to each option's own check.
void checkOptionValues(CLI::App& app);

/// The model options of info and bake as the command line gives them.
struct ModelFlags {
    std::string junctions, primitives = "cone";
    double bendDegrees = 0.0, regrowth = 0.0, time = 0.0;
    bool noLeaves = false;
    CLI::Option* timeOption = nullptr;
    /// The typed options (InputError for a value that names nothing).
    ModelOptions options() const;
};
/// Adds --junctions, --bend, --primitives, --regrowth, --no-leaves and --time.
void addModelFlags(CLI::App* command, ModelFlags& flags);

/// Adds --min-radius (BakeRequest::minRadius) to a command that bakes a model.
void addMinRadiusFlag(CLI::App* command, double& voxels);

/// `cambium bake … --slurm`'s options (a sequence's, or a frame's tiles).
struct SlurmFlags {
    bool slurm = false, wait = false, dryRun = false;
    size_t chunk = 1;  ///< at least this many frames a task, whole reuse groups
    int throttle = 0;  ///< tasks at once; 0: as many as Slurm runs
    int retries = 2;   ///< times the final job submits a failed chunk again
    std::vector<std::string> sbatchArgs;
};
/// The sequence as a Slurm job array (src/farm): printed (dryRun), or
/// submitted, and followed to its end with `wait`.
int runSlurmCommand(const struct SequenceRequest& request, const SlurmFlags& flags);

/// One bake and its report line (with `timings`, its stage timings).
int runBakeCommand(const struct BakeRequest& request, bool timings);

/// One frame baked as `tiles` spatial tiles, each by a process of its own,
/// then merged (app/tiles.cpp); tiles 0: as many as keep a tile's share of
/// the frame's estimated memory within `maxMemory`.
int runTiledBakeCommand(const struct BakeRequest& request, int tiles, double maxMemory,
                        bool timings);

/// A frame's tiles decided (app/tiles.cpp): the voxel size, the tile count
/// (from --tiles, or from --max-memory: as many as keep a tile's share of the
/// frame's estimate within it; 1 when the frame fits) and the estimates;
/// InputError for a frame tiles cannot bake (--fog, a bark photo) or a share
/// over --max-memory.  `here`: a tile's share must fit this machine.
struct TilePlan {
    double voxelSize = 0.0;
    int tiles = 1;
    double frameBytes = 0.0;  ///< the whole frame's estimate
    double tileBytes = 0.0;   ///< a tile's share of it
    double fileBytes = 0.0;   ///< the merged file's estimate
    double bandVoxels = 0.0;  ///< the frame's estimated band voxels
    double threshold = 0.5;   ///< the model's iso-value
    double time = 0.0;        ///< the model's time (growth files: years)
};
TilePlan planTiles(const struct BakeRequest& request, int tiles, double maxMemory, bool here);

/// One frame's tiles as a Slurm job array merged by its final job
/// (src/farm): printed (dryRun), or submitted, and followed with `wait`.
int runTileFarmCommand(const struct BakeRequest& request, const TilePlan& tiles,
                       const SlurmFlags& flags);

/// The sequence's report of each frame and its summary (with `timings`, each
/// baked frame's stage timings on stderr).
int runSequenceCommand(const struct SequenceRequest& request, bool timings);

/// A bake's stage timings (BakeStats::timings), one line on stderr: what
/// --timings prints.
void printTimings(const struct BakeStats& stats);
/// Whether stage times are printed: the command's --timings, or CAMBIUM_TIMING set.
bool timingsAsked(bool flag);

/// "(x, y, z)" with six significant digits.
std::string formatVec(const glm::dvec3& v);

/// Says "cambium: planning N frames" on stderr (with the progress bars:
/// stdout is the report) for a sequence of 100,000 frames or more, whose
/// plan takes seconds: each frame's path checked, frames sampled.
void notePlanning(size_t frames);

/// Prints a notice line on stdout ("note: ...").
void printNotice(const std::string& line);

/// A progress bar on stderr when it is a terminal; otherwise, once the
/// command has worked 5 s, a line "cambium: working: STAGE (N % done)" for
/// each stage it enters.
class ProgressBar {
public:
    ProgressBar();
    ~ProgressBar();
    void operator()(const char* stage, double fraction);
    void clear();

private:
    bool tty_;
    std::chrono::steady_clock::time_point start_;
    bool shown_ = false;
    std::mutex mutex_;
    std::string stage_;
    int percent_ = -1;
};

}  // namespace cambium
