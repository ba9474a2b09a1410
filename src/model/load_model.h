// cambium — a model from a file: a JSON scene, an L-system, a skeleton or a
// growth parameter file, whichever the file is, as a BlobTree.
#pragma once

#include "blobtree/blobtree.h"
#include "model/tree_builder.h"

#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace cambium {

/// Reads a model: a JSON scene (.json), an L-system (.l, derived for its
/// derivation length, drawn by the turtle and built with the papers' junction
/// rules, model/tree_builder.h) or a skeleton text file (anything else,
/// docs/skeleton-format.md, as the benchmarks' summation blend of one cone
/// per internode).
struct ModelOptions {
    /// How skeletons and L-systems become BlobTrees: Pcm (the papers'
    /// junction rules with PCM between branches), Smooth (the rules with
    /// summation only), Blend (one cone per internode, summed, no rules: the
    /// benchmarks' field).
    enum class Junctions { Pcm, Smooth, Blend };
    std::optional<Junctions> junctions;  ///< none: Pcm for L-systems, Blend for skeleton files
    double bendDegrees = 0.0;  ///< endpoint-preserving bend of lateral internodes (Pcm, Smooth)
    /// Cone (papers 001/003), Convolution or Mixed (paper 002; Pcm and Smooth only)
    using Primitives = TreeBuildOptions::Primitives;
    Primitives primitives = Primitives::Cone;
    double regrowth = 0.0;  ///< callus over saw cuts, 0 to 1 (pcm, smooth)
    /// Growth parameter files: the time in years (< 0: the file's last year)
    /// and whether to grow leaves.
    std::optional<double> time;
    bool leaves = true;
    /// Told of long phases while a model is made (an L-system's derivation:
    /// its stage name and the fraction done); may be empty.
    std::function<void(const char* stage, double fraction)> progress;
};
/// InputError unless the options are valid (before any work).
void checkModelOptions(const ModelOptions& options);
/// InputError when options for L-systems and skeletons are given with a
/// growth parameter file.
void checkGrowthOptions(const std::string& path, const ModelOptions& options);
/// The option values' names on the command line ("pcm", "cone", ...), and
/// back: InputError naming the option and the values it takes.
ModelOptions::Junctions parseJunctions(const std::string& name);
ModelOptions::Primitives parsePrimitives(const std::string& name);
const char* junctionsName(ModelOptions::Junctions junctions);
const char* primitivesName(ModelOptions::Primitives primitives);
class GrowthModel;
/// A grown model's tree at `options.time` (the file's last year when
/// unset), as loadModel makes it from `path`: for a caller that keeps the
/// growth model (its global phase) between trees of other times.
BlobTree grownTree(const GrowthModel& model, const std::string& path, const ModelOptions& options);

/// Also reads growth parameter files (a .json with "curves",
/// docs/growth-format.md): the tree grown to `options.time`.
BlobTree loadModel(const std::string& path, const ModelOptions& options = {});

/// The files a model at `path` reads: the file and, for a growth parameter
/// file, the bark photo it names (what no output may replace).
std::vector<std::string> modelFiles(const std::string& path);

}  // namespace cambium
