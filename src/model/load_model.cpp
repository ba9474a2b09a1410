// cambium — reading a model of any source.
#include "model/load_model.h"

#include "blobtree/scene_io.h"
#include "core/error.h"
#include "core/math.h"
#include "model/growth.h"
#include "model/skeleton.h"
#include "model/tree_builder.h"
#include "model/turtle.h"

#include <fmt/format.h>

#include <cmath>

namespace cambium {

namespace {

bool endsWith(const std::string& s, const std::string& suffix)
{
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

/// The tree builder's options for `junctions` "pcm" or "smooth".
TreeBuildOptions treeOptions(const ModelOptions& o, const std::string& junctions)
{
    TreeBuildOptions t;
    t.junction = junctions == "pcm" ? TreeBuildOptions::Junction::Pcm : TreeBuildOptions::Junction::Smooth;
    t.bend = o.bendDegrees * kDegree;
    t.regrowth = o.regrowth;
    t.primitives = o.primitives == "cone"          ? TreeBuildOptions::Primitives::Cone
                   : o.primitives == "convolution" ? TreeBuildOptions::Primitives::Convolution
                                                   : TreeBuildOptions::Primitives::Mixed;
    return t;
}

}  // namespace

void checkModelOptions(const ModelOptions& o)
{
    if (!o.junctions.empty() && o.junctions != "pcm" && o.junctions != "smooth" && o.junctions != "blend")
        throw InputError(fmt::format("--junctions must be pcm, smooth or blend (got '{}')", o.junctions));
    if (!(std::abs(o.bendDegrees) < 90.0))
        throw InputError(fmt::format("--bend must be between -90 and 90 degrees (got {})", o.bendDegrees));
    if (o.bendDegrees != 0.0 && o.junctions == "blend")
        throw InputError("--bend needs --junctions pcm or smooth (blend builds no junctions)");
    if (o.primitives != "cone" && o.primitives != "convolution" && o.primitives != "mixed")
        throw InputError(fmt::format("--primitives must be cone, convolution or mixed (got '{}')", o.primitives));
    if (o.primitives != "cone" && o.junctions == "blend")
        throw InputError("--primitives convolution or mixed needs --junctions pcm or smooth");
    checkTreeBuildOptions(treeOptions(o, "pcm"));
}

void checkGrowthOptions(const std::string& path, const ModelOptions& o)
{
    if (!o.junctions.empty() || o.bendDegrees != 0.0 || o.primitives != "cone" || o.regrowth != 0.0)
        throw InputError(fmt::format("{}: --junctions, --bend, --primitives and --regrowth are for L-systems and "
                                     "skeletons; a growth parameter file sets its own (docs/growth-format.md)",
                                     path));
}

BlobTree loadModel(const std::string& path, const ModelOptions& o)
{
    checkModelOptions(o);
    if (isGrowthParameterFile(path)) {
        checkGrowthOptions(path, o);
        const GrowthModel model(loadGrowthParameters(path));
        const double t = timeOfLife(model.params(), o.time, path, "--time");
        const Skeleton sk = model.skeleton(t, o.leaves);
        if (sk.internodes.empty())
            throw InputError(fmt::format("{}: at year {} the tree has not begun to grow: nothing to bake", path, t));
        return buildTree(sk, model.buildOptions());
    }
    if (endsWith(path, ".json"))
        return loadScene(path);
    Skeleton sk;
    const bool lsystem = endsWith(path, ".l");
    if (lsystem) {
        const LSystem sys = loadLSystem(path);
        sk = interpretTurtle(sys, derive(sys, sys.derivationLength, sys.seed, kDefaultMaxModules));
        if (sk.internodes.empty())
            throw InputError(fmt::format("{}: after {} derivation steps the string draws no internode (no F): "
                                         "nothing to bake",
                                         path, sys.derivationLength));
    } else {
        sk = loadSkeleton(path);
    }
    const std::string junctions = o.junctions.empty() ? (lsystem ? "pcm" : "blend") : o.junctions;
    return junctions == "blend" ? skeletonToBlend(sk) : buildTree(sk, treeOptions(o, junctions));
}

}  // namespace cambium
