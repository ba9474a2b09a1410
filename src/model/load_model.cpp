// cambium — reading a model of any source.
#include "model/load_model.h"

#include "blobtree/scene_io.h"
#include "core/error.h"
#include "core/files.h"
#include "core/math.h"
#include "model/growth.h"
#include "model/skeleton.h"
#include "model/tree_builder.h"
#include "model/turtle.h"

#include <fmt/format.h>

#include <cmath>

namespace cambium {

namespace {

/// The tree builder's options for junction rules Pcm or Smooth.
TreeBuildOptions treeOptions(const ModelOptions& o, ModelOptions::Junctions junctions)
{
    TreeBuildOptions t;
    t.junction = junctions == ModelOptions::Junctions::Pcm ? TreeBuildOptions::Junction::Pcm
                                                           : TreeBuildOptions::Junction::Smooth;
    t.bend = o.bendDegrees * kDegree;
    t.regrowth = o.regrowth;
    t.primitives = o.primitives;
    return t;
}

}  // namespace

namespace {

const std::vector<std::string> kJunctionNames{"pcm", "smooth", "blend"};
const std::vector<std::string> kPrimitiveNames{"cone", "convolution", "mixed"};

}  // namespace

ModelOptions::Junctions parseJunctions(const std::string& name)
{
    return ModelOptions::Junctions(optionChoice(name, kJunctionNames, "--junctions"));
}

ModelOptions::Primitives parsePrimitives(const std::string& name)
{
    return ModelOptions::Primitives(optionChoice(name, kPrimitiveNames, "--primitives"));
}

const char* junctionsName(ModelOptions::Junctions junctions)
{
    return kJunctionNames[size_t(junctions)].c_str();
}

const char* primitivesName(ModelOptions::Primitives primitives)
{
    return kPrimitiveNames[size_t(primitives)].c_str();
}

namespace {

/// --bend and --primitives build junctions: refused where the junctions are
/// `blend`, given or (`defaulted`) a skeleton file's default.
void checkBuildsJunctions(const ModelOptions& o, ModelOptions::Junctions junctions, bool defaulted)
{
    if (junctions != ModelOptions::Junctions::Blend)
        return;
    const char* why = defaulted ? "a skeleton file's default junctions are blend, which builds none"
                                : "blend builds no junctions";
    if (o.bendDegrees != 0.0)
        throw InputError(fmt::format("--bend needs --junctions pcm or smooth ({})", why));
    if (o.primitives != ModelOptions::Primitives::Cone)
        throw InputError(fmt::format(
            "--primitives convolution or mixed needs --junctions pcm or smooth ({})", why));
}

}  // namespace

void checkModelOptions(const ModelOptions& o)
{
    if (!(std::abs(o.bendDegrees) < 90.0))
        throw InputError(
            fmt::format("--bend must be between -90 and 90 degrees (got {})", o.bendDegrees));
    if (o.junctions)
        checkBuildsJunctions(o, *o.junctions, false);
    checkTreeBuildOptions(treeOptions(o, ModelOptions::Junctions::Pcm));
}

void checkGrowthOptions(const std::string& path, const ModelOptions& o)
{
    if (o.junctions || o.bendDegrees != 0.0 || o.primitives != ModelOptions::Primitives::Cone ||
        o.regrowth != 0.0)
        throw InputError(fmt::format(
            "{}: --junctions, --bend, --primitives and --regrowth are for L-systems and "
            "skeletons; a growth parameter file sets its own (docs/growth-format.md)",
            path));
}

BlobTree grownTree(const GrowthModel& model, const std::string& path, const ModelOptions& o)
{
    checkModelOptions(o);
    checkGrowthOptions(path, o);
    const double t = timeOfLife(model.params(), o.time, path, "--time");
    const Skeleton sk = model.skeleton(t, o.leaves);
    if (sk.internodes.empty())
        throw InputError(
            fmt::format("{}: at year {} the tree has not begun to grow: nothing to bake", path, t));
    BlobTree tree = buildTree(sk, model.buildOptions());
    tree.setTime(t);
    return tree;
}

std::vector<std::string> modelFiles(const std::string& path)
{
    std::vector<std::string> files = {path};
    if (isGrowthParameterFile(path))
        files.push_back(loadGrowthParameters(path).barkPhoto);
    return files;
}

BlobTree loadModel(const std::string& path, const ModelOptions& o)
{
    checkModelOptions(o);
    if (isGrowthParameterFile(path)) {
        checkGrowthOptions(path, o);
        return grownTree(GrowthModel(loadGrowthParameters(path)), path, o);
    }
    // (a time given for a model that does not grow was ignored)
    if (o.time)
        throw InputError(fmt::format(
            "{}: a time (--year, --time, a shape base's \"year\") is for growth parameter files "
            "(a .json with \"curves\"); this model does not grow",
            path));
    if (fileExtension(path) == "json")
        return loadScene(path);
    if (fileExtension(path) == "obj" || fileExtension(path) == "ply")
        throw InputError(fmt::format(
            "{}: a mesh file, not a model (scene .json, L-system .l, skeleton or growth file): "
            "`cambium render --mesh` draws it, a shape's \"mesh\" base bakes it",
            path));
    const bool lsystem = fileExtension(path) == "l";
    using J = ModelOptions::Junctions;
    const J junctions = o.junctions.value_or(lsystem ? J::Pcm : J::Blend);
    // (a skeleton file baked as if --bend 30 had not been given, exit 0)
    try {
        checkBuildsJunctions(o, junctions, !o.junctions);
    } catch (const InputError& e) {
        throw InputError(fmt::format("{}: {}", path, e.what()));
    }
    Skeleton sk;
    if (lsystem) {
        const LSystem sys = loadLSystem(path);
        sk = interpretTurtle(
            sys, derive(sys, sys.derivationLength, sys.seed, kDefaultMaxModules, o.progress));
        if (sk.internodes.empty())
            throw InputError(
                fmt::format("{}: after {} derivation steps the string draws no internode (no F): "
                            "nothing to bake",
                            path, sys.derivationLength));
    } else {
        sk = loadSkeleton(path);
    }
    try {
        return junctions == J::Blend ? skeletonToBlend(sk)
                                     : buildTree(sk, treeOptions(o, junctions));
    } catch (const InputError& e) {  // (the skeleton's own problems, named by internode)
        throw InputError(fmt::format("{}: {}", path, e.what()));
    }
}

}  // namespace cambium
