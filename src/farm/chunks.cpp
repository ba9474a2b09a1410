// cambium — a sequence plan cut into chunks for a farm.
#include "farm/chunks.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace cambium {

std::vector<FarmChunk> chunkPlan(const SequencePlan& plan, size_t framesPerChunk)
{
    framesPerChunk = std::max<size_t>(framesPerChunk, 1);
    const std::vector<long long>& f = plan.frames;
    // The step between the plan's frames (one range: constant).
    const long long step = f.size() > 1 ? f[1] - f[0] : 1;
    std::vector<FarmChunk> chunks;
    size_t next = 0;  // the first frame not in a chunk yet
    for (const std::vector<size_t>& group : plan.groups) {
        if (group.empty() || group.front() != next ||
            group.back() != group.front() + group.size() - 1)
            throw std::logic_error("chunkPlan: the plan's reuse groups are not runs in order");
        next = group.back() + 1;
        if (chunks.empty() || chunks.back().last - chunks.back().first >= framesPerChunk)
            chunks.push_back({group.front(), group.front(), {}});
        chunks.back().last = next;
    }
    if (next != f.size())
        throw std::logic_error("chunkPlan: the plan's reuse groups do not cover its frames");
    for (FarmChunk& c : chunks)
        c.frames = step == 1 ? fmt::format("{}-{}", f[c.first], f[c.last - 1])
                             : fmt::format("{}-{}:{}", f[c.first], f[c.last - 1], step);
    return chunks;
}

TaskResources taskResources(double bakeBytes, int nodeCpus, double nodeMemoryBytes)
{
    // The process beside the bake: libraries (OpenVDB, PoCL and its LLVM:
    // about 120 MB, docs/benchmarks.md) and the sequence's own state.
    constexpr double kProcessBytes = 256e6;
    const double bytes = bakeBytes + kProcessBytes;
    TaskResources r;
    r.memoryMB = (long long)std::ceil(bytes / (1 << 20));
    nodeCpus = std::max(nodeCpus, 1);
    if (nodeMemoryBytes > 0.0) {
        const double share = std::min(1.0, bytes / nodeMemoryBytes);
        r.cpus = std::clamp(int(std::ceil(share * nodeCpus - 1e-9)), 1, nodeCpus);
    }
    return r;
}

}  // namespace cambium
