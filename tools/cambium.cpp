// cambium — the command-line tool.  A thin table of sub-commands: each parses
// its arguments and calls the library.
#include "blobtree/evaluator.h"
#include "blobtree/scene_io.h"
#include "blobtree/stats.h"
#include "core/error.h"
#include "core/versions.h"

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <functional>
#include <string>

namespace {

using namespace cambium;

std::string vec(const glm::dvec3& v) { return fmt::format("({:.6g}, {:.6g}, {:.6g})", v.x, v.y, v.z); }

int runInfo(const std::string& scenePath)
{
    const BlobTree tree = loadScene(scenePath);
    const TreeStats s = computeStats(tree);
    fmt::print("scene      {}\n", scenePath);
    fmt::print("threshold  {}\n", tree.threshold());
    fmt::print("nodes      {}: {} primitive{}, {} operator{}, {} warp{}\n",
               s.primitives + s.operators + s.warps, s.primitives, s.primitives == 1 ? "" : "s",
               s.operators, s.operators == 1 ? "" : "s", s.warps, s.warps == 1 ? "" : "s");
    for (const auto& [type, count] : s.countByType)
        fmt::print("  {:<22} {}\n", typeName(type), count);
    fmt::print("depth      {}\n", s.depth);
    if (s.bounds.empty()) {
        fmt::print("bounds     empty (the field is nowhere positive: no surface)\n");
    } else {
        fmt::print("bounds     min {}  max {}\n", vec(s.bounds.lo), vec(s.bounds.hi));
        fmt::print("           size {}  (from primitive supports: the surface lies within)\n",
                   vec(s.bounds.size()));
    }
    return 0;
}

int runEval(const std::string& scenePath, const std::vector<double>& xyz)
{
    const BlobTree tree = loadScene(scenePath);
    const ReferenceEvaluator eval(tree);
    const glm::dvec3 p(xyz[0], xyz[1], xyz[2]);
    const FieldSample s = eval.sample(p);
    fmt::print("point     {}\n", vec(p));
    fmt::print("field     {:.9g}  ({} at threshold {})\n", s.value,
               s.value > tree.threshold() ? "inside" : (s.value < tree.threshold() ? "outside" : "on the surface"),
               tree.threshold());
    fmt::print("gradient  {}  |grad| {:.6g}\n", vec(s.gradient), glm::length(s.gradient));
    fmt::print("colour    {}\n", vec(s.color));
    return 0;
}

int runVersion()
{
    fmt::print("cambium {}\n", version());
    for (const auto& [lib, v] : dependencyVersions())
        fmt::print("  {:<12} {}\n", lib, v);
    return 0;
}

}  // namespace

int main(int argc, char** argv)
{
    CLI::App app{"cambium: bake BlobTree implicit models of growing plants into OpenVDB level sets"};
    app.require_subcommand(1);
    app.set_version_flag("--version", std::string("cambium ") + cambium::version());

    std::function<int()> action;

    std::string scene;
    auto* info = app.add_subcommand("info", "Print a scene's node counts by type, depth and bounds");
    info->add_option("scene", scene, "Scene file (JSON, docs/scene-format.md)")->required();
    info->callback([&] { action = [&] { return runInfo(scene); }; });

    std::vector<double> point;
    auto* eval = app.add_subcommand("eval", "Evaluate a scene's field, gradient and colour at a point "
                                            "(CPU reference evaluator)");
    eval->add_option("scene", scene, "Scene file")->required();
    eval->add_option("point", point, "x y z")->required()->expected(3);
    eval->callback([&] { action = [&] { return runEval(scene, point); }; });

    auto* ver = app.add_subcommand("version", "Print the versions of cambium, its libraries and the "
                                              "OpenCL devices found");
    ver->callback([&] { action = [&] { return runVersion(); }; });

    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e);
    }
    try {
        return action ? action() : 0;
    } catch (const cambium::InputError& e) {
        fmt::print(stderr, "cambium: error: {}\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        fmt::print(stderr, "cambium: failed: {}\n", e.what());
        return 1;
    }
}
