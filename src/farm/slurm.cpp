// cambium — a sequence plan as a Slurm job array.
#include "farm/slurm.h"

#include "core/error.h"
#include "core/frames.h"
#include "core/hash.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <filesystem>

namespace cambium {

namespace fs = std::filesystem;

std::string shellQuote(const std::string& s)
{
    std::string out = "'";
    for (char c : s)
        out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

std::vector<std::string> chunkBakeArguments(const SequencePlan& plan, const std::string& frames,
                                            const std::string& threads)
{
    const SequenceRequest& r = plan.request;
    const BakeRequest& b = r.bake;
    std::vector<std::string> a = {"bake",
                                  fs::absolute(b.input).string(),
                                  "--frames",
                                  frames,
                                  "--fps-per-year",
                                  fmt::format("{}", r.fpsPerYear),
                                  "--voxel-size",
                                  fmt::format("{}", plan.voxelSize),
                                  "--half-width",
                                  fmt::format("{}", b.halfWidth),
                                  "--device",
                                  b.device == Device::Cpu ? "cpu" : "opencl",
                                  "-o",
                                  fs::absolute(b.output).string(),
                                  "--resume",
                                  "--jobs",
                                  "1",
                                  "--threads",
                                  threads};
    if (!b.model.leaves)
        a.push_back("--no-leaves");
    if (b.fog)
        a.push_back("--fog");
    if (b.half)
        a.push_back("--half");
    if (!b.barkPhoto.empty())
        a.insert(a.end(), {"--bark-photo", fs::absolute(b.barkPhoto).string()});
    if (b.barkCoherent)
        a.insert(a.end(), {"--bark-colouring", *b.barkCoherent ? "coherent" : "random"});
    return a;
}

SlurmArray planSlurmArray(const SequencePlan& plan, const SlurmOptions& o)
{
    SlurmArray s;
    const fs::path output = fs::absolute(plan.request.bake.output);
    // OUTDIR/NAME.frames.vdb.farm for OUTDIR/NAME.####.vdb: no '#' in the
    // paths of #SBATCH lines.
    std::string name = output.filename().string();
    const auto [hashFirst, hashLast] = frameRun(name);
    name.replace(hashFirst, hashLast - hashFirst, "frames");
    const fs::path farm = output.parent_path() / (name + ".farm");
    // #SBATCH lines take their values unquoted: a space ends one, and '%'
    // starts one of Slurm's file name patterns.
    if (farm.string().find_first_of(" \t\n%'\"\\$") != std::string::npos)
        throw InputError(fmt::format(
            "-o {}: --slurm needs an output path without spaces, '%', quotes, '\\' or '$' (the "
            "batch script's #SBATCH lines name its directory)",
            output.string()));
    s.farmDir = farm.string();
    s.planPath = (farm / "plan.json").string();
    s.scriptPath = (farm / "array.sh").string();
    s.chunks = chunkPlan(plan, o.framesPerChunk);
    s.resources = taskResources(plan, o.nodeCpus, o.nodeMemoryBytes);

    const std::string input = fs::absolute(plan.request.bake.input).string();
    nlohmann::ordered_json j;
    j["cambium_farm_plan"] = 1;
    j["input"] = input;
    j["input_hash"] = fmt::format("{:016x}", fnv1a64(readTextFile(input, "growth parameter file")));
    j["output"] = output.string();
    j["key"] = plan.key;
    j["voxel_size"] = plan.voxelSize;
    j["fps_per_year"] = plan.request.fpsPerYear;
    j["frames"] = plan.request.frames;
    j["memory_per_task_mb"] = s.resources.memoryMB;
    j["cpus_per_task"] = s.resources.cpus;
    nlohmann::ordered_json chunks = nlohmann::ordered_json::array();
    for (const FarmChunk& c : s.chunks)
        chunks.push_back({{"frames", c.frames},
                          {"first", plan.frames[c.first]},
                          {"last", plan.frames[c.last - 1]},
                          {"count", c.last - c.first}});
    j["chunks"] = chunks;
    s.planJson = j.dump(2) + "\n";

    // The script: Slurm reads its #SBATCH lines; task i runs chunk i and
    // leaves its exit status beside the logs for the final job, which tells
    // a frame's bad input (2: never retried) from a failure (retried).
    std::string sc = "#!/bin/bash\n";
    sc += fmt::format("#SBATCH --job-name=cambium-{}\n", name);
    sc += fmt::format("#SBATCH --array=0-{}{}\n", s.chunks.size() - 1,
                      o.throttle > 0 ? fmt::format("%{}", o.throttle) : "");
    sc += fmt::format("#SBATCH --cpus-per-task={}\n", s.resources.cpus);
    sc += fmt::format("#SBATCH --mem={}M\n", s.resources.memoryMB);
    sc += fmt::format("#SBATCH --output={}\n", (farm / "task-%a.log").string());
    sc += fmt::format("#SBATCH --chdir={}\n", farm.string());
    for (const std::string& arg : o.sbatchArgs)
        sc += "#SBATCH " + arg + "\n";
    sc += fmt::format("# cambium: {} frames of {} in {} chunks ({}); the plan is {}\n",
                      plan.frames.size(), input, s.chunks.size(), plan.request.frames, s.planPath);
    sc += "set -u\n";
    // Caches in the farm's directory, never in $HOME (the submission copies
    // the user's compiled kernels there).
    sc += "export CAMBIUM_CACHE_DIR=" + shellQuote((farm / "cache" / "cambium").string()) + "\n";
    sc += "export POCL_CACHE_DIR=" + shellQuote((farm / "cache" / "pocl").string()) + "\n";
    sc += "case \"$SLURM_ARRAY_TASK_ID\" in\n";
    for (size_t k = 0; k < s.chunks.size(); ++k)
        sc += fmt::format("{}) frames={} ;;\n", k, s.chunks[k].frames);
    sc += "*) echo \"cambium: no chunk $SLURM_ARRAY_TASK_ID in this plan\" >&2; exit 2 ;;\nesac\n";
    std::string command = shellQuote(o.exe);
    for (const std::string& a : chunkBakeArguments(plan, "@FRAMES@", "@THREADS@"))
        command += " " + (a == "@FRAMES@"    ? std::string("\"$frames\"")
                          : a == "@THREADS@" ? std::string("\"${SLURM_CPUS_PER_TASK:-1}\"")
                                             : shellQuote(a));
    sc += command + "\n";
    sc += "status=$?\n";
    sc += "echo \"$status\" >" + shellQuote((farm / "task-").string()) +
          "\"$SLURM_ARRAY_TASK_ID\".status\n";
    sc += "exit \"$status\"\n";
    s.script = sc;
    return s;
}

}  // namespace cambium
