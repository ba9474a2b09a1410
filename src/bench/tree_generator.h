// cambium — the benchmark workload: a deterministic branching skeleton of any
// size, written in the skeleton text format (docs/skeleton-format.md).
#pragma once

#include <string>

namespace cambium {

struct TreeGeneratorOptions {
    int internodes = 4096;  ///< internodes written (none when <= 0)
    int seed = 1;           ///< Python's random.Random(seed) stream
    int laterals = 2;       ///< laterals per node below branch order 6 (one from there on); >= 1
    double angle = 45.0;    ///< mean branching angle of a lateral, degrees (+-10 at random)
    double height = 10.0;   ///< twelve times the trunk's first internode length
};

/// The skeleton text of a tree grown breadth first until it holds
/// `options.internodes` internodes: a header comment, then one line per
/// internode, "id parent x0 y0 z0 x1 y1 z1 r0 r1" with six decimals.  It has
/// the statistics of ../shared/bench/gen_skeleton.py, reproduced to the byte:
/// for the same options the text equals that script's output, so benchmark
/// numbers stay comparable with runs made before the generator moved here.
/// Throws InputError when laterals < 1.
std::string generateBenchSkeleton(const TreeGeneratorOptions& options);

}  // namespace cambium
