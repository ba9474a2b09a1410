// cambium info — a model's node counts by type, depth and bounds.
#include "app/app.h"

#include "blobtree/stats.h"
#include "core/clock.h"
#include "core/error.h"
#include "core/system.h"
#include "core/files.h"
#include "io/vdb_header.h"
#include "model/load_model.h"
#include "shape/synthesis.h"

#include <fmt/format.h>

#include <algorithm>

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

/// A .vdb file: what vdb_print says and cambium's metadata, from the file's
/// structure and its grids' metadata (no tree read); `check`: every byte
/// against cambium's checksum.
int runVdbInfo(const std::string& path, bool check)
{
    const auto start = Clock::now();
    const VdbDescription d = describeVdb(path);
    const VdbSummary& s = d.summary;
    auto text = [&](const char* key) {
        const auto it = s.strings.find(key);
        return it == s.strings.end() ? std::string() : it->second;
    };
    // The checksum's verdict first: a file --check refuses prints nothing
    // (its "file" line came before the error).
    std::string checksum;
    if (const std::string missing = missingChecksum(path, s); !missing.empty()) {
        if (check)
            throw InputError(missing);
        checksum = "missing: " + missing;
    } else if (s.checksumEnd == 0) {
        checksum = "none (not written by cambium)";
    } else if (!check) {
        checksum = "present, not verified (--check reads every byte)";
    } else {
        const auto t = Clock::now();
        verifyVdbChecksum(path, s);  // (InputError when it does not hold)
        checksum = fmt::format("holds: every byte as written ({:.2f} s)", secondsSince(t));
    }
    fmt::print("file       {}: {} bytes, OpenVDB file format {}{}\n", path,
               formatCount(double(s.bytes)), s.fileVersion,
               text("creator").empty() ? "" : ", written by " + text("creator"));
    if (!text("cambium_sequence").empty())
        fmt::print("sequence   {}{}\n", text("cambium_sequence"),
                   text("cambium_part").empty() ? "" : ", " + text("cambium_part"));
    fmt::print("checksum   {}\n", checksum);
    for (const VdbGridDescription& g : d.grids) {
        fmt::print(
            "grid       {}: {}{}{}, {} active voxels{}\n", g.name, g.valueType,
            g.gridClass == "unknown" ? "" : " " + g.gridClass, g.half ? " (stored as halves)" : "",
            g.activeVoxels < 0 ? "an unrecorded number of" : formatCount(double(g.activeVoxels)),
            g.leaves < 0 ? "" : fmt::format(" in {} leaves", formatCount(double(g.leaves))));
        fmt::print("  voxel    {}\n", formatVec(g.voxelSize));
        if (g.bounded) {
            fmt::print("  index    ({}, {}, {}) to ({}, {}, {}): {} x {} x {} voxels\n",
                       g.indexMin[0], g.indexMin[1], g.indexMin[2], g.indexMax[0], g.indexMax[1],
                       g.indexMax[2], g.indexMax[0] - g.indexMin[0] + 1,
                       g.indexMax[1] - g.indexMin[1] + 1, g.indexMax[2] - g.indexMin[2] + 1);
            fmt::print("  world    {} to {}\n", formatVec(g.worldMin), formatVec(g.worldMax));
        } else {
            fmt::print("  bounds   not recorded{}\n",
                       g.activeVoxels == 0 ? " (no active voxels)" : "");
        }
        fmt::print(
            "  memory   {} in core; {} in the file{}\n",
            g.memoryBytes < 0 ? std::string("unrecorded") : formatBytes(double(g.memoryBytes)),
            formatBytes(double(g.fileBytes)),
            g.compression.empty() ? "" : " (" + g.compression + ")");
        for (const auto& [key, value] : g.metadata)
            fmt::print("  {:<22} {}\n", key, value);
    }
    fmt::print("read       {:.3f} s\n", secondsSince(start));
    return 0;
}

int runInfo(const std::string& scenePath, const ModelOptions& model, bool check)
{
    // (a FIFO's read for the magic number waited for ever)
    checkInputFile(scenePath, "model or .vdb file");
    // (a .vdb too short for its magic number is named as one, damaged: it
    // was read as a skeleton file, "no internodes")
    if (looksLikeVdbFile(scenePath) || fileExtension(scenePath) == "vdb")
        return runVdbInfo(scenePath, check);
    if (check)
        throw InputError("--check verifies a .vdb file's checksum: give a .vdb file");
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
        bool check = false;
    };
    auto o = std::make_shared<Options>();
    auto* cmd = app.add_subcommand(
        "info", "Print a scene's node counts by type, depth and bounds, or a .vdb file's grids");
    cmd->add_option("scene", o->scene,
                    "Scene (JSON, docs/scene-format.md), growth parameters "
                    "(docs/growth-format.md), shape (docs/shape-format.md), L-system (.l, "
                    "docs/lsystem-format.md), skeleton (docs/skeleton-format.md) or .vdb file")
        ->required();
    addModelFlags(cmd, o->model);
    cmd->add_flag("--check", o->check,
                  "A .vdb file: read every byte and check it against cambium's checksum");
    cmd->callback(
        [o, &action] { action = [o] { return runInfo(o->scene, o->model.options(), o->check); }; });
}

}  // namespace cambium
