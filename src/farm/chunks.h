// cambium — a sequence plan cut into chunks for a farm (Slurm job arrays, or
// any manager that hands frame ranges to `cambium bake --frames`): each chunk
// a run of whole reuse groups, baked by one task in order, so that the
// temporal reuse of a group keeps working inside the task.
#pragma once

#include "bake/sequence.h"

#include <string>
#include <vector>

namespace cambium {

struct FarmChunk {
    size_t first = 0, last = 0;  ///< plan.frames[first, last)
    std::string frames;          ///< the chunk as --frames takes it: "A-B" or "A-B:STEP"
};

/// The plan's frames in chunks of whole reuse groups, each of at least
/// `framesPerChunk` frames (>= 1) but the last, in order, covering every
/// frame once.
std::vector<FarmChunk> chunkPlan(const SequencePlan& plan, size_t framesPerChunk);

/// What one task asks of a node: its memory (`bakeBytes`, the estimate of
/// its largest bake: a frame's, a tile's; with a margin for the process
/// itself) and cores,
/// as many as the node has in proportion to the share of its memory a task
/// takes, so that the tasks a node's memory allows keep its cores busy.
struct TaskResources {
    long long memoryMB = 0;
    int cpus = 1;
};
TaskResources taskResources(double bakeBytes, int nodeCpus, double nodeMemoryBytes);

}  // namespace cambium
