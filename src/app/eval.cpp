// cambium eval — the field, gradient and colour at a point (CPU reference).
#include "app/app.h"

#include "bake/bake.h"
#include "blobtree/bounds.h"
#include "blobtree/evaluator.h"
#include "core/error.h"
#include "core/math.h"
#include "model/load_model.h"

#include <fmt/format.h>

#include <cmath>
#include <vector>

namespace cambium {

namespace {

int runEval(const std::string& scenePath, const std::vector<double>& xyz)
{
    const glm::dvec3 p(xyz[0], xyz[1], xyz[2]);
    // (within the coordinates a model may have: a bend's squared terms
    // overflowed at 1e160, "inside" with a NaN gradient, exit 0)
    if (!(std::abs(p.x) <= kFarthestCoordinate && std::abs(p.y) <= kFarthestCoordinate &&
          std::abs(p.z) <= kFarthestCoordinate))
        throw InputError(
            fmt::format("eval: the point {} must have finite coordinates within {:g} of the origin",
                        formatVec(p), kFarthestCoordinate));
    const BlobTree tree = loadModel(scenePath);
    // (the model within them too, as a bake checks it)
    if (const Box bounds = surfaceBounds(tree); !bounds.empty())
        checkModelReach(bounds, scenePath);
    const ReferenceEvaluator eval(tree);
    const FieldSample s = eval.sample(p);
    fmt::print("point     {}\n", formatVec(p));
    fmt::print("field     {:.9g}  ({} at threshold {})\n", s.value,
               s.value > tree.threshold()
                   ? "inside"
                   : (s.value < tree.threshold() ? "outside" : "on the surface"),
               tree.threshold());
    fmt::print("gradient  {}  |grad| {:.6g}\n", formatVec(s.gradient), glm::length(s.gradient));
    fmt::print("colour    {}\n", formatVec(s.color));
    return 0;
}

}  // namespace

void addEvalCommand(CLI::App& app, Action& action)
{
    struct Options {
        std::string scene;
        std::vector<double> point;
    };
    auto o = std::make_shared<Options>();
    auto* cmd = app.add_subcommand("eval",
                                   "Evaluate a scene's field, gradient and colour at a point "
                                   "(CPU reference evaluator)");
    cmd->add_option("scene", o->scene, "Scene (JSON) or skeleton")->required();
    cmd->add_option("point", o->point, "x y z")->required()->expected(3);
    cmd->callback([o, &action] { action = [o] { return runEval(o->scene, o->point); }; });
}

}  // namespace cambium
