// cambium info — a model's node counts by type, depth and bounds.
#include "app/app.h"

#include "blobtree/stats.h"
#include "core/clock.h"
#include "model/load_model.h"

#include <fmt/format.h>

namespace cambium {

namespace {

int runInfo(const std::string& scenePath, const ModelOptions& model)
{
    const auto start = Clock::now();
    const BlobTree tree = loadModel(scenePath, model);
    const double seconds = secondsSince(start);
    const TreeStats s = computeStats(tree);
    fmt::print("scene      {}\n", scenePath);
    fmt::print("read       {:.3f} s (reading, deriving and building the BlobTree)\n", seconds);
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
        fmt::print("bounds     min {}  max {}\n", formatVec(s.bounds.lo), formatVec(s.bounds.hi));
        fmt::print("           size {}  (from primitive supports: the surface lies within)\n",
                   formatVec(s.bounds.size()));
    }
    return 0;
}

}  // namespace

void addInfoCommand(CLI::App& app, Action& action)
{
    struct Options {
        std::string scene;
        ModelFlags model;
    };
    auto o = std::make_shared<Options>();
    auto* cmd = app.add_subcommand("info", "Print a scene's node counts by type, depth and bounds");
    cmd->add_option("scene", o->scene,
                    "Scene (JSON, docs/scene-format.md), growth parameters "
                    "(docs/growth-format.md), L-system (.l, "
                    "docs/lsystem-format.md) or skeleton (docs/skeleton-format.md)")
        ->required();
    addModelFlags(cmd, o->model);
    cmd->callback([o, &action] { action = [o] { return runInfo(o->scene, o->model.options()); }; });
}

}  // namespace cambium
