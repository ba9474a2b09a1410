// cambium bake … --frames A-B --slurm: a sequence as a Slurm job array (the
// plan and scripts from src/farm) and its final job, submitted with sbatch,
// followed with squeue when --wait; and `cambium farm DIR [--finish]`, what
// the final job runs: every frame checked, the manifest, failed chunks
// submitted again.
#include "app/app.h"

#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "core/math.h"
#include "core/system.h"
#include "bake/bake.h"
#include "bake/tiles.h"
#include "cl/runtime.h"
#include "core/clock.h"
#include "io/vdb.h"
#include "farm/slurm.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <deque>
#include <cmath>
#include <cstdio>
#include <charconv>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <set>
#include <sstream>
#include <thread>
#include <unistd.h>

namespace cambium {

namespace fs = std::filesystem;

namespace {

/// A shell command's standard output, standard error and exit status, kept
/// apart: what is parsed is the output alone (a site's submit plugin or a
/// warning writes to standard error).  A command that does not end within
/// two minutes is stopped, its status 124 and its standard error saying so
/// (a hung sbatch held `bake --slurm` silently for ever).
struct Output {
    std::string text, err;
    int status = -1;
};
/// (CAMBIUM_SLURM_SECONDS sets another limit: a test's, or a slow site's.)
int slurmSeconds()
{
    const char* env = std::getenv("CAMBIUM_SLURM_SECONDS");
    if (!env)
        return 120;
    // (whole seconds, as written: atoi read 1e30 as 1 and ignored "abc")
    const std::string text = env;
    int given = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), given);
    if (ec != std::errc() || end != text.data() + text.size() || given < 1 || given > 86400)
        throw InputError(
            fmt::format("CAMBIUM_SLURM_SECONDS: '{}' is not a whole number of "
                        "seconds from 1 to 86400",
                        printable(text)));
    return given;
}
Output capture(const std::string& command, int seconds = slurmSeconds())
{
    Output out;
    std::string errPath = (fs::temp_directory_path() / "cambium-farm-XXXXXX").string();
    const int fd = ::mkstemp(errPath.data());
    if (fd < 0)
        throw std::runtime_error("cannot make a temporary file for " + command);
    ::close(fd);
    FILE* p = ::popen(
        fmt::format("timeout -k 5 {} {} 2>{}", seconds, command, shellQuote(errPath)).c_str(), "r");
    if (p) {
        char buf[4096];
        size_t n;
        while ((n = std::fread(buf, 1, sizeof buf, p)) > 0)
            out.text.append(buf, n);
        const int s = ::pclose(p);
        out.status = WIFEXITED(s) ? WEXITSTATUS(s) : -1;
    }
    std::ifstream in(errPath);
    out.err.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    ::unlink(errPath.c_str());
    if (out.status == 124 || out.status == 137)
        out.err += fmt::format(" (it did not answer in {} s and was stopped)", seconds);
    return out;
}

/// A farm directory's text file, empty when there is none; InputError when
/// it is not a regular file (a FIFO would block the read for ever).
std::string fileText(const fs::path& p, const char* what)
{
    std::error_code ec;
    if (!fs::exists(fs::symlink_status(p, ec)))
        return {};
    return readTextFile(p.string(), what);
}

/// Which of the jobs `ids` (comma-separated) are still queued or running:
/// squeue's list (a line each, an array's tasks each on its own, in
/// `format`: the job id by default), empty when none is.  Slurm forgets a job some minutes after
/// its end ("Invalid job id"): gone too.  std::runtime_error when Slurm does
/// not answer for ten seconds.
std::string queuedJobs(const std::string& ids, const char* format = "%i")
{
    // A busy slurmctld may not answer at once: asked again, each time for
    // at most 20 s, until the Slurm limit has passed (a hung squeue was
    // asked six times for two minutes each).
    const int limit = slurmSeconds();
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(limit);
    for (bool said = false;; said = true) {
        const double left =
            std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
        const Output q =
            capture(std::string("squeue -h -r -o ") + format + " -j " + shellQuote(ids),
                    std::clamp(int(std::ceil(left)), 1, 20));
        if (q.status == 0)
            return q.text;
        if (q.err.find("Invalid job id") != std::string::npos)
            return {};
        // (not there at all: no use asking again)
        if (q.status == 127 || q.status == 126)
            throw std::runtime_error("squeue cannot be run: " + q.err);
        if (std::chrono::steady_clock::now() + std::chrono::seconds(2) >= deadline)
            throw std::runtime_error("squeue does not answer: " + q.err);
        // Said once, not waited in silence (a Slurm without a controller
        // held `cambium farm` for two minutes without a word, sweep 27).
        if (!said) {
            std::string why = q.err;
            while (!why.empty() && std::isspace(static_cast<unsigned char>(why.back())))
                why.pop_back();
            why.erase(0, why.rfind('\n') + 1);  // its last line (npos + 1: all of it)
            printNotice(fmt::format(
                "squeue failed ({}): asking again every 2 s for up to {} s "
                "(CAMBIUM_SLURM_SECONDS)",
                shortened(printable(why.empty() ? fmt::format("exit {}", q.status) : why), 200),
                limit));
        }
        std::this_thread::sleep_for(std::chrono::seconds(2));
    }
}

/// The most job ids of a farm asked about: its latest submissions.
constexpr size_t kAskedFarmJobs = 1000;

/// The job ids of a farm directory's submissions (its `jobs` file: the
/// arrays and final jobs, one a line), comma-separated: the last 1,000 (the
/// earlier ended before the later were submitted: 30,000 ids held `cambium
/// farm` for squeue's two minutes, sweep 20).
std::string farmJobs(const fs::path& farm)
{
    // (written whole by writeFile: a line not an id is an edit, and squeue
    // would answer "Invalid job id" for the whole list, every job unseen)
    const std::string path = (farm / "jobs").string();
    std::istringstream lines(fileText(path, "farm's job list"));
    std::deque<std::string> ids;
    size_t number = 0;
    for (std::string line; std::getline(lines, line);) {
        ++number;
        if (!allDigits(line, 20))
            throw InputError(fmt::format(
                "{}:{}: '{}' is not a Slurm job id (cambium writes one a line): the farm "
                "directory was edited",
                path, number, line));
        ids.push_back(line);
        if (ids.size() > kAskedFarmJobs)
            ids.pop_front();
    }
    std::string list;
    for (const std::string& id : ids)
        list += (list.empty() ? "" : ",") + id;
    return list;
}

/// Those of a farm directory's jobs still queued or running.
std::string liveJobs(const fs::path& farm)
{
    const std::string ids = farmJobs(farm);
    return ids.empty() ? std::string() : queuedJobs(ids);
}

/// Submits `script` with sbatch and `args`: the job id.  std::runtime_error
/// with sbatch's words when it refuses.
std::string sbatch(const std::string& script, const std::vector<std::string>& args)
{
    std::string command = "sbatch --parsable";
    for (const std::string& a : args)
        command += " " + shellQuote(a);
    const Output sub = capture(command + " " + shellQuote(script));
    // "ID" or "ID;CLUSTER" on the last line of the output.
    std::string id;
    {
        std::istringstream lines(sub.text);
        for (std::string line; std::getline(lines, line);)
            if (!line.empty())
                id = line;
    }
    while (!id.empty() && id.back() == '\r')
        id.pop_back();
    if (sub.status == 124 || sub.status == 137)
        throw std::runtime_error(fmt::format(
            "sbatch did not answer in {} s and was stopped ({}; squeue tells whether it was "
            "submitted)",
            slurmSeconds(), script));
    id = id.substr(0, id.find(';'));
    // (a job id is digits: "42 42" was written to the job list, and every
    // later look at the farm refused the list as edited)
    if (sub.status != 0 || !allDigits(id, 20))
        throw std::runtime_error("sbatch refused " + script + ": " + sub.err + sub.text);
    return id;
}

/// Submits chunks `chunks` of the farm (all when empty) and the final job
/// after them, and adds both to its `jobs` file: the two job ids.
std::pair<std::string, std::string> submitFarm(const FarmPlan& plan,
                                               const std::vector<size_t>& chunks)
{
    std::vector<std::string> args;
    if (!chunks.empty()) {
        std::string list;
        for (size_t k : chunks)
            list += (list.empty() ? "" : ",") + std::to_string(k);
        if (plan.throttle > 0)
            list += fmt::format("%{}", plan.throttle);
        args.push_back("--array=" + list);  // (the command line's wins over the script's)
    }
    // Each id into `jobs` as soon as it is known; an array whose final job
    // cannot be submitted is cancelled rather than left running untracked.
    const std::string jobsPath = (fs::path(plan.dir) / "jobs").string();
    const std::string array = sbatch(plan.scriptPath, args);
    std::string jobs = fileText(jobsPath, "farm's job list") + array + "\n";
    writeFile(jobsPath, jobs.data(), jobs.size());
    std::string final;
    try {
        final = sbatch(plan.finalScriptPath, {"--dependency=afterany:" + array});
    } catch (const std::exception&) {
        // (an sbatch stopped for its time may have submitted the final job:
        // whatever waits on the array is cancelled with it)
        capture("scancel " + shellQuote(array));
        const Output waiting = capture("squeue -h -o '%i %E'");
        std::istringstream lines(waiting.status == 0 ? waiting.text : std::string());
        for (std::string line; std::getline(lines, line);) {
            std::istringstream in(line);
            std::string id, dependency;
            const std::string on = "afterany:" + array;
            if (in >> id >> dependency && allDigits(id, 20)) {
                const size_t at = dependency.find(on), end = at + on.size();
                if (at != std::string::npos &&
                    (end == dependency.size() || !std::isdigit((unsigned char)dependency[end])))
                    capture("scancel " + shellQuote(id));
            }
        }
        throw;
    }
    jobs += final + "\n";
    writeFile(jobsPath, jobs.data(), jobs.size());
    return {array, final};
}

/// The summary line of a farm's state, and its exit status: 0 when every
/// frame is there (a tile farm's tiles merged), 2 when a chunk failed for bad
/// input, 1 otherwise.
int summarize(const FarmPlan& plan, const FarmState& state, size_t running = 0)
{
    const char* chunks = plan.tiles ? "tiles" : "chunks";
    const std::string merged =
        !plan.tiles || state.good != state.frames ? std::string()
        : state.merged                            ? fmt::format(", merged into {}", plan.output)
                       : fmt::format(", not merged into {} (cambium farm --finish {} merges them)",
                                     plan.output, plan.dir);
    fmt::print("{} of {} {}s written and of this plan{}; {}{} {} failed, {} for bad input\n",
               state.good, state.frames, plan.unit(), merged,
               running ? fmt::format("{} {} queued or running, ", running, chunks) : std::string(),
               state.failed() - running, chunks, state.badInput());
    std::fflush(stdout);
    return state.complete(plan) ? 0 : state.badInput() ? 2 : 1;
}

}  // namespace

namespace {

/// The options every farm's plan takes, with a node's cores and memory:
/// Slurm's largest node, else (--dry-run without Slurm) this machine's.
SlurmOptions slurmOptions(const SlurmFlags& flags)
{
    SlurmOptions o;
    o.framesPerChunk = flags.chunk;
    o.throttle = flags.throttle;
    o.retries = flags.retries;
    for (const std::string& arg : flags.sbatchArgs)
        for (const char c : arg)
            if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
                // (each is one "#SBATCH" line of the job scripts: a newline
                // would start a shell line of its own)
                throw InputError(fmt::format(
                    "--slurm-arg '{}': a control character (code {}) in an sbatch option",
                    printable(arg), int(static_cast<unsigned char>(c))));
    // The options the scripts set themselves: one given again would take
    // the farm's own place (--array=0-99 made the final job an array of 100;
    // --output and --chdir moved its logs and status away from the farm).
    static const std::vector<std::string> own = {"--job-name",
                                                 "--array",
                                                 "--cpus-per-task",
                                                 "--mem",
                                                 "--mem-per-cpu",
                                                 "--mem-per-gpu",
                                                 "--output",
                                                 "--error",
                                                 "--open-mode",
                                                 "--chdir",
                                                 "--dependency",
                                                 "--wrap",
                                                 "-J",
                                                 "-a",
                                                 "-c",
                                                 "-o",
                                                 "-e",
                                                 "-D",
                                                 "-d"};
    for (const std::string& arg : flags.sbatchArgs) {
        // One option a line, as sbatch reads "#SBATCH" lines: "-x", "-xVALUE",
        // "--name" or "--name=VALUE" (a space would be read as two words).
        if (arg.size() < 2 || arg[0] != '-' || arg.find_first_of(" \t") != std::string::npos)
            throw InputError(fmt::format(
                "--slurm-arg '{}': one sbatch option, as -x, -xVALUE, --name or --name=VALUE "
                "(no spaces)",
                printable(arg)));
        // sbatch takes an unambiguous prefix of a long option's name as the
        // option (--arr is --array): a prefix of an own option is refused.
        const std::string given = arg.substr(0, arg.find('='));
        for (const std::string& name : own) {
            const bool longName = name.size() > 2;
            if (longName ? given.size() > 2 && name.rfind(given, 0) == 0 : arg.rfind(name, 0) == 0)
                throw InputError(fmt::format(
                    "--slurm-arg '{}': {} is set by cambium's job scripts (the farm's array, "
                    "resources, logs and directory); give other sbatch options",
                    printable(arg), name));
        }
    }
    o.sbatchArgs = flags.sbatchArgs;
    o.exe = (fs::path(executableDirectory()) / "cambium").string();
    const Output nodes = capture("sinfo -h -o '%c %m'");
    int cpus = 0;
    double mb = 0.0;
    if (nodes.status == 0) {
        std::istringstream lines(nodes.text);
        for (std::string line; std::getline(lines, line);) {
            std::istringstream in(line);
            int c;
            double m;
            if (in >> c >> m) {  // (a line that is not "CPUS MEMORY" is skipped)
                cpus = std::max(cpus, c);
                mb = std::max(mb, m);
            }
        }
    }
    o.nodesListed = cpus > 0;
    if (cpus == 0) {
        if (!flags.dryRun)
            throw std::runtime_error("Slurm does not answer (sinfo: " + nodes.err +
                                     "): no job submitted");
        cpus = int(std::thread::hardware_concurrency());
        mb = availableMemoryBytes() / (1 << 20);
    }
    o.nodeCpus = cpus;
    o.nodeMemoryBytes = mb * (1 << 20);
    return o;
}

/// A task or final job larger than any node Slurm lists (sinfo): sbatch
/// would refuse it, or queue it for ever (a node of 1 MB was given 300 MB
/// tasks).  InputError before anything is written or submitted.
void checkNodesFit(const SlurmArray& array, const SlurmOptions& o)
{
    if (!o.nodesListed)
        return;
    const double nodeMB = o.nodeMemoryBytes / (1 << 20);
    const long long need = std::max(array.resources.memoryMB, array.finalMemoryMB);
    if (double(need) > nodeMB)
        throw InputError(fmt::format(
            "the farm's {} needs {} MB of memory, and the largest node Slurm lists (sinfo) has "
            "{:.0f} MB: no node could run it; bake in tiles (--max-memory), use a larger voxel "
            "size, or a partition of larger nodes (--slurm-arg)",
            need == array.resources.memoryMB ? "task" : "final job", need, nodeMB));
}

/// Submits a planned array (or prints it: --dry-run) and its final job, and
/// with --wait follows it to its end.  `output`: what it makes, for messages;
/// `what`: "27 frames in 3 chunks" or the like.
int submitArray(const SlurmArray& array, const SlurmFlags& flags, const std::string& output,
                const std::string& what)
{
    if (flags.dryRun) {
        fmt::print("# {}\n{}\n# {}\n{}# {}\n{}", array.planPath, array.planJson, array.scriptPath,
                   array.script, array.finalScriptPath, array.finalScript);
        return 0;
    }
    const fs::path farm = array.farmDir;
    fs::create_directories(farm);
    // One submission at a time: the check, sbatch and the job id written.
    // (Released once the jobs are written: the final job takes it to submit
    // failed chunks again while --wait follows.)
    std::optional<OutputLock> submitting;
    submitting.emplace((farm / "submission").string());
    if (std::string live = liveJobs(farm); !live.empty()) {
        while (!live.empty() && live.back() == '\n')
            live.pop_back();
        for (char& c : live)
            c = c == '\n' ? ' ' : c;
        throw InputError(fmt::format(
            "{}: Slurm jobs of an earlier submission of it are still queued or running ({}): "
            "wait for them or scancel them",
            output, live));
    }
    writeFile(array.planPath, array.planJson.data(), array.planJson.size());
    writeFile(array.scriptPath, array.script.data(), array.script.size());
    writeFile(array.finalScriptPath, array.finalScript.data(), array.finalScript.size());
    // Compiled kernels for the tasks, copied from the user's caches (they
    // write only under the farm's directory: CAMBIUM_CACHE_DIR and
    // POCL_CACHE_DIR in the script).
    auto envPath = [](const char* name) {
        const char* v = std::getenv(name);
        return v && *v ? fs::path(v) : fs::path();
    };
    const fs::path xdg = !envPath("XDG_CACHE_HOME").empty() ? envPath("XDG_CACHE_HOME")
                         : !envPath("HOME").empty()         ? envPath("HOME") / ".cache"
                                                            : fs::path();
    const fs::path poclCache = !envPath("POCL_CACHE_DIR").empty() ? envPath("POCL_CACHE_DIR")
                               : xdg.empty()                      ? fs::path()
                                                                  : xdg / "pocl";
    std::error_code ec;
    // (a cache that holds the farm's directory is not copied into it: it
    // would copy itself, a level deeper each time, until the path is too long)
    auto inside = [](const fs::path& a, const fs::path& b) {
        std::error_code e;
        std::string ca = fs::weakly_canonical(a, e).string(),
                    cb = fs::weakly_canonical(b, e).string();
        while (ca.size() > 1 && ca.back() == '/')
            ca.pop_back();
        while (cb.size() > 1 && cb.back() == '/')
            cb.pop_back();
        return ca == cb || ca.rfind(cb == "/" ? cb : cb + "/", 0) == 0;
    };
    for (const auto& [from, to] :
         {std::pair{fs::path(programCacheDirectory()), farm / "cache" / "cambium" / "opencl"},
          std::pair{poclCache, farm / "cache" / "pocl"}})
        if (!from.empty() && fs::is_directory(from, ec) && !inside(farm, from) &&
            !inside(from, farm)) {
            fs::create_directories(to, ec);
            fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::skip_existing, ec);
        }
    // A new submission: statuses and attempts from nothing.
    const FarmPlan farmPlan = readFarmPlan(farm.string());
    for (size_t k = 0; k < farmPlan.chunks.size(); ++k)
        fs::remove(chunkHistoryPath(farm.string(), k), ec);
    fs::remove(farm / "manifest.json", ec);
    fs::remove(farm / "jobs", ec);
    const auto [id, finalId] = submitFarm(farmPlan, {});
    submitting.reset();
    fmt::print("submitted job array {}: {}, {} MB and {} cores a task; plan {}\n", id, what,
               array.resources.memoryMB, array.resources.cpus, array.planPath);
    fmt::print(
        "final job {}: after the array, checks every {}{}, writes {}/manifest.json and submits "
        "a failed {} again (at most {} times)\n",
        finalId, farmPlan.unit(),
        farmPlan.tiles ? fmt::format(", merges the tiles into {}", output) : std::string(),
        farm.string(), farmPlan.tiles ? "tile" : "chunk", farmPlan.retries);
    std::fflush(stdout);
    if (!flags.wait) {
        fmt::print(
            "follow it with: squeue -n {}; the logs are {}/task-*.log and final-*.log; "
            "scancel -n {} stops it\n",
            array.jobName, farm.string(), array.jobName);
        return 0;
    }
    // --wait: a line per chunk as each attempt ends and as it is submitted
    // again (its history, readChunkEvents: none is missed however fast the
    // final job acts), until no job of the farm is queued (the final job adds
    // its own before it ends: the list is read again after squeue finds none).
    std::vector<size_t> shown(farmPlan.chunks.size(), 0);
    for (;;) {
        const std::string ids = farmJobs(farm);
        const bool queued = !queuedJobs(ids).empty();
        for (size_t k = 0; k < farmPlan.chunks.size(); ++k) {
            const std::vector<ChunkEvent> events = readChunkEvents(farm.string(), k);
            for (; shown[k] < events.size(); ++shown[k]) {
                auto say = [&](const std::string& happened) {
                    fmt::print("{} {}\n", farmPlan.chunkName(k), happened);
                };
                const ChunkEvent& e = events[shown[k]];
                if (!e.again) {
                    say(describeStatus(e.status));
                    continue;
                }
                // (An attempt whose script was cancelled or killed left no line.)
                if (shown[k] == 0 || events[shown[k] - 1].again)
                    say(describeStatus(-1));
                say("submitted again");
            }
            std::fflush(stdout);
        }
        if (!queued && farmJobs(farm) == ids)
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
    const FarmState state = assessFarm(farmPlan);
    for (const FarmChunkState& c : state.chunks)
        if (!c.done())
            fmt::print("{} {} after {} attempts\n", c.name, describeChunk(c), c.attempts);
    return summarize(farmPlan, state);
}

}  // namespace

int runSlurmCommand(const SequenceRequest& asked, const SlurmFlags& flags)
{
    // Absolute paths: the tasks run elsewhere, and the sequence key hashes
    // the photo's path as given.
    SequenceRequest request = asked;
    for (std::string* path : {&request.bake.input, &request.bake.output, &request.bake.barkPhoto})
        if (!path->empty())
            *path = fs::absolute(*path).string();
    const SequencePlan plan = planSequence(request);
    const SlurmOptions options = slurmOptions(flags);
    const SlurmArray array = planSlurmArray(plan, options);
    checkNodesFit(array, options);
    return submitArray(
        array, flags, request.bake.output,
        fmt::format("{} frames in {} chunks", plan.frames.size(), array.chunks.size()));
}

int runTileFarmCommand(const BakeRequest& asked, const TilePlan& tiles, const SlurmFlags& flags)
{
    TileFarmRequest t;
    t.request = asked;
    t.request.input = fs::absolute(asked.input).string();
    t.request.output = fs::absolute(asked.output).string();
    t.request.voxelSize = tiles.voxelSize;
    t.tiles = tiles.tiles;
    t.tileBytes = tiles.tileBytes;
    t.frameBytes = tiles.frameBytes;
    t.threshold = tiles.threshold;
    t.time = tiles.time;
    t.scene = asked.input;
    if (tiles.tiles == 1)
        printNotice(fmt::format("the frame's estimate ({}) is within --max-memory: one task",
                                formatBytes(tiles.frameBytes)));
    const SlurmOptions options = slurmOptions(flags);
    const SlurmArray array = planTileArray(t, options);
    checkNodesFit(array, options);
    return submitArray(array, flags, t.request.output,
                       fmt::format("1 frame in {} tiles (voxel size {:g}, the frame's estimate {})",
                                   tiles.tiles, tiles.voxelSize, formatBytes(tiles.frameBytes)));
}

void addFarmCommand(CLI::App& app, Action& action)
{
    struct Options {
        std::string dir;
        bool finish = false;
    };
    auto o = std::make_shared<Options>();
    auto* cmd = app.add_subcommand(
        "farm",
        "Check a farm's files (the directory cambium bake --slurm made: every frame or tile "
        "written, readable and of its plan), a line per chunk; --finish (the final job) also "
        "merges a frame's tiles, writes manifest.json and submits the failed chunks again");
    cmd->add_option(
           "farm_dir", o->dir,
           "The farm's directory, OUTDIR/NAME.frames.vdb.farm or OUTDIR/NAME.vdb.tiles.farm")
        ->required();
    cmd->add_flag("--finish", o->finish,
                  "Merge a frame's tiles once all are written, write manifest.json and submit "
                  "the chunks that failed (not for bad input) again, with a final job after them");
    cmd->callback([o, &action] {
        action = [o] {
            const FarmPlan plan = readFarmPlan(o->dir);
            FarmState state = assessFarm(plan);
            // The chunks whose task is queued or running (squeue's array
            // task ids; "N/A" for the final job).
            std::set<size_t> running;
            if (const std::string ids = farmJobs(plan.dir); !o->finish && !ids.empty()) {
                try {
                    std::istringstream tasks(queuedJobs(ids, "%K"));
                    for (std::string t; std::getline(tasks, t);)
                        if (!t.empty() && std::isdigit((unsigned char)t.front()))
                            running.insert(size_t(std::stoul(t)));
                } catch (const std::runtime_error& e) {  // (read where Slurm is not)
                    printNotice(fmt::format("not knowing which chunks are queued or running: {}",
                                            e.what()));
                }
            }
            size_t runningUndone = 0;
            for (size_t k = 0; k < state.chunks.size(); ++k) {
                const FarmChunkState& c = state.chunks[k];
                runningUndone += running.count(k) && !c.done();
                fmt::print(
                    "{} {} (attempt {})\n", c.name,
                    running.count(k) && !c.done()
                        ? fmt::format("queued or running, {} of {} {}s to write", c.missing.size(),
                                      plan.chunkFiles(k).size(), plan.unit())
                        : describeChunk(c),
                    c.attempts);
            }
            if (!o->finish)
                return summarize(plan, state, runningUndone);
            // One submission at a time (a user's, or this): the chunks to run
            // again marked so in their histories, the manifest saying so, then
            // sbatch (a failed sbatch leaves a manifest without them).
            const fs::path farm = plan.dir;
            // (A user's submission holds the lock for seconds: waited for.)
            std::optional<OutputLock> submitting;
            for (int attempt = 0; !submitting; ++attempt) {
                try {
                    submitting.emplace((farm / "submission").string());
                } catch (const InputError&) {
                    if (attempt == 60)
                        throw;
                    std::this_thread::sleep_for(std::chrono::seconds(1));
                }
            }
            // Run by hand while the farm's tasks run, it would submit them
            // again: refused.  (The final job itself is one of the farm's.)
            std::string live = liveJobs(farm), others;
            const char* self = std::getenv("SLURM_JOB_ID");
            std::istringstream liveIds(live);
            for (std::string id; std::getline(liveIds, id);)
                if (!id.empty() && (!self || id != self))
                    others += (others.empty() ? "" : " ") + id;
            if (!others.empty())
                throw InputError(fmt::format(
                    "{}: jobs of this farm are still queued or running ({}): --finish runs once "
                    "they have ended (the final job does)",
                    plan.dir, others));
            // A tile farm with every tile written: the tiles merged into its
            // output, the manifest recording the merged file, the tiles
            // removed.
            if (plan.tiles && state.good == state.frames && !state.merged) {
                const auto start = Clock::now();
                std::vector<std::string> files;
                for (size_t k = 0; k < plan.chunks.size(); ++k)
                    files.push_back(tilePath(plan.dir, k));
                // (the output may have become a link to the input, or a tile,
                // since the plan was made)
                checkOutputPath(plan.output);
                std::vector<std::string> inputs = files;
                inputs.push_back(plan.merged.scene);
                checkOutputIsNoInput(plan.output, inputs);
                const BakedGrids grids = mergeTiles(files, plan.merged.half);
                BakeRequest described;
                described.input = plan.merged.scene;
                checkSomethingBaked(grids.stats, described);
                writeVdb(grids, plan.output, plan.merged);
                state.merged = true;
                state.mergedChecksum = inspectVdb(plan.output).strings.at("cambium_checksum");
                const std::string manifest = farmManifest(plan, state, {});
                writeFile((farm / "manifest.json").string(), manifest.data(), manifest.size());
                std::error_code ec;
                for (const std::string& f : files)
                    fs::remove(f, ec);
                fmt::print(
                    "merged {} tiles into {}: {} active voxels, {:.2f} s, peak memory {:.0f} "
                    "MB\n",
                    files.size(), plan.output, formatCount(double(grids.stats.activeVoxels)),
                    secondsSince(start), peakMemoryBytes() / 1e6);
                return summarize(plan, state);  // (merged, as the manifest now says)
            }
            const std::vector<size_t> again = chunksToRetry(plan, state);
            std::vector<std::string> histories;  // (put back where sbatch refuses)
            for (size_t k : again) {
                histories.push_back(fileText(chunkHistoryPath(plan.dir, k), "chunk history"));
                markSubmittedAgain(plan.dir, k);
            }
            const std::string manifest = farmManifest(plan, state, again);
            writeFile((farm / "manifest.json").string(), manifest.data(), manifest.size());
            if (!again.empty()) {
                std::pair<std::string, std::string> ids;
                try {
                    ids = submitFarm(plan, again);
                } catch (const std::exception&) {
                    const std::string none = farmManifest(plan, state, {});
                    writeFile((farm / "manifest.json").string(), none.data(), none.size());
                    for (size_t i = 0; i < again.size(); ++i)
                        writeFile(chunkHistoryPath(plan.dir, again[i]), histories[i].data(),
                                  histories[i].size());
                    throw;
                }
                std::string list;
                for (size_t k : again)
                    list += (list.empty() ? "" : ", ") + std::to_string(k + 1);
                fmt::print("submitted {} {} again as job array {}; final job {}\n",
                           plan.tiles ? "tiles" : "chunks", list, ids.first, ids.second);
                std::fflush(stdout);
                return 0;
            }
            return summarize(plan, state);
        };
    });
}

}  // namespace cambium
