// cambium — a sequence plan as a Slurm job array.
#include "farm/slurm.h"

#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "core/hash.h"
#include "core/math.h"
#include "core/json.h"
#include "io/vdb_header.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace cambium {

namespace fs = std::filesystem;

/// The plan.json layout this cambium writes and reads.
constexpr int kFarmPlanVersion = 2;  // (2: with plan_hash)

/// The hash a plan carries of its own fields (`plan_hash`: of its JSON with
/// sorted keys, without that field), so that an edited plan is told.
std::string planHash(nlohmann::json plan)
{
    plan.erase("plan_hash");
    return fmt::format("{:016x}", fnv1a64(plan.dump()));
}

/// The plan's text, its hash among its fields.
std::string planText(nlohmann::ordered_json plan)
{
    plan["plan_hash"] = planHash(nlohmann::json::parse(plan.dump()));
    return plan.dump(2) + "\n";
}

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
                                  "--device",     deviceName(b.device),
                                  "-o",           fs::absolute(b.output).string()};
    const ModelOptions& m = b.model;
    if (m.junctions)
        a.insert(a.end(), {"--junctions", junctionsName(*m.junctions)});
    if (m.bendDegrees != 0.0)
        a.insert(a.end(), {"--bend", fmt::format("{}", m.bendDegrees)});
    if (m.primitives != ModelOptions::Primitives::Cone)
        a.insert(a.end(), {"--primitives", primitivesName(m.primitives)});
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
    if (b.colour != ColourExtent::Shell)
        a.insert(a.end(), {"--colour", colourExtentName(b.colour)});
    // (always: a tile farm's key is made of these, and a farm planned
    // before the bake thickened its thin parts holds other tiles)
    a.insert(a.end(), {"--min-radius", fmt::format("{}", b.minRadius)});
    if (!b.barkPhoto.empty())
        a.insert(a.end(), {"--bark-photo", fs::absolute(b.barkPhoto).string()});
    if (b.barkCoherent)
        a.insert(a.end(), {"--bark-colouring", kBarkColourings[*b.barkCoherent ? 0 : 1]});
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

namespace {

constexpr const char* kPart = "\x01part\x01";
constexpr const char* kNumber = "\x01number\x01";
constexpr const char* kThreads = "\x01threads\x01";

/// A path the batch script names: InputError where it holds a control
/// character (a newline would end a line of the script).
void checkScriptPath(const std::string& path, const char* what)
{
    for (char c : path)
        if ((unsigned char)c < 0x20 || c == 0x7f)
            throw InputError(fmt::format(
                "{} {}: --slurm needs paths without control characters (the batch script names "
                "them)",
                what, path));
}

/// A farm's directory beside `output`, OUTDIR/NAME.farm: refused where
/// #SBATCH lines could not name it (they take their values unquoted: a
/// space ends one, and '%' starts one of Slurm's file name patterns).
fs::path farmDirectory(const fs::path& output, const std::string& name)
{
    const fs::path farm = output.parent_path() / (name + ".farm");
    if (farm.string().find_first_of(" \t\n%'\"\\$") != std::string::npos)
        throw InputError(fmt::format(
            "-o {}: --slurm needs an output path without spaces, '%', quotes, '\\' or '$' (the "
            "batch script's #SBATCH lines name its directory)",
            output.string()));
    checkScriptPath(output.string(), "-o");
    return farm;
}

/// The array's and the final job's scripts of `s` (its farmDir, jobName,
/// resources and chunks' parts set): task i sets $part to part i and runs
/// `command`, in whose arguments kPart, kNumber and kThreads stand for $part,
/// its number before a '/' and the task's cores, and adds its exit status to
/// the chunk's history.  (The placeholders hold a control character no path
/// cambium takes holds: farmDirectory refuses them.)
void writeScripts(SlurmArray& s, const std::vector<std::string>& parts,
                  const std::vector<std::string>& command, const std::string& what,
                  const SlurmOptions& o)
{
    const fs::path farm = s.farmDir;
    // The script: Slurm reads its #SBATCH lines; task i runs chunk i and
    // leaves its exit status beside the logs for the final job, which tells
    // bad input (2: never retried) from a failure (retried).
    std::string sc = "#!/bin/bash\n";
    sc += fmt::format("#SBATCH --job-name={}\n", s.jobName);
    sc += fmt::format("#SBATCH --array=0-{}{}\n", parts.size() - 1,
                      o.throttle > 0 ? fmt::format("%{}", o.throttle) : "");
    sc += fmt::format("#SBATCH --cpus-per-task={}\n", s.resources.cpus);
    sc += fmt::format("#SBATCH --mem={}M\n", s.resources.memoryMB);
    sc += fmt::format("#SBATCH --output={}\n", (farm / "task-%a.log").string());
    sc += "#SBATCH --open-mode=append\n";  // (a chunk submitted again adds to its log)
    sc += fmt::format("#SBATCH --chdir={}\n", farm.string());
    for (const std::string& arg : o.sbatchArgs)
        sc += "#SBATCH " + arg + "\n";
    sc += fmt::format("# cambium: {}; the plan is {}\n", what, s.planPath);
    sc += "set -u\n";
    // Caches in the farm's directory, never in $HOME (the submission copies
    // the user's compiled kernels there).
    const std::string caches =
        "export CAMBIUM_CACHE_DIR=" + shellQuote((farm / "cache" / "cambium").string()) + "\n" +
        "export POCL_CACHE_DIR=" + shellQuote((farm / "cache" / "pocl").string()) + "\n";
    sc += caches;
    sc += "case \"$SLURM_ARRAY_TASK_ID\" in\n";
    for (size_t k = 0; k < parts.size(); ++k)
        sc += fmt::format("{}) part={} ;;\n", k, parts[k]);
    sc += "*) echo \"cambium: no chunk $SLURM_ARRAY_TASK_ID in this plan\" >&2; exit 2 ;;\nesac\n";
    // Each argument a shell word: its text quoted, the placeholders in it
    // expanded.
    const std::pair<const char*, const char*> expansions[] = {
        {kPart, "\"$part\""},
        {kThreads, "\"${SLURM_CPUS_PER_TASK:-1}\""},
        {kNumber, "\"${part%%/*}\""}};
    std::string line = shellQuote(o.exe);
    for (const std::string& a : command) {
        std::string word, literal;
        for (size_t i = 0; i < a.size();) {
            bool expanded = false;
            for (const auto& [name, shell] : expansions)
                if (a.compare(i, std::strlen(name), name) == 0) {
                    word += (literal.empty() ? "" : shellQuote(literal)) + shell;
                    literal.clear();
                    i += std::strlen(name);
                    expanded = true;
                    break;
                }
            if (!expanded)
                literal += a[i++];
        }
        line += " " + word + (literal.empty() && !word.empty() ? "" : shellQuote(literal));
    }
    sc += line + "\n";
    sc += "status=$?\n";
    // The status with the array's job id, added to the chunk's history
    // (readChunkEvents).
    sc += "echo \"$status ${SLURM_ARRAY_JOB_ID:-}\" >>" + shellQuote((farm / "task-").string()) +
          "\"$SLURM_ARRAY_TASK_ID\".status\n";
    sc += "exit \"$status\"\n";
    s.script = sc;

    // The final job: after the array, whatever its tasks did (afterany, given
    // by the submission), one core; the frame's estimate where it merges
    // tiles (finalMemoryMB), else little (it reads headers).
    std::string fin = "#!/bin/bash\n";
    fin += fmt::format("#SBATCH --job-name={}\n", s.jobName);
    fin += fmt::format("#SBATCH --cpus-per-task=1\n#SBATCH --mem={}M\n", s.finalMemoryMB);
    fin += fmt::format("#SBATCH --output={}\n", (farm / "final-%j.log").string());
    fin += fmt::format("#SBATCH --chdir={}\n", farm.string());
    for (const std::string& arg : o.sbatchArgs)
        fin += "#SBATCH " + arg + "\n";
    fin += "# cambium: checks every file of " + s.planPath +
           " (a tile farm's: merges the tiles once all are there), writes manifest.json and "
           "submits the failed chunks again\n";
    fin += caches;
    fin += "exec " + shellQuote(o.exe) + " farm --finish " + shellQuote(farm.string()) + "\n";
    s.finalScript = fin;
}

/// The plan file's fields every farm has.
nlohmann::ordered_json planHeader(const SlurmArray& s, const std::string& kind,
                                  const std::string& input, const std::string& output,
                                  const std::string& key, double voxelSize, const SlurmOptions& o)
{
    nlohmann::ordered_json j;
    j["cambium_farm_plan"] = kFarmPlanVersion;
    j["kind"] = kind;
    j["input"] = input;
    j["input_hash"] = fmt::format("{:016x}", fnv1a64(readTextFile(input, "input file")));
    j["output"] = output;
    j["key"] = key;
    j["voxel_size"] = voxelSize;
    j["script"] = s.scriptPath;
    j["final_script"] = s.finalScriptPath;
    j["retries"] = o.retries;
    j["throttle"] = o.throttle;
    j["memory_per_task_mb"] = s.resources.memoryMB;
    j["cpus_per_task"] = s.resources.cpus;
    return j;
}

void nameFiles(SlurmArray& s, const fs::path& farm, const std::string& name)
{
    s.farmDir = farm.string();
    s.planPath = (farm / "plan.json").string();
    s.scriptPath = (farm / "array.sh").string();
    s.finalScriptPath = (farm / "final.sh").string();
    s.jobName = "cambium-" + name;
}

}  // namespace

SlurmArray planSlurmArray(const SequencePlan& plan, const SlurmOptions& o)
{
    SlurmArray s;
    const fs::path output = fs::absolute(plan.request.bake.output);
    // OUTDIR/NAME.frames.vdb.farm for OUTDIR/NAME.####.vdb: no '#' in the
    // paths of #SBATCH lines.
    std::string name = output.filename().string();
    const auto [hashFirst, hashLast] = frameRun(name);
    name.replace(hashFirst, hashLast - hashFirst, "frames");
    nameFiles(s, farmDirectory(output, name), name);
    s.chunks = chunkPlan(plan, o.framesPerChunk);
    s.resources = taskResources(plan.bytesPerFrame, o.nodeCpus, o.nodeMemoryBytes);

    const std::string input = fs::absolute(plan.request.bake.input).string();
    checkScriptPath(input, "input");
    checkScriptPath(plan.request.bake.barkPhoto, "--bark-photo");
    nlohmann::ordered_json j =
        planHeader(s, "frames", input, output.string(), plan.key, plan.voxelSize, o);
    j["fps_per_year"] = plan.request.fpsPerYear;
    j["frames"] = plan.request.frames;
    nlohmann::ordered_json chunks = nlohmann::ordered_json::array();
    std::vector<std::string> parts;
    for (const FarmChunk& c : s.chunks) {
        chunks.push_back({{"frames", c.frames},
                          {"first", plan.frames[c.first]},
                          {"last", plan.frames[c.last - 1]},
                          {"count", c.last - c.first}});
        parts.push_back(c.frames);
    }
    j["chunks"] = chunks;
    s.planJson = planText(j);
    writeScripts(s, parts, chunkBakeArguments(plan, kPart, kThreads),
                 fmt::format("{} frames of {} in {} chunks ({})", plan.frames.size(), input,
                             s.chunks.size(), plan.request.frames),
                 o);
    return s;
}

std::string tileFarmKey(const BakeRequest& request, int tiles)
{
    // What a tile's bake is given, whatever file it writes, its cores and
    // --half (a tile's file holds floats), and the input's text.
    BakeRequest r = request;
    r.output = "/";  // (dropped below)
    r.threads = 0;
    r.half = false;
    std::string text = fmt::format("tiles={}", tiles);
    const std::vector<std::string> args = bakeArguments(r, r.voxelSize.value_or(0.0));
    for (size_t i = 0; i < args.size(); ++i)
        if (args[i] == "-o")
            ++i;  // (its value too)
        else
            text += " " + args[i];
    return fmt::format("{:016x}", fnv1a64(text, fnv1a64(readTextFile(r.input, "input file"))));
}

std::string tilePath(const std::string& farmDir, size_t tile)
{
    return (fs::path(farmDir) / fmt::format("tile-{}.vdb", tile + 1)).string();
}

SlurmArray planTileArray(const TileFarmRequest& t, const SlurmOptions& o)
{
    SlurmArray s;
    const BakeRequest& r = t.request;
    const fs::path output = fs::absolute(r.output);
    // OUTDIR/NAME.vdb.tiles.farm for OUTDIR/NAME.vdb.
    const std::string name = output.filename().string() + ".tiles";
    nameFiles(s, farmDirectory(output, name), name);
    s.resources = taskResources(t.tileBytes, o.nodeCpus, o.nodeMemoryBytes);
    // The merge holds every tile's leaves packed: measured at 0.82 times the
    // single bake's peak (docs/farm.md); the frame's estimate asked for.
    s.finalMemoryMB = std::max(s.finalMemoryMB, taskResources(t.frameBytes, 1, 0.0).memoryMB);

    const std::string input = fs::absolute(r.input).string();
    checkScriptPath(input, "input");
    nlohmann::ordered_json j =
        planHeader(s, "tiles", input, output.string(), tileFarmKey(r, t.tiles), *r.voxelSize, o);
    j["tiles"] = t.tiles;
    j["half"] = r.half;
    j["threshold"] = t.threshold;
    j["time"] = t.time;
    j["half_width"] = r.halfWidth;
    j["scene"] = t.scene;
    std::vector<std::string> parts;
    nlohmann::ordered_json chunks = nlohmann::ordered_json::array();
    for (int k = 0; k < t.tiles; ++k) {
        parts.push_back(fmt::format("{}/{}", k + 1, t.tiles));
        chunks.push_back({{"tile", parts.back()}, {"file", tilePath(s.farmDir, size_t(k))}});
    }
    j["chunks"] = chunks;
    s.planJson = planText(j);
    // Task k: tile k+1 into the farm's tile-K.vdb, as floats (the merge
    // packs halves itself); "K/N" is the task's part.
    BakeRequest one = r;
    one.half = false;
    one.threads = 0;
    one.output = tilePath(s.farmDir, 0);
    std::vector<std::string> command = bakeArguments(one, *r.voxelSize);
    std::replace(command.begin(), command.end(), one.output,
                 (fs::path(s.farmDir) / (std::string("tile-") + kNumber + ".vdb")).string());
    command.insert(command.end(), {"--tile", kPart, "--threads", kThreads});
    writeScripts(
        s, parts, command,
        fmt::format("one frame of {} in {} tiles, merged into {}", input, t.tiles, output.string()),
        o);
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
    if (const nlohmann::json& version = j.at("cambium_farm_plan");
        !version.is_number_integer() || version.get<long long>() != kFarmPlanVersion)
        v.fail("cambium_farm_plan",
               fmt::format("version {} is not the one this cambium reads ({}): a plan of "
                           "another cambium",
                           printable(version.dump()), kFarmPlanVersion));
    FarmPlan p;
    p.dir = fs::absolute(farmDir).string();
    p.output = v.string(v.required(j, "output", ""), "output");
    const std::string kind =
        j.contains("kind") ? v.string(j.at("kind"), "kind") : std::string("frames");
    if (kind != "frames" && kind != "tiles")
        v.fail("kind", "must be \"frames\" or \"tiles\"");
    if (kind == "frames")
        frameRun(p.output);  // (a pattern with one run of '#')
    p.key = v.string(v.required(j, "key", ""), "key");
    p.scriptPath = v.string(v.required(j, "script", ""), "script");
    p.finalScriptPath = v.string(v.required(j, "final_script", ""), "final_script");
    p.retries = int(v.number(v.required(j, "retries", ""), "retries", 0, 100));
    p.throttle = int(v.number(v.required(j, "throttle", ""), "throttle", 0, 1e9));
    if (kind == "tiles") {
        p.tiles = int(v.number(v.required(j, "tiles", ""), "tiles", 1, 4096));
        p.merged.scene = v.string(v.required(j, "scene", ""), "scene");
        p.merged.threshold = v.number(v.required(j, "threshold", ""), "threshold", -1e30, 1e30);
        p.merged.halfWidth = v.number(v.required(j, "half_width", ""), "half_width", 1.0, 1e6);
        p.merged.half = v.boolean(v.required(j, "half", ""), "half");
        // (plans written before the merged file recorded its model time: 0)
        if (j.contains("time"))
            p.merged.time = v.number(j.at("time"), "time", -1e30, 1e30);
    }
    const nlohmann::json& chunks = v.required(j, "chunks", "");
    if (!chunks.is_array() || chunks.empty() || (p.tiles && int(chunks.size()) != p.tiles))
        v.fail("chunks",
               p.tiles ? "must be an array of a chunk a tile" : "must be an array of chunks");
    for (size_t k = 0; k < chunks.size(); ++k) {
        const std::string at = fmt::format("chunks[{}]", k);
        const char* field = p.tiles ? "tile" : "frames";
        const std::string part =
            v.string(v.required(v.object(chunks[k], at, "a chunk"), field, at), at + "." + field);
        if (p.tiles && part != fmt::format("{}/{}", k + 1, p.tiles))
            v.fail(at + ".tile", fmt::format("must be \"{}/{}\"", k + 1, p.tiles));
        if (!p.tiles)
            parseFrames(part, path + ": " + at + ".frames");
        p.chunks.push_back(part);
    }
    // (Last: a plan whose fields are wrong is named by its field first.)
    if (!j.contains("plan_hash") || !j.at("plan_hash").is_string() ||
        j.at("plan_hash").get<std::string>() != planHash(j))
        v.fail("plan_hash",
               "the plan was edited after cambium wrote it (its fields do not match "
               "its plan_hash): plan the farm again");
    return p;
}

std::vector<FarmPlan::File> FarmPlan::chunkFiles(size_t k) const
{
    if (tiles)
        return {{(long long)k + 1, tilePath(dir, k)}};
    std::vector<File> files;
    for (long long f : parseFrames(chunks.at(k)))
        files.push_back({f, framePath(output, f)});
    return files;
}

std::string FarmPlan::chunkName(size_t k) const
{
    return tiles ? "tile " + chunks.at(k)
                 : fmt::format("chunk {}/{} frames {}", k + 1, chunks.size(), chunks.at(k));
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

std::string chunkHistoryPath(const std::string& farmDir, size_t chunk)
{
    return (fs::path(farmDir) / fmt::format("task-{}.status", chunk)).string();
}

namespace {
constexpr const char* kSubmittedAgain = "submitted again";
}  // namespace

std::vector<ChunkEvent> readChunkEvents(const std::string& farmDir, size_t chunk)
{
    std::vector<ChunkEvent> events;
    const std::string path = chunkHistoryPath(farmDir, chunk);
    std::error_code ec;
    if (!fs::exists(fs::symlink_status(path, ec)))
        return events;
    // (readTextFile refuses a FIFO or a device, whose read would block)
    const std::string text = readTextFile(path, "chunk history");
    std::istringstream in(text);
    size_t number = 0;
    for (std::string line; std::getline(in, line);) {
        ++number;
        // (the last line cut short by a node's crash, without its newline:
        // as if not written, even where what is left reads, "13" of "137")
        if (in.eof() && text.back() != '\n')
            break;
        ChunkEvent e;
        // "STATUS [ARRAY-JOB-ID]" (the task's exit status, 0-255), or a
        // final job's "submitted again"
        std::istringstream words(line);
        std::string status, job, more;
        words >> status >> job >> more;
        if (line == kSubmittedAgain) {
            e.again = true;
        } else if (allDigits(status, 3) && std::stoi(status) <= 255 &&
                   (job.empty() || allDigits(job, 20)) && more.empty()) {
            e.status = std::stoi(status);
        } else {
            throw InputError(fmt::format(
                "{}:{}: '{}' is not a task's status line (an exit status and a job id, or "
                "'{}'): the farm directory was edited; remove the file to run the chunk again",
                path, number, line, kSubmittedAgain));
        }
        events.push_back(e);
    }
    return events;
}

void markSubmittedAgain(const std::string& farmDir, size_t chunk)
{
    const fs::path path = chunkHistoryPath(farmDir, chunk);
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
    std::string mergedChecksum;
    const fs::path manifest = fs::path(plan.dir) / "manifest.json";
    if (fs::exists(manifest)) {
        try {
            const nlohmann::json m =
                parseJson(readTextFile(manifest.string(), "farm manifest"), manifest.string());
            if (m.contains("merged_checksum"))
                mergedChecksum = m.at("merged_checksum").get<std::string>();
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
    // A tile farm whose final job merged its tiles (and removed them): done
    // while the output is the file it wrote (the checksum it recorded).
    if (plan.tiles && !mergedChecksum.empty()) {
        try {
            const VdbSummary out = inspectVdb(plan.output);
            const auto sum = out.strings.find("cambium_checksum");
            // (and its bytes hold it: a damaged merge is not done)
            s.merged = sum != out.strings.end() && sum->second == mergedChecksum &&
                       verifyVdbChecksum(plan.output, out);
            if (s.merged)
                s.mergedChecksum = mergedChecksum;
        } catch (const InputError&) {
        }
    }
    // Every file's stamp (its header: a few hundred bytes), then the bytes
    // of those that are this plan's against their checksum, on all cores (a
    // frame whose bytes changed passed the status as written, and --resume
    // kept it through every retry, sweep 20).
    struct Entry {
        size_t chunk;
        FarmPlan::File file;
        FileStamp stamp;
        bool mine = false;
    };
    std::vector<Entry> entries;
    for (size_t k = 0; k < plan.chunks.size(); ++k) {
        // (Another frame's or tile's file copied over it is not it.)
        for (const FarmPlan::File& file : plan.chunkFiles(k)) {
            Entry e{k, file, {}, s.merged};
            const std::string part =
                plan.tiles ? tilePart(int(k), int(plan.chunks.size())) : framePart(file.number);
            try {
                if (!s.merged)
                    e.stamp = readFileStamp(file.path);
            } catch (const InputError&) {
            }
            e.mine = s.merged ||
                     (e.stamp.key == plan.key && (e.stamp.part.empty() || e.stamp.part == part));
            entries.push_back(std::move(e));
        }
    }
    tbb::parallel_for(size_t(0), entries.size(), [&](size_t i) {
        Entry& e = entries[i];
        if (!e.mine || s.merged)
            return;
        try {
            readFileStamp(e.file.path, /*verify=*/true);
        } catch (const InputError&) {
            e.mine = false;
            e.stamp = {};
        }
    });
    size_t next = 0;  // (entries are in chunk order)
    for (size_t k = 0; k < plan.chunks.size(); ++k) {
        FarmChunkState c;
        c.name = plan.chunkName(k);
        c.unit = plan.unit();
        c.attempts = attempts[k];
        const std::vector<ChunkEvent> events = readChunkEvents(plan.dir, k);
        c.status = events.empty() || events.back().again ? -1 : events.back().status;
        for (; next < entries.size() && entries[next].chunk == k; ++next) {
            const Entry& e = entries[next];
            ++s.frames;
            if (e.mine) {
                ++s.good;
            } else {
                c.missing.push_back(e.file.number);
                std::error_code ec;
                if (!e.stamp.key.empty() || fs::exists(e.file.path, ec))
                    c.foreign.push_back(e.file.number);
            }
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
    // "frame 5 missing", "3 frames missing", "tile 2 not of this plan ...":
    // absent or unreadable files, and files of another plan, apart.
    std::vector<long long> absent;
    for (long long n : c.missing)
        if (std::find(c.foreign.begin(), c.foreign.end(), n) == c.foreign.end())
            absent.push_back(n);
    auto count = [&](const std::vector<long long>& v, const char* what) {
        return v.size() == 1 ? fmt::format("{} {} {}", c.unit, v.front(), what)
                             : fmt::format("{} {}s {}", v.size(), c.unit, what);
    };
    std::string files;
    if (!absent.empty())
        files = count(absent, "missing");
    if (!c.foreign.empty())
        files += (files.empty() ? "" : ", ") +
                 count(c.foreign, fmt::format("there but not of this plan (damaged, another "
                                              "tool's, baked from another input or options, or "
                                              "another {}'s file)",
                                              c.unit)
                                      .c_str());
    return (c.status == 0 ? std::string("ended (exit 0)") : describeStatus(c.status)) + ", " +
           files;
}

bool FarmState::complete(const FarmPlan& plan) const
{
    return good == frames && (!plan.tiles || merged);
}

std::string farmManifest(const FarmPlan& plan, const FarmState& state,
                         const std::vector<size_t>& resubmitted)
{
    nlohmann::ordered_json j;
    j["cambium_farm_manifest"] = 1;
    j["output"] = plan.output;
    j["key"] = plan.key;
    j["complete"] = state.complete(plan);
    if (plan.tiles) {
        j["tiles"] = state.frames;
        j["tiles_written"] = state.good;
        if (state.merged)
            j["merged_checksum"] = state.mergedChecksum;  // (the tiles, merged, are removed)
    } else {
        j["frames"] = state.frames;
        j["frames_written"] = state.good;
    }
    nlohmann::ordered_json chunks = nlohmann::ordered_json::array();
    nlohmann::ordered_json files = nlohmann::ordered_json::array();
    for (size_t k = 0; k < state.chunks.size(); ++k) {
        const FarmChunkState& c = state.chunks[k];
        const bool again =
            std::find(resubmitted.begin(), resubmitted.end(), k) != resubmitted.end();
        chunks.push_back({{plan.tiles ? "tile" : "frames", plan.chunks[k]},
                          {"status", c.status},
                          {"attempts", c.attempts},
                          {"state", describeChunk(c)},
                          {"resubmitted", again}});
        for (const FarmPlan::File& file :
             state.merged ? std::vector<FarmPlan::File>() : plan.chunkFiles(k)) {
            const bool ok =
                std::find(c.missing.begin(), c.missing.end(), file.number) == c.missing.end();
            std::error_code ec;
            const auto bytes = fs::file_size(file.path, ec);
            files.push_back({{plan.unit(), file.number},
                             {"path", file.path},
                             {"ok", ok},
                             {"bytes", ec ? 0 : (unsigned long long)bytes}});
        }
    }
    if (state.merged) {  // (the tiles removed: the merged file)
        std::error_code ec;
        const auto bytes = fs::file_size(plan.output, ec);
        files.push_back(
            {{"path", plan.output}, {"ok", true}, {"bytes", ec ? 0 : (unsigned long long)bytes}});
    }
    j["chunks"] = chunks;
    j["files"] = files;
    return j.dump(2) + "\n";
}

}  // namespace cambium
