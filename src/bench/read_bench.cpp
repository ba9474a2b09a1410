// cambium — `cambium bench read` (bench/read_bench.h).
#include "bench/read_bench.h"

#include "core/error.h"
#include "core/files.h"
#include "core/system.h"
#include "io/vdb.h"
#include "use/mesh.h"

#include <fmt/format.h>

#include <filesystem>
#include <unistd.h>

namespace cambium {

void runReadBench(const ReadBenchRequest& req, const std::function<void()>& checked,
                  const std::function<void(const ReadBenchFile&)>& done)
{
    namespace fs = std::filesystem;
    const ScratchDirectory scratch(ScratchDirectory::temporaryPath("read_bench"));
    const fs::path dir = scratch.path();
    const std::string exe = executableDirectory(), log = (dir / "log.txt").string();
    const std::string cambium = exe + "/cambium", peer = exe + "/cambium-vdbpeer";
    std::vector<std::pair<std::string, std::string>> files;  // label, path
    for (const std::string& f : req.files) {
        // Checked as render and mesh check them, every grid's tree walked
        // and the surface read, before the plain OpenVDB peer reads it whole
        // (a byte of another tool's file crashed it; a surface labelled
        // vec3s made it spin; a 382-byte file of one active root tile ran
        // its volumeToMesh out of memory, sweep 20).
        VdbSummary summary = checkLevelSetFile(f);
        for (const VdbSummary::Grid& g : summary.grids)
            checkTreeStructure(f, g, true);
        // The peers read it whole and mesh it, as `cambium mesh` does: the
        // surface's memory and its meshing's, and the other grids' values,
        // checked once the surface read here is freed (the plain OpenVDB
        // peer ran out of memory where cambium's own read fitted, and Blosc
        // crashed it, sweep 25).
        double need = 0.0;
        {
            const LevelSetGrids g = readLevelSet(f, kSurfaceGrid, ColourRead::None, &summary);
            need = double(g.surface->memUsage()) + meshingBytes(*g.surface, true);
        }
        for (const VdbSummary::Grid& g : summary.grids)
            if (g.name != kSurfaceGrid && g.leaves > 0)
                need += double(g.leaves) * 512.0 * double(g.valueBytes);
        checkMemoryFits(need, fmt::format("{}: reading it whole and meshing it", f),
                        "benchmark it on a machine with more memory");
        files.emplace_back(f, f);
    }
    checked();
    if (files.empty())
        for (const char* colour : {"band", "shell"}) {
            const std::string out = (dir / fmt::format("{}.vdb", colour)).string();
            runProcess(
                {cambium, "bake", req.parameters, "--year", fmt::format("{}", req.year),
                 "--voxel-size", fmt::format("{}", req.voxelSize), "--colour", colour, "-o", out},
                log);
            files.emplace_back(
                fmt::format("year {} at {}, --colour {}", req.year, req.voxelSize, colour), out);
        }
    const std::string png = (dir / "picture.png").string(), ply = (dir / "mesh.ply").string();
    for (const auto& [label, path] : files) {
        checkInputFile(path, ".vdb file");
        ReadBenchFile r;
        r.label = label;
        r.path = path;
        r.bytes = double(fs::file_size(path));
        const std::vector<std::pair<std::string, std::vector<std::string>>> commands = {
            {"OpenVDB io::File, every grid", {peer, "read", path}},
            {"OpenVDB io::File, surface", {peer, "read", path, "surface"}},
            {"OpenVDB io::File + volumeToMesh", {peer, "mesh", path}},
            {"cambium's reader (surface and Cd)", {peer, "cambium", path}},
            {fmt::format("cambium render {}x{}, {} spp", req.width, req.height, req.spp),
             {cambium, "render", path, "-o", png, "--width", std::to_string(req.width), "--height",
              std::to_string(req.height), "--spp", std::to_string(req.spp)}},
            {"cambium mesh (PLY written)", {cambium, "mesh", path, "-o", ply}},
            {"cambium info", {cambium, "info", path}}};
        std::vector<std::vector<ProcessRun>> runs(commands.size());
        // Every command in turn, round after round: a drift of the machine's
        // speed touches them alike.
        for (int rep = 0; rep < std::max(1, req.repeats); ++rep)
            for (size_t k = 0; k < commands.size(); ++k)
                runs[k].push_back(runProcess(commands[k].second, log));
        for (size_t k = 0; k < commands.size(); ++k)
            r.rows.push_back({commands[k].first, summariseRuns(runs[k])});
        done(r);
    }
}

}  // namespace cambium
