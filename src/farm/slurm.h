// cambium — a sequence plan as a Slurm job array: the plan file written next
// to the output, and the batch script whose task i bakes chunk i of the plan
// (`cambium bake … --frames` of the chunk, --resume, the plan's voxel size).
// What runs the scripts (sbatch, the final verification job) is the app's.
#pragma once

#include "farm/chunks.h"

#include <string>
#include <vector>

namespace cambium {

struct SlurmOptions {
    size_t framesPerChunk = 1;            ///< --chunk: at least this many frames a task
    int throttle = 0;                     ///< tasks running at once (the array's %K); 0: any
    std::vector<std::string> sbatchArgs;  ///< --slurm-arg: more sbatch options, one each
    std::string exe;                      ///< the cambium binary the tasks run (absolute)
    int nodeCpus = 1;                     ///< a node's cores and memory, for the task's share
    double nodeMemoryBytes = 0.0;
};

/// A sequence as a job array, decided before anything is written.
struct SlurmArray {
    /// OUTDIR/NAME.frames.vdb.farm for -o OUTDIR/NAME.####.vdb: the plan,
    /// scripts, logs, statuses and caches
    std::string farmDir;
    std::string planPath, scriptPath;
    std::vector<FarmChunk> chunks;
    TaskResources resources;
    std::string planJson;  ///< the plan file: inputs and their hash, key, voxel size, chunks
    std::string script;    ///< the array's batch script
};

SlurmArray planSlurmArray(const SequencePlan& plan, const SlurmOptions& options);

/// The arguments of `cambium bake` that bake chunk `frames` of the plan as
/// one local run of the whole plan would (the plan's voxel size, every
/// option that changes a frame, --resume, one frame at a time on `threads`
/// threads): what each task runs.
std::vector<std::string> chunkBakeArguments(const SequencePlan& plan, const std::string& frames,
                                            const std::string& threads);

/// `s` quoted for a POSIX shell.
std::string shellQuote(const std::string& s);

}  // namespace cambium
