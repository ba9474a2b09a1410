// cambium — a sequence plan as a Slurm job array.
#include "farm/slurm.h"

#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "core/hash.h"
#include "core/json.h"
#include "io/vdb.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace cambium {

namespace fs = std::filesystem;

std::string shellQuote(const std::string& s)
{
    std::string out = "'";
    for (char c : s)
        out += c == '\'' ? std::string("'\\''") : std::string(1, c);
    return out + "'";
}

std::vector<std::string> bakeArguments(const BakeRequest& b, double voxelSize)
{
    std::vector<std::string> a = {"bake",         fs::absolute(b.input).string(),
                                  "--voxel-size", fmt::format("{}", voxelSize),
                                  "--half-width", fmt::format("{}", b.halfWidth),
                                  "--device",     b.device == Device::Cpu ? "cpu" : "opencl",
                                  "-o",           fs::absolute(b.output).string()};
    const ModelOptions& m = b.model;
    using J = ModelOptions::Junctions;
    using P = ModelOptions::Primitives;
    if (m.junctions)
        a.insert(a.end(), {"--junctions", *m.junctions == J::Pcm      ? "pcm"
                                          : *m.junctions == J::Smooth ? "smooth"
                                                                      : "blend"});
    if (m.bendDegrees != 0.0)
        a.insert(a.end(), {"--bend", fmt::format("{}", m.bendDegrees)});
    if (m.primitives != P::Cone)
        a.insert(a.end(),
                 {"--primitives", m.primitives == P::Convolution ? "convolution" : "mixed"});
    if (m.regrowth != 0.0)
        a.insert(a.end(), {"--regrowth", fmt::format("{}", m.regrowth)});
    if (m.time)
        a.insert(a.end(), {"--time", fmt::format("{}", *m.time)});
    if (!m.leaves)
        a.push_back("--no-leaves");
    if (b.fog)
        a.push_back("--fog");
    if (b.half)
        a.push_back("--half");
    if (!b.barkPhoto.empty())
        a.insert(a.end(), {"--bark-photo", fs::absolute(b.barkPhoto).string()});
    if (b.barkCoherent)
        a.insert(a.end(), {"--bark-colouring", *b.barkCoherent ? "coherent" : "random"});
    if (b.threads > 0)
        a.insert(a.end(), {"--threads", std::to_string(b.threads)});
    return a;
}

std::vector<std::string> chunkBakeArguments(const SequencePlan& plan, const std::string& frames,
                                            const std::string& threads)
{
    const SequenceRequest& r = plan.request;
    BakeRequest b = r.bake;
    b.threads = 0;
    std::vector<std::string> a = bakeArguments(b, plan.voxelSize);
    a.insert(a.end(), {"--frames", frames, "--fps-per-year", fmt::format("{}", r.fpsPerYear),
                       "--resume", "--jobs", "1", "--threads", threads});
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
    s.finalScriptPath = (farm / "final.sh").string();
    s.jobName = "cambium-" + name;
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
    j["script"] = s.scriptPath;
    j["final_script"] = s.finalScriptPath;
    j["retries"] = o.retries;
    j["throttle"] = o.throttle;
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
    sc += fmt::format("#SBATCH --job-name={}\n", s.jobName);
    sc += fmt::format("#SBATCH --array=0-{}{}\n", s.chunks.size() - 1,
                      o.throttle > 0 ? fmt::format("%{}", o.throttle) : "");
    sc += fmt::format("#SBATCH --cpus-per-task={}\n", s.resources.cpus);
    sc += fmt::format("#SBATCH --mem={}M\n", s.resources.memoryMB);
    sc += fmt::format("#SBATCH --output={}\n", (farm / "task-%a.log").string());
    sc += "#SBATCH --open-mode=append\n";  // (a chunk submitted again adds to its log)
    sc += fmt::format("#SBATCH --chdir={}\n", farm.string());
    for (const std::string& arg : o.sbatchArgs)
        sc += "#SBATCH " + arg + "\n";
    sc += fmt::format("# cambium: {} frames of {} in {} chunks ({}); the plan is {}\n",
                      plan.frames.size(), input, s.chunks.size(), plan.request.frames, s.planPath);
    sc += "set -u\n";
    // Caches in the farm's directory, never in $HOME (the submission copies
    // the user's compiled kernels there).
    const std::string caches =
        "export CAMBIUM_CACHE_DIR=" + shellQuote((farm / "cache" / "cambium").string()) + "\n" +
        "export POCL_CACHE_DIR=" + shellQuote((farm / "cache" / "pocl").string()) + "\n";
    sc += caches;
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
    // The status with the array's job id, added to the chunk's history
    // (readChunkEvents).
    sc += "echo \"$status ${SLURM_ARRAY_JOB_ID:-}\" >>" + shellQuote((farm / "task-").string()) +
          "\"$SLURM_ARRAY_TASK_ID\".status\n";
    sc += "exit \"$status\"\n";
    s.script = sc;

    // The final job: after the array, whatever its tasks did (afterany, given
    // by the submission), one core and little memory (it reads headers).
    std::string fin = "#!/bin/bash\n";
    fin += fmt::format("#SBATCH --job-name={}\n", s.jobName);
    fin += "#SBATCH --cpus-per-task=1\n#SBATCH --mem=512M\n";
    fin += fmt::format("#SBATCH --output={}\n", (farm / "final-%j.log").string());
    fin += fmt::format("#SBATCH --chdir={}\n", farm.string());
    for (const std::string& arg : o.sbatchArgs)
        fin += "#SBATCH " + arg + "\n";
    fin += "# cambium: checks every frame of " + s.planPath +
           ", writes manifest.json and submits the failed chunks again\n";
    fin += caches;
    fin += "exec " + shellQuote(o.exe) + " farm --finish " + shellQuote(farm.string()) + "\n";
    s.finalScript = fin;
    return s;
}

FarmPlan readFarmPlan(const std::string& farmDir)
{
    const std::string path = (fs::path(farmDir) / "plan.json").string();
    const nlohmann::json j = parseJson(readTextFile(path, "farm plan"), path);
    const JsonValidator v(path);
    v.object(j, "", "a farm plan (an object)");
    if (!j.contains("cambium_farm_plan"))
        v.fail("cambium_farm_plan", "missing: not a plan cambium bake --slurm wrote");
    FarmPlan p;
    p.dir = fs::absolute(farmDir).string();
    p.output = v.string(v.required(j, "output", ""), "output");
    frameRun(p.output);  // (a pattern with one run of '#')
    p.key = v.string(v.required(j, "key", ""), "key");
    p.scriptPath = v.string(v.required(j, "script", ""), "script");
    p.finalScriptPath = v.string(v.required(j, "final_script", ""), "final_script");
    p.retries = int(v.number(v.required(j, "retries", ""), "retries", 0, 100));
    p.throttle = int(v.number(v.required(j, "throttle", ""), "throttle", 0, 1e9));
    const nlohmann::json& chunks = v.required(j, "chunks", "");
    if (!chunks.is_array() || chunks.empty())
        v.fail("chunks", "must be an array of chunks");
    for (size_t k = 0; k < chunks.size(); ++k) {
        const std::string at = fmt::format("chunks[{}]", k);
        const std::string frames =
            v.string(v.required(v.object(chunks[k], at, "a chunk"), "frames", at), at + ".frames");
        parseFrames(frames, path + ": " + at + ".frames");
        p.chunks.push_back(frames);
    }
    return p;
}

size_t FarmState::badInput() const
{
    return size_t(std::count_if(chunks.begin(), chunks.end(),
                                [](const FarmChunkState& c) { return c.badInput(); }));
}

size_t FarmState::failed() const
{
    return size_t(std::count_if(chunks.begin(), chunks.end(),
                                [](const FarmChunkState& c) { return !c.done(); }));
}

namespace {
fs::path chunkEventsPath(const std::string& farmDir, size_t chunk)
{
    return fs::path(farmDir) / fmt::format("task-{}.status", chunk);
}
constexpr const char* kSubmittedAgain = "submitted again";
}  // namespace

std::vector<ChunkEvent> readChunkEvents(const std::string& farmDir, size_t chunk)
{
    std::vector<ChunkEvent> events;
    std::ifstream in(chunkEventsPath(farmDir, chunk));
    for (std::string line; std::getline(in, line);) {
        ChunkEvent e;
        if (line == kSubmittedAgain)
            e.again = true;
        else if (std::istringstream words(line); !(words >> e.status))
            continue;  // (a line cut short by a node's crash)
        events.push_back(e);
    }
    return events;
}

void markSubmittedAgain(const std::string& farmDir, size_t chunk)
{
    const fs::path path = chunkEventsPath(farmDir, chunk);
    std::string text;
    if (fs::exists(path))
        text = readTextFile(path.string(), "chunk status");
    if (!text.empty() && text.back() != '\n')
        text += '\n';
    text += std::string(kSubmittedAgain) + "\n";
    writeFile(path.string(), text.data(), text.size());
}

FarmState assessFarm(const FarmPlan& plan)
{
    // Attempts so far: an earlier final job's count, one more where it
    // submitted the chunk again.
    std::vector<int> attempts(plan.chunks.size(), 1);
    const fs::path manifest = fs::path(plan.dir) / "manifest.json";
    if (fs::exists(manifest)) {
        try {
            const nlohmann::json m =
                parseJson(readTextFile(manifest.string(), "farm manifest"), manifest.string());
            const nlohmann::json& chunks = m.at("chunks");
            for (size_t k = 0; k < plan.chunks.size() && k < chunks.size(); ++k)
                attempts[k] = chunks[k].at("attempts").get<int>() +
                              (chunks[k].at("resubmitted").get<bool>() ? 1 : 0);
        } catch (const std::exception& e) {
            throw InputError(
                fmt::format("{}: not a manifest cambium wrote ({}): remove it to count the "
                            "attempts from one",
                            manifest.string(), e.what()));
        }
    }
    FarmState s;
    for (size_t k = 0; k < plan.chunks.size(); ++k) {
        FarmChunkState c;
        c.frames = plan.chunks[k];
        c.attempts = attempts[k];
        const std::vector<ChunkEvent> events = readChunkEvents(plan.dir, k);
        c.status = events.empty() || events.back().again ? -1 : events.back().status;
        for (long long f : parseFrames(c.frames)) {
            std::string key;
            try {
                key = readSequenceKey(framePath(plan.output, f));
            } catch (const InputError&) {
            }
            ++s.frames;
            if (key == plan.key)
                ++s.good;
            else
                c.missing.push_back(f);
        }
        s.chunks.push_back(std::move(c));
    }
    return s;
}

std::vector<size_t> chunksToRetry(const FarmPlan& plan, const FarmState& state)
{
    std::vector<size_t> out;
    for (size_t k = 0; k < state.chunks.size(); ++k) {
        const FarmChunkState& c = state.chunks[k];
        if (!c.done() && !c.badInput() && c.attempts <= plan.retries)
            out.push_back(k);
    }
    return out;
}

std::string describeStatus(int status)
{
    return status == 0   ? "done"
           : status == 2 ? "failed: bad input (exit 2; see its log)"
           : status < 0  ? "ended without a status (cancelled or killed)"
                         : fmt::format("failed (exit {})", status);
}

std::string describeChunk(const FarmChunkState& c)
{
    if (c.done())
        return "done";
    const std::string frames = c.missing.size() == 1
                                   ? fmt::format("frame {} missing", c.missing.front())
                                   : fmt::format("{} frames missing", c.missing.size());
    return (c.status == 0 ? std::string("ended (exit 0)") : describeStatus(c.status)) + ", " +
           frames;
}

std::string farmManifest(const FarmPlan& plan, const FarmState& state,
                         const std::vector<size_t>& resubmitted)
{
    nlohmann::ordered_json j;
    j["cambium_farm_manifest"] = 1;
    j["output"] = plan.output;
    j["key"] = plan.key;
    j["complete"] = state.good == state.frames;
    j["frames"] = state.frames;
    j["frames_written"] = state.good;
    nlohmann::ordered_json chunks = nlohmann::ordered_json::array();
    nlohmann::ordered_json files = nlohmann::ordered_json::array();
    for (size_t k = 0; k < state.chunks.size(); ++k) {
        const FarmChunkState& c = state.chunks[k];
        const bool again =
            std::find(resubmitted.begin(), resubmitted.end(), k) != resubmitted.end();
        chunks.push_back({{"frames", c.frames},
                          {"status", c.status},
                          {"attempts", c.attempts},
                          {"state", describeChunk(c)},
                          {"resubmitted", again}});
        for (long long f : parseFrames(c.frames)) {
            const std::string path = framePath(plan.output, f);
            const bool ok = std::find(c.missing.begin(), c.missing.end(), f) == c.missing.end();
            std::error_code ec;
            const auto bytes = fs::file_size(path, ec);
            files.push_back({{"frame", f},
                             {"path", path},
                             {"ok", ok},
                             {"bytes", ec ? 0 : (unsigned long long)bytes}});
        }
    }
    j["chunks"] = chunks;
    j["files"] = files;
    return j.dump(2) + "\n";
}

}  // namespace cambium
