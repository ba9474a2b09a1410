// cambium info — a model's node counts by type, depth and bounds.
#include "app/app.h"

#include "blobtree/stats.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/system.h"
#include "model/load_model.h"
#include "shape/synthesis.h"

#include <fmt/format.h>

namespace cambium {

namespace {

const char* const kBaseNames[] = {"cube", "sphere", "torus", "plane",
                                  "fuse", "mesh",   "vdb",   "model"};
const char* const kDetailNames[] = {"rock", "berry", "tentacle", "mushroom", "spur"};

/// A shape file: its base, details and edits, and each level's counts.
int runShapeInfo(const std::string& path)
{
    const ShapeSpec spec = readShapeFile(path);
    const BaseShape base = makeBase(spec.base, spec.source, Device::OpenCL);
    checkSynthesisMemory(base.mesh, spec.levels, path);
    const MultiresSurface surface(base.mesh, spec.levels, path);
    fmt::print("shape      {}\n", path);
    fmt::print("base       {}{}: {} points, {} faces\n", kBaseNames[int(spec.base.type)],
               spec.base.file.empty() ? "" : " " + spec.base.file, base.mesh.points.size(),
               base.mesh.faceCount());
    fmt::print("levels     {}\n", spec.levels);
    for (int l = 0; l <= surface.levels(); ++l)
        fmt::print("  level {}: {} vertices, {} faces\n", l,
                   formatCount(double(surface.level(l).vertexCount())),
                   formatCount(double(surface.level(l).faceCount())));
    for (const DetailSpec& d : spec.details) {
        std::string levels;
        for (int l : d.levels)
            levels += (levels.empty() ? "" : ", ") + std::to_string(l);
        fmt::print("detail     {} at levels {}\n", kDetailNames[int(d.type)], levels);
    }
    for (const EditSpec& e : spec.edits)
        fmt::print("edit       gain {} within {} of {}\n", e.gain, e.radius, formatVec(e.at));
    return 0;
}

int runInfo(const std::string& scenePath, const ModelOptions& model)
{
    if (looksLikeShapeFile(scenePath))
        return runShapeInfo(scenePath);
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
                    "(docs/growth-format.md), shape (docs/shape-format.md), L-system (.l, "
                    "docs/lsystem-format.md) or skeleton (docs/skeleton-format.md)")
        ->required();
    addModelFlags(cmd, o->model);
    cmd->callback([o, &action] { action = [o] { return runInfo(o->scene, o->model.options()); }; });
}

}  // namespace cambium
