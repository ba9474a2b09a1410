// cambium — reading baked level sets back.
#include "use/grid_file.h"

#include "bake/vdb_io.h"
#include "core/error.h"
#include "core/frames.h"

#include <fmt/format.h>
#include <openvdb/io/File.h>

#include <filesystem>

namespace cambium {

LevelSetFile readLevelSet(const std::string& path, const std::string& grid)
{
    // A damaged file is named here, before OpenVDB decodes it: its structure,
    // and for cambium's own files the checksum of every byte.
    verifyVdbChecksum(path, inspectVdb(path));
    openvdb::GridPtrVecPtr grids;
    try {
        openvdb::io::File file(path);
        file.open(false);  // read whole now: no private copy of the file for delayed loading
        grids = file.getGrids();
        file.close();
    } catch (const std::exception& e) {
        throw InputError(fmt::format("{}: cannot read it as a .vdb file: {}", path, e.what()));
    }
    LevelSetFile out;
    std::string names;
    for (const auto& g : *grids) {
        names += (names.empty() ? "" : ", ") + g->getName();
        if (g->getName() == grid) {
            out.surface = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
            if (!out.surface || g->getGridClass() != openvdb::GRID_LEVEL_SET)
                throw InputError(fmt::format("{}: grid '{}' is a {} {}, not a float level set", path, grid,
                                             g->valueType(), openvdb::GridBase::gridClassToString(g->getGridClass())));
        }
        if (g->getName() == "Cd")
            out.color = openvdb::gridPtrCast<openvdb::Vec3fGrid>(g);
    }
    if (!out.surface)
        throw InputError(
            fmt::format("{}: no grid named '{}' (it holds: {})", path, grid, names.empty() ? "no grids" : names));
    return out;
}

void forEachFile(const std::string& input, const std::string& output, const std::string& frames,
                 const std::function<void(const std::string&)>& checkOutput,
                 const std::function<void(const std::string&, const std::string&)>& one)
{
    if (!isFramePattern(input) && !isFramePattern(output) && frames.empty()) {
        checkOutput(output);
        one(input, output);
        return;
    }
    if (!isFramePattern(input) || !isFramePattern(output) || frames.empty())
        throw InputError(fmt::format("a sequence needs an input and an output with a run of '#' for the frame "
                                     "number, and --frames (e.g. out/tree.####.vdb --frames 1-10 -o {})",
                                     isFramePattern(output) ? output : "out/tree.####" +
                                         std::filesystem::path(output).extension().string()));
    const std::vector<long long> list = parseFrames(frames);
    for (long long f : list) {
        const std::string in = framePath(input, f);
        if (!std::filesystem::exists(in))
            throw InputError(fmt::format("{}: no such file (frame {} of --frames {})", in, f, frames));
    }
    checkOutput(framePath(output, list.front()));
    for (long long f : list)
        one(framePath(input, f), framePath(output, f));
}

}  // namespace cambium
