// cambium — a sequence plan as a Slurm job array: the plan file written next
// to the output, and the batch script whose task i bakes chunk i of the plan
// (`cambium bake … --frames` of the chunk, --resume, the plan's voxel size),
// and the final job's script (`cambium farm --finish DIR` once the array has
// ended: every frame checked, a manifest, failed chunks submitted again).
// What runs the scripts (sbatch) is the app's.
#pragma once

#include "farm/chunks.h"
#include "io/vdb_header.h"

#include <string>
#include <vector>

namespace cambium {

struct SlurmOptions {
    size_t framesPerChunk = 1;            ///< --chunk: at least this many frames a task
    int throttle = 0;                     ///< tasks running at once (the array's %K); 0: any
    int retries = 2;                      ///< times the final job submits a failed chunk again
    std::vector<std::string> sbatchArgs;  ///< --slurm-arg: more sbatch options, one each
    std::string exe;                      ///< the cambium binary the tasks run (absolute)
    int nodeCpus = 1;                     ///< a node's cores and memory, for the task's share
    double nodeMemoryBytes = 0.0;
    bool nodesListed = false;  ///< the node's from sinfo (else this machine's: --dry-run)
};

/// A sequence as a job array, decided before anything is written.
struct SlurmArray {
    /// OUTDIR/NAME.frames.vdb.farm for -o OUTDIR/NAME.####.vdb: the plan,
    /// scripts, logs, statuses and caches
    std::string farmDir;
    std::string planPath, scriptPath, finalScriptPath;
    std::string jobName;  ///< the array's and the final job's: `scancel -n` stops both
    std::vector<FarmChunk> chunks;
    TaskResources resources;
    std::string planJson;     ///< the plan file: inputs and their hash, key, voxel size, chunks
    std::string script;       ///< the array's batch script
    std::string finalScript;  ///< the final job's: `cambium farm --finish FARMDIR`
    long long finalMemoryMB = 512;  ///< the final job's --mem
};

SlurmArray planSlurmArray(const SequencePlan& plan, const SlurmOptions& options);

/// One frame baked as tiles by a job array (bake --tiles --slurm): task k
/// bakes tile k+1 of `tiles` (`--tile K/N`) into FARMDIR/tile-K.vdb, and the
/// final job merges them into the request's output, OUTDIR/NAME.vdb, whose
/// farm directory is OUTDIR/NAME.vdb.tiles.farm.
struct TileFarmRequest {
    BakeRequest request;  ///< its voxel size decided
    int tiles = 2;
    double tileBytes = 0.0;   ///< a tile's share of the frame's estimate
    double frameBytes = 0.0;  ///< the frame's estimate (the merge holds less)
    double threshold = 0.5;   ///< the model's, for the merged file's metadata
    double time = 0.0;        ///< the model's time (growth files: years), the same
    std::string scene;        ///< the input as the user named it, for the same
};
SlurmArray planTileArray(const TileFarmRequest& request, const SlurmOptions& options);

/// The key a tile's file carries (`cambium_sequence`): a hash of the input's
/// text and every option of the tile's bake but its output, cores and --half,
/// with the tile count; the same for the plan and for each tile's bake.
std::string tileFarmKey(const BakeRequest& request, int tiles);

/// Tile `tile` (0-based) of a tile farm: FARMDIR/tile-K.vdb, K from 1.
std::string tilePath(const std::string& farmDir, size_t tile);

/// The arguments of `cambium bake` that bake `request` at `voxelSize` (every
/// option that changes the result, paths made absolute): what a farm's or a
/// tiled bake's processes run, given more options.
std::vector<std::string> bakeArguments(const BakeRequest& request, double voxelSize);

/// The arguments of `cambium bake` that bake chunk `frames` of the plan as
/// one local run of the whole plan would (the plan's voxel size, every
/// option that changes a frame, --resume, one frame at a time on `threads`
/// threads): what each task runs.
std::vector<std::string> chunkBakeArguments(const SequencePlan& plan, const std::string& frames,
                                            const std::string& threads);

/// A farm directory's plan.json, as the final job and `cambium farm` read
/// it.  InputError naming the file and what is wrong with it.
struct FarmPlan {
    std::string dir, output, key, scriptPath, finalScriptPath;
    int retries = 0, throttle = 0;
    /// each chunk's --frames; a tile farm's: each tile's --tile, "K/N"
    std::vector<std::string> chunks;
    int tiles = 0;  ///< a tile farm's tile count (0: a sequence's farm)
    /// A tile farm's merged file, as the tiles' bake would have written it.
    VdbFileInfo merged;
    /// A chunk's files, each with its number: its frames, or its tile's
    /// file (the tile's number, from 1).
    struct File {
        long long number;
        std::string path;
    };
    std::vector<File> chunkFiles(size_t chunk) const;
    /// "chunk 1/3 frames 1-9" or "tile 2/4": a chunk in a line about it.
    std::string chunkName(size_t chunk) const;
    const char* unit() const { return tiles ? "tile" : "frame"; }
};
FarmPlan readFarmPlan(const std::string& farmDir);

/// A chunk's history, its task-I.status file: a line a task's end ("STATUS
/// ARRAYJOBID", appended by the task's script) or a submission again
/// ("submitted again", by the final job), oldest first; every attempt's end
/// is kept, so that one who follows the farm misses none.
struct ChunkEvent {
    bool again = false;  ///< submitted again (else a task ended)
    int status = 0;      ///< the ended task's exit status
};
std::vector<ChunkEvent> readChunkEvents(const std::string& farmDir, size_t chunk);
/// Chunk `chunk`'s history file, FARMDIR/task-I.status.
std::string chunkHistoryPath(const std::string& farmDir, size_t chunk);
/// Adds "submitted again" to chunk `chunk`'s history (before its sbatch).
void markSubmittedAgain(const std::string& farmDir, size_t chunk);

/// Where one chunk of a farm stands.
struct FarmChunkState {
    std::string name;            ///< the plan's chunkName
    const char* unit = "frame";  ///< what it writes: "frame" or "tile"
    /// The last attempt's exit status (its task-I.status); -1: none
    /// (cancelled, killed with its script, or not ended yet).
    int status = -1;
    int attempts = 1;  ///< times the chunk was submitted
    /// The chunk's frames not written, not readable or not of this plan.
    std::vector<long long> missing;
    /// Those of `missing` whose file is there, but damaged or another plan's
    /// (a tile baked from an edited input, another frame's or another
    /// tool's file copied over, a truncated file).
    std::vector<long long> foreign;
    bool done() const { return missing.empty(); }
    bool badInput() const { return !done() && status == 2; }
};
struct FarmState {
    std::vector<FarmChunkState> chunks;
    size_t frames = 0, good = 0;  ///< files (frames or tiles) of the plan, and those written
    /// A tile farm's tiles merged into its output (then removed): every
    /// chunk done.
    bool merged = false;
    /// The merged file's `cambium_checksum`, as the manifest records it.
    std::string mergedChecksum;
    /// Every file of the plan there (a tile farm's: merged too).
    bool complete(const struct FarmPlan& plan) const;
    /// Chunks not done: for bad input (never submitted again), and the rest.
    size_t badInput() const;
    size_t failed() const;
};

/// Every frame of the plan checked (the file exists, its header reads, it
/// carries the plan's key, and its bytes hold the checksum cambium wrote:
/// a status that read the headers only called a damaged frame written)
/// with each chunk's task status; attempts counted from the manifest an
/// earlier final job wrote.
FarmState assessFarm(const FarmPlan& plan);

/// The chunks to submit again: not done, not failed for bad input, and
/// submitted at most `plan.retries` times so far.
std::vector<size_t> chunksToRetry(const FarmPlan& plan, const FarmState& state);

/// The manifest (manifest.json) of a farm: every file's (frame's, tile's)
/// state, every chunk's status and attempts, and which were submitted again;
/// for a tile farm whose tiles were merged, the merged file and its checksum.
std::string farmManifest(const FarmPlan& plan, const FarmState& state,
                         const std::vector<size_t>& resubmitted);

/// A task's exit status in words: "done", "failed (exit 1)", "failed: bad
/// input (exit 2; see its log)", or (-1) "ended without a status …".
std::string describeStatus(int status);

/// Where a chunk stands in words: "done", or its status and missing frames.
std::string describeChunk(const FarmChunkState& chunk);

/// `s` quoted for a POSIX shell.
std::string shellQuote(const std::string& s);

}  // namespace cambium
