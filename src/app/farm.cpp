// cambium bake … --frames A-B --slurm: a sequence as a Slurm job array (the
// plan and script from src/farm), submitted with sbatch, followed with
// squeue when --wait.
#include "app/app.h"

#include "core/error.h"
#include "core/files.h"
#include "core/system.h"
#include "cl/runtime.h"
#include "farm/slurm.h"
#include "io/vdb.h"

#include <fmt/format.h>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>
#include <thread>
#include <unistd.h>

namespace cambium {

namespace fs = std::filesystem;

namespace {

/// A shell command's standard output, standard error and exit status, kept
/// apart: what is parsed is the output alone (a site's submit plugin or a
/// warning writes to standard error).
struct Output {
    std::string text, err;
    int status = -1;
};
Output capture(const std::string& command)
{
    Output out;
    std::string errPath = (fs::temp_directory_path() / "cambium-farm-XXXXXX").string();
    const int fd = ::mkstemp(errPath.data());
    if (fd < 0)
        throw std::runtime_error("cannot make a temporary file for " + command);
    ::close(fd);
    FILE* p = ::popen((command + " 2>" + shellQuote(errPath)).c_str(), "r");
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
    return out;
}

std::string fileText(const fs::path& p)
{
    std::ifstream in(p);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

/// Which of the jobs `ids` (comma-separated) are still queued or running:
/// squeue's list, empty when none is.  Slurm forgets a job some minutes after
/// its end ("Invalid job id"): gone too.  std::runtime_error when Slurm does
/// not answer for ten seconds.
std::string queuedJobs(const std::string& ids)
{
    for (int attempt = 0;; ++attempt) {  // a busy slurmctld may not answer at once
        const Output q = capture("squeue -h -o %i -j " + shellQuote(ids));
        if (q.status == 0)
            return q.text;
        if (q.err.find("Invalid job id") != std::string::npos)
            return {};
        if (attempt == 5)
            throw std::runtime_error("squeue does not answer: " + q.err);
        std::this_thread::sleep_for(std::chrono::seconds(2));
    }
}

/// The job ids a live submission of this farm directory left, still queued
/// or running.
std::string liveJobs(const fs::path& farm)
{
    const std::string ids = fileText(farm / "jobs");
    if (ids.empty())
        return {};
    std::string list;
    for (char c : ids)
        list += c == '\n' ? ',' : c;
    while (!list.empty() && list.back() == ',')
        list.pop_back();
    return queuedJobs(list);
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
    SlurmOptions o;
    o.framesPerChunk = flags.chunk;
    o.throttle = flags.throttle;
    o.sbatchArgs = flags.sbatchArgs;
    o.exe = (fs::path(executableDirectory()) / "cambium").string();
    // A node's cores and memory: Slurm's largest node, else this machine's.
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
    if (cpus == 0) {
        if (!flags.dryRun)
            throw std::runtime_error("Slurm does not answer (sinfo: " + nodes.err +
                                     "): no job submitted");
        cpus = int(std::thread::hardware_concurrency());
        mb = availableMemoryBytes() / (1 << 20);
    }
    o.nodeCpus = cpus;
    o.nodeMemoryBytes = mb * (1 << 20);
    const SlurmArray array = planSlurmArray(plan, o);
    if (flags.dryRun) {
        fmt::print("# {}\n{}\n# {}\n{}", array.planPath, array.planJson, array.scriptPath,
                   array.script);
        return 0;
    }
    const fs::path farm = array.farmDir;
    fs::create_directories(farm);
    // One submission at a time: the check, sbatch and the job id written.
    const OutputLock submitting((farm / "submission").string());
    if (std::string live = liveJobs(farm); !live.empty()) {
        while (!live.empty() && live.back() == '\n')
            live.pop_back();
        for (char& c : live)
            c = c == '\n' ? ' ' : c;
        throw InputError(fmt::format(
            "{}: Slurm jobs of an earlier submission of this sequence are still queued or "
            "running ({}): wait for them or scancel them",
            request.bake.output, live));
    }
    writeFile(array.planPath, array.planJson.data(), array.planJson.size());
    writeFile(array.scriptPath, array.script.data(), array.script.size());
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
    for (const auto& [from, to] :
         {std::pair{fs::path(programCacheDirectory()), farm / "cache" / "cambium" / "opencl"},
          std::pair{poclCache, farm / "cache" / "pocl"}})
        if (!from.empty() && fs::is_directory(from, ec)) {
            fs::create_directories(to, ec);
            fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::skip_existing, ec);
        }
    for (size_t k = 0; k < array.chunks.size(); ++k)
        fs::remove(farm / fmt::format("task-{}.status", k), ec);
    const Output sub = capture("sbatch --parsable " + shellQuote(array.scriptPath));
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
    if (sub.status != 0 || id.empty() || !std::isdigit((unsigned char)id.front()))
        throw std::runtime_error("sbatch refused the job array: " + sub.err + sub.text);
    id = id.substr(0, id.find(';'));  // "ID;CLUSTER"
    const std::string jobs = id + "\n";
    writeFile((farm / "jobs").string(), jobs.data(), jobs.size());
    fmt::print(
        "submitted job array {}: {} frames in {} chunks, {} MB and {} cores a task; "
        "plan {}\n",
        id, plan.frames.size(), array.chunks.size(), array.resources.memoryMB, array.resources.cpus,
        array.planPath);
    std::fflush(stdout);
    if (!flags.wait) {
        fmt::print("follow it with: squeue -j {}; the tasks' logs are {}/task-*.log\n", id,
                   farm.string());
        return 0;
    }
    // --wait: a line per chunk as it ends, then the frames checked.
    std::set<size_t> reported;
    int badInput = 0, failed = 0;
    for (;;) {
        const bool queued = !queuedJobs(id).empty();
        for (size_t k = 0; k < array.chunks.size(); ++k) {
            if (reported.count(k))
                continue;
            const std::string s = fileText(farm / fmt::format("task-{}.status", k));
            if (s.empty() && queued)
                continue;
            const int status = s.empty() ? -1 : std::atoi(s.c_str());
            reported.insert(k);
            badInput += status == 2;
            failed += status != 0 && status != 2;
            fmt::print("chunk {}/{} frames {} {}\n", k + 1, array.chunks.size(),
                       array.chunks[k].frames,
                       status == 0   ? "done"
                       : status == 2 ? "failed: bad input (exit 2; see its log)"
                       : status < 0  ? "ended without a status (cancelled or killed)"
                                     : fmt::format("failed (exit {})", status));
            std::fflush(stdout);
        }
        if (!queued)
            break;
        std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
    size_t good = 0;
    for (const std::string& path : plan.paths) {
        std::string key;
        try {
            key = readSequenceKey(path);
        } catch (const std::exception&) {
        }
        good += key == plan.key;
    }
    fmt::print("{} of {} frames written and of this plan; {} chunks failed, {} for bad input\n",
               good, plan.paths.size(), failed, badInput);
    return good == plan.paths.size() ? 0 : badInput ? 2 : 1;
}

}  // namespace cambium
