// Farm plans: a sequence cut into chunks of whole reuse groups, what one task
// asks of a node, and what the final job finds and submits again; one frame
// baked as spatial tiles.
#include "bake/bake.h"
#include "farm/chunks.h"
#include "farm/slurm.h"
#include "field/program.h"
#include "model/load_model.h"

#include "core/error.h"
#include "core/frames.h"
#include "cli_util.h"
#include "temp_dir.h"
#include "test_util.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace {

using namespace cambium;
using cambium::test::fileContents;

const std::string kPopulus = CAMBIUM_SOURCE_DIR "/examples/populus/populus.json";

SequencePlan plan(const std::string& frames, double fps)
{
    SequenceRequest r;
    r.bake.input = kPopulus;
    r.bake.output =
        (std::filesystem::temp_directory_path() / "cambium_farm_test.####.vdb").string();
    r.bake.voxelSize = 0.05;
    r.frames = frames;
    r.fpsPerYear = fps;
    return planSequence(r);
}

TEST(FarmChunks, AreWholeReuseGroupsCoveringEveryFrameOnce)
{
    // (Ten years at most: a plan estimates its frames' trees, and the last
    // years' are the largest.)
    for (const auto& [frames, fps] : {std::pair<std::string, double>{"1-20", 2.0},
                                      {"3-100", 10.0},
                                      {"2-50:4", 3.0},
                                      {"5-5", 1.0}}) {
        const SequencePlan p = plan(frames, fps);
        // Where the plan's reuse groups begin: a chunk may begin only there.
        std::vector<bool> groupStart(p.frames.size() + 1, false);
        for (const auto& g : p.groups)
            groupStart[g.front()] = true;
        groupStart[p.frames.size()] = true;
        for (const size_t n : {size_t(1), size_t(3), size_t(10), size_t(100000)}) {
            const std::vector<FarmChunk> chunks = chunkPlan(p, n);
            ASSERT_FALSE(chunks.empty());
            size_t next = 0;
            for (size_t k = 0; k < chunks.size(); ++k) {
                const FarmChunk& c = chunks[k];
                EXPECT_EQ(c.first, next) << frames << " chunk " << k;
                EXPECT_TRUE(groupStart[c.first] && groupStart[c.last])
                    << frames << ": chunk " << k << " splits a reuse group";
                if (k + 1 < chunks.size()) {
                    EXPECT_GE(c.last - c.first, n) << frames << " chunk " << k;
                }
                // Its --frames are exactly its frames of the plan.
                const std::vector<long long> got = parseFrames(c.frames);
                const std::vector<long long> want(p.frames.begin() + long(c.first),
                                                  p.frames.begin() + long(c.last));
                EXPECT_EQ(got, want) << frames << " chunk " << k << ": " << c.frames;
                next = c.last;
            }
            EXPECT_EQ(next, p.frames.size()) << frames;
            // One group per chunk at n = 1; one chunk for all at n = 100000.
            if (n == 1) {
                EXPECT_EQ(chunks.size(), p.groups.size()) << frames;
            }
            if (n == 100000) {
                EXPECT_EQ(chunks.size(), 1u) << frames;
            }
        }
    }
}

TEST(FarmChunks, ATaskAsksForItsFramesMemoryAndTheCoresOfItsShareOfANode)
{
    const SequencePlan p = plan("1-27", 1.0);
    ASSERT_GT(p.bytesPerFrame, 0.0);
    const TaskResources alone = taskResources(p.bytesPerFrame, 16, 0.0);
    EXPECT_GE(double(alone.memoryMB) * (1 << 20), p.bytesPerFrame);
    EXPECT_LE(double(alone.memoryMB) * (1 << 20), p.bytesPerFrame + 300e6);
    const double task = double(alone.memoryMB) * (1 << 20);
    // A node whose memory holds eight tasks: two of its sixteen cores each.
    EXPECT_EQ(taskResources(p.bytesPerFrame, 16, 8.0 * task).cpus, 2);
    // One that holds one and a half: the whole node's cores for one.
    EXPECT_EQ(taskResources(p.bytesPerFrame, 2, 1.5 * task).cpus, 2);
    // Plenty of memory: one core a task.
    EXPECT_EQ(taskResources(p.bytesPerFrame, 2, 100.0 * task).cpus, 1);
    // Less memory than a task: all the cores (Slurm refuses the memory).
    EXPECT_EQ(taskResources(p.bytesPerFrame, 4, 0.5 * task).cpus, 4);
}

TEST(FarmArray, ItsTasksBakeTheFramesOfOneLocalRun)
{
    // The array's batch script run by hand, task by task as Slurm would
    // (SLURM_ARRAY_TASK_ID), writes the files one local bake of the whole
    // plan writes, byte for byte past the header's random UUID, and leaves
    // each task's exit status beside its logs.
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_farm");
    fs::create_directories(dir / "local");
    fs::create_directories(dir / "farm");
    openvdb::initialize();
    SequenceRequest r;
    r.bake.input = kPopulus;
    r.bake.voxelSize = 0.05;
    r.bake.device = Device::Cpu;
    r.frames = "3-8";
    r.fpsPerYear = 2.0;
    r.bake.output = (dir / "local" / "p.####.vdb").string();
    bakeSequence(r);
    r.bake.output = (dir / "farm" / "p.####.vdb").string();
    const SequencePlan plan = planSequence(r);
    SlurmOptions o;
    o.framesPerChunk = 2;
    o.exe = CAMBIUM_EXE;
    const SlurmArray array = planSlurmArray(plan, o);
    ASSERT_EQ(array.chunks.size(), 3u);  // years 1, 2, 3 and 4: groups of 1, 2, 2, 1 frames
    fs::create_directories(array.farmDir);
    std::ofstream(array.scriptPath) << array.script;
    std::ofstream(array.planPath) << array.planJson;
    for (size_t k = 0; k < array.chunks.size(); ++k) {
        const std::string command =
            "cd " + shellQuote(array.farmDir) +
            " && SLURM_ARRAY_JOB_ID=77 SLURM_ARRAY_TASK_ID=" + std::to_string(k) +
            " bash array.sh > task-" + std::to_string(k) + ".log 2>&1";
        EXPECT_EQ(std::system(command.c_str()), 0)
            << fileContents(array.farmDir + "/task-" + std::to_string(k) + ".log");
        EXPECT_EQ(fileContents(array.farmDir + "/task-" + std::to_string(k) + ".status"), "0 77\n");
    }
    for (int f = 3; f <= 8; ++f) {
        const std::string name = "p.000" + std::to_string(f) + ".vdb";
        const std::string a = fileContents(dir / "local" / name),
                          b = fileContents(dir / "farm" / name);
        constexpr size_t kUuidEnd = 57;
        ASSERT_GT(a.size(), kUuidEnd) << name;
        EXPECT_EQ(a.size(), b.size()) << name;
        EXPECT_TRUE(a.substr(kUuidEnd) == b.substr(kUuidEnd)) << name << " differs";
    }
    // What the final job finds: every frame there; then a chunk killed
    // (exit 137) without frame 5 is submitted again while attempts are left,
    // and a chunk that failed for bad input (exit 2) without frame 8 never.
    const FarmPlan farm = readFarmPlan(array.farmDir);
    EXPECT_EQ(farm.retries, 2);
    FarmState state = assessFarm(farm);
    EXPECT_EQ(state.good, 6u);
    EXPECT_EQ(state.frames, 6u);
    EXPECT_TRUE(chunksToRetry(farm, state).empty());
    // A frame copied over another (p.0003 over p.0004): that one is missing.
    const std::string four = fileContents(dir / "farm" / "p.0004.vdb");
    fs::copy_file(dir / "farm" / "p.0003.vdb", dir / "farm" / "p.0004.vdb",
                  fs::copy_options::overwrite_existing);
    state = assessFarm(farm);
    EXPECT_EQ(state.good, 5u);
    std::vector<long long> missing;
    for (const FarmChunkState& c : state.chunks)
        missing.insert(missing.end(), c.missing.begin(), c.missing.end());
    EXPECT_EQ(missing, std::vector<long long>{4});
    // ... named as another's file, not as missing
    for (const FarmChunkState& c : state.chunks) {
        if (!c.done()) {
            EXPECT_NE(describeChunk(c).find("frame 4 there but not of this plan"),
                      std::string::npos)
                << describeChunk(c);
        }
    }
    // A byte changed near its end (its size and header as written): the
    // status and the final job's check find it missing (a status that read
    // only headers called it written, sweep 20).
    std::string damaged = four;
    damaged[damaged.size() - 100] ^= 0x5a;
    std::ofstream(dir / "farm" / "p.0004.vdb", std::ios::binary) << damaged;
    state = assessFarm(farm);
    EXPECT_EQ(state.good, 5u);
    EXPECT_EQ(state.chunks[0].missing.size() + state.chunks[1].missing.size() +
                  state.chunks[2].missing.size(),
              1u);
    std::ofstream(dir / "farm" / "p.0004.vdb", std::ios::binary) << four;
    EXPECT_EQ(assessFarm(farm).good, 6u);
    fs::remove(dir / "farm" / "p.0005.vdb");
    std::ofstream(array.farmDir + "/task-1.status") << "137 78\n";
    fs::remove(dir / "farm" / "p.0008.vdb");
    std::ofstream(array.farmDir + "/task-2.status") << "2 78\n";
    state = assessFarm(farm);
    EXPECT_EQ(state.good, 4u);
    EXPECT_EQ(state.chunks[1].missing, std::vector<long long>{5});
    EXPECT_EQ(describeChunk(state.chunks[1]), "failed (exit 137), frame 5 missing");
    EXPECT_TRUE(state.chunks[2].badInput());
    EXPECT_EQ(state.failed(), 2u);
    EXPECT_EQ(state.badInput(), 1u);
    ASSERT_EQ(chunksToRetry(farm, state), std::vector<size_t>{1});
    // A chunk's history keeps every attempt: submitted again, it has no
    // status until its new task ends, whose line is added after the others.
    markSubmittedAgain(array.farmDir, 1);
    EXPECT_EQ(assessFarm(farm).chunks[1].status, -1);
    std::ofstream(array.farmDir + "/task-1.status", std::ios::app) << "1 79\n";
    const std::vector<ChunkEvent> events = readChunkEvents(array.farmDir, 1);
    ASSERT_EQ(events.size(), 3u);
    EXPECT_TRUE(!events[0].again && events[0].status == 137 && events[1].again &&
                !events[2].again && events[2].status == 1);
    EXPECT_EQ(assessFarm(farm).chunks[1].status, 1);
    // The manifest counts the attempts: after two resubmissions, none more.
    for (int attempt = 2; attempt <= 3; ++attempt) {
        std::ofstream(array.farmDir + "/manifest.json") << farmManifest(farm, state, {1});
        state = assessFarm(farm);
        EXPECT_EQ(state.chunks[1].attempts, attempt);
        EXPECT_EQ(state.chunks[0].attempts, 1);
    }
    EXPECT_TRUE(chunksToRetry(farm, state).empty());
    // `cambium farm DIR` says so: exit 2, bad input.
    const std::string check = std::string(CAMBIUM_EXE) + " farm " + shellQuote(array.farmDir) +
                              " > " + shellQuote((dir / "check.txt").string());
    EXPECT_EQ(WEXITSTATUS(std::system(check.c_str())), 2);
    EXPECT_NE(fileContents(dir / "check.txt")
                  .find("4 of 6 frames written and of this plan; 2 chunks failed, 1 for bad input"),
              std::string::npos)
        << fileContents(dir / "check.txt");
    // An edited plan (its retries raised by hand) is refused.
    std::string edited = array.planJson;
    edited.replace(edited.find("\"retries\": 2"), 12, "\"retries\": 5");
    std::ofstream(array.planPath) << edited;
    try {
        readFarmPlan(array.farmDir);
        ADD_FAILURE() << "an edited plan was read";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("plan.json: plan_hash: the plan was edited"),
                  std::string::npos)
            << e.what();
    }
    // A plan file that is not one is named.
    std::ofstream(array.planPath) << "{\"cambium_farm_plan\": 2, \"output\": 3}";
    try {
        readFarmPlan(array.farmDir);
        ADD_FAILURE() << "a damaged plan was read";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("plan.json: output"), std::string::npos) << e.what();
    }
    // Nor is one of another version.
    for (const std::string version : {"1", "3", "\"2\"", "2.5"}) {
        std::ofstream(array.planPath) << "{\"cambium_farm_plan\": " + version + "}";
        try {
            readFarmPlan(array.farmDir);
            ADD_FAILURE() << "a plan of version " << version << " was read";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("plan.json: cambium_farm_plan: version " +
                                                 version + " is not the one this cambium reads"),
                      std::string::npos)
                << e.what();
        }
    }

    // An output path that #SBATCH lines cannot name is refused, by name.
    for (const std::string bad : {"with space", "per%cent"}) {
        fs::create_directories(dir / bad);
        SequenceRequest q = r;
        q.bake.output = (dir / bad / "p.####.vdb").string();
        try {
            planSlurmArray(planSequence(q), o);
            ADD_FAILURE() << "accepted " << q.bake.output;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
        }
    }
    // A task index past the plan's chunks is refused as bad input.
    const std::string past = "cd " + shellQuote(array.farmDir) +
                             " && SLURM_ARRAY_TASK_ID=3 bash array.sh > /dev/null 2>&1";
    EXPECT_EQ(WEXITSTATUS(std::system(past.c_str())), 2);
}

TEST(FarmTiles, AFrameBakedAsTilesIsTheSingleBakeAndMaxMemorySplitsIt)
{
    // Tiles baked by processes of their own and merged write the file the
    // single bake writes, byte for byte past the header's UUID; a frame whose
    // estimate is twice --max-memory is split into the 3 tiles whose shares
    // (1.5 / tiles of the estimate) fit; bad --tile values are refused.
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_tiles");
    const std::string exe = CAMBIUM_EXE;
    const std::string bake = exe + " bake " + kPopulus + " --time 8 --voxel-size 0.02 --device cpu";
    auto run = [&](const std::string& args, const std::string& out) {
        const std::string command = bake + " " + args + " -o " + shellQuote((dir / out).string()) +
                                    " > " + shellQuote((dir / (out + ".txt")).string()) + " 2>&1";
        return WEXITSTATUS(std::system(command.c_str()));
    };
    ASSERT_EQ(run("", "single.vdb"), 0) << fileContents(dir / "single.vdb.txt");
    ASSERT_EQ(run("--tiles 3", "tiled.vdb"), 0) << fileContents(dir / "tiled.vdb.txt");
    const std::string a = fileContents(dir / "single.vdb"), b = fileContents(dir / "tiled.vdb");
    constexpr size_t kUuidEnd = 57;
    ASSERT_GT(a.size(), kUuidEnd);
    EXPECT_EQ(a.size(), b.size());
    EXPECT_TRUE(a.substr(kUuidEnd) == b.substr(kUuidEnd)) << "the merged tiles differ";
    EXPECT_NE(fileContents(dir / "tiled.vdb.txt").find("tile 3/3: peak memory"), std::string::npos);
    // With --half too (the tiles' files hold floats; the merge packs halves).
    ASSERT_EQ(run("--half", "single_half.vdb"), 0);
    ASSERT_EQ(run("--half --tiles 2", "tiled_half.vdb"), 0)
        << fileContents(dir / "tiled_half.vdb.txt");
    EXPECT_TRUE(fileContents(dir / "single_half.vdb").substr(kUuidEnd) ==
                fileContents(dir / "tiled_half.vdb").substr(kUuidEnd))
        << "the merged tiles differ with --half";
    // The estimate, as the bake makes it.
    BakeRequest r;
    r.input = kPopulus;
    r.model.time = 8.0;
    r.voxelSize = 0.02;
    BlobTree tree = loadModel(r.input, r.model);
    const double estimate = planModel(tree, r).plan.bytes;
    ASSERT_EQ(run(fmt::format("--max-memory {}", (long long)(estimate / 2) + 1), "auto.vdb"), 0)
        << fileContents(dir / "auto.vdb.txt");
    EXPECT_NE(fileContents(dir / "auto.vdb.txt").find("3 tiles merged"), std::string::npos)
        << fileContents(dir / "auto.vdb.txt");
    EXPECT_TRUE(fileContents(dir / "auto.vdb").substr(kUuidEnd) == a.substr(kUuidEnd));
    ASSERT_EQ(run(fmt::format("--max-memory {}", (long long)(estimate * 2)), "fits.vdb"), 0);
    EXPECT_NE(fileContents(dir / "fits.vdb.txt").find("one bake"), std::string::npos);
    // More tiles than 128-voxel layers (the tree spans 5): a tile for each
    // layer, said (the others would be empty, a process each for nothing:
    // --tiles 4096 on a small frame ran 4096), the same file.
    ASSERT_EQ(run("--tiles 8", "many.vdb"), 0) << fileContents(dir / "many.vdb.txt");
    EXPECT_TRUE(fileContents(dir / "many.vdb").substr(kUuidEnd) == a.substr(kUuidEnd));
    EXPECT_NE(fileContents(dir / "many.vdb.txt")
                  .find("note: 8 tiles: the frame spans 5 layers of 128 voxels across its longest "
                        "side, and a tile is a run of them: 5 tiles"),
              std::string::npos)
        << fileContents(dir / "many.vdb.txt");
    EXPECT_EQ(fileContents(dir / "many.vdb.txt").find("tile 6/"), std::string::npos);
    for (const char* bad : {"--tile 0/3", "--tile 4/3", "--tile 1/0", "--tile 2", "--tiles 2 --fog",
                            "--tile +1/3", "--tile 1/99999999999", "--max-memory 12X",
                            "--tiles 2 --max-memory 1K", "--max-memory 1", "--max-memory ''"}) {
        EXPECT_EQ(run(bad, "bad.vdb"), 2) << bad << ": " << fileContents(dir / "bad.vdb.txt");
        EXPECT_FALSE(fs::exists(dir / "bad.vdb")) << bad;
    }
}

/// The pids of the processes whose command line holds `text`.
std::vector<pid_t> processesWith(const std::string& text)
{
    std::vector<pid_t> found;
    for (const auto& e : std::filesystem::directory_iterator("/proc")) {
        const std::string name = e.path().filename().string();
        if (name.find_first_not_of("0123456789") != std::string::npos)
            continue;
        std::string cmd = fileContents(e.path() / "cmdline");
        std::replace(cmd.begin(), cmd.end(), '\0', ' ');
        if (cmd.find(text) != std::string::npos)
            found.push_back(pid_t(std::stoi(name)));
    }
    return found;
}

TEST(FarmTiles, AKilledTiledBakesTileEndsAndItsTilesGoNextTime)
{
    // kill -9 of a local tiled bake left its tile baking on as an orphan and
    // its directory of tiles beside the output for good (sweep 18): the tile
    // ends itself once its parent is gone, and the next tiled bake of the
    // output removes the directory.  (Waits are bounded polls.)
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_tiles_killed");
    const std::string out = (dir / "killed.vdb").string(), scratch = ".killed.vdb.tiles-";
    const pid_t parent = ::fork();
    if (parent == 0) {
        const int null = ::open("/dev/null", O_WRONLY);
        ::dup2(null, 1);
        ::dup2(null, 2);
        ::execl(CAMBIUM_EXE, "cambium", "bake", kPopulus.c_str(), "--time", "8", "--voxel-size",
                "0.0025", "--device", "cpu", "--tiles", "2", "-o", out.c_str(),
                static_cast<char*>(nullptr));
        ::_exit(127);
    }
    ASSERT_GT(parent, 0);
    const auto waitFor = [](const std::function<bool()>& done, double seconds) {
        const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
        while (!done() && std::chrono::steady_clock::now() < end)
            ::usleep(50000);
        return done();
    };
    int status = 0;
    bool ended = false;
    waitFor(
        [&] {
            ended = ended || ::waitpid(parent, &status, WNOHANG) == parent;
            return ended ||
                   !processesWith(scratch + std::to_string(parent) + "/tile-1.vdb").empty();
        },
        120.0);
    ASSERT_FALSE(ended) << "the tiled bake ended before its first tile was seen (status " << status
                        << ")";
    ::kill(parent, SIGKILL);
    ::waitpid(parent, &status, 0);
    EXPECT_TRUE(
        waitFor([&] { return processesWith(scratch + std::to_string(parent)).empty(); }, 60.0))
        << "a tile of the killed bake still runs";
    // (its tile takes seconds; an orphan would have finished and written it)
    EXPECT_TRUE(fs::exists(dir / (scratch + std::to_string(parent))));
    EXPECT_FALSE(fs::exists(dir / (scratch + std::to_string(parent)) / "tile-1.vdb"))
        << "the killed bake's tile went on and wrote its file";
    const test::Result next =
        test::run("bake " + kPopulus + " --time 8 --voxel-size 0.02 --device cpu --tiles 2 -o " +
                  shellQuote(out));
    ASSERT_EQ(next.status, 0) << next.err;
    EXPECT_NE((next.out + next.err)
                  .find("removed " + (dir / scratch).string() + std::to_string(parent) +
                        ", the tiles an interrupted run left"),
              std::string::npos)
        << next.out << next.err;
    EXPECT_FALSE(fs::exists(dir / (scratch + std::to_string(parent))));
}

TEST(FarmTiles, AnArraysTilesMergedByItsFinalJobAreTheSingleBake)
{
    // A frame's tiles as a job array: its batch script run by hand task by
    // task as Slurm would writes tiles the final job recognises (the plan's
    // key); a tile missing is submitted again; `cambium farm --finish` merges
    // them into the file the single bake writes (--half: the merge packs
    // halves), byte for byte past the UUID, records it and removes the tiles.
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_tile_farm");
    openvdb::initialize();
    const std::string exe = CAMBIUM_EXE;
    const std::string single = (dir / "single.vdb").string();
    ASSERT_EQ(std::system((exe + " bake " + kPopulus +
                           " --time 8 --voxel-size 0.02 --device cpu --half -o " + single +
                           " > /dev/null")
                              .c_str()),
              0);
    TileFarmRequest t;
    t.request.input = kPopulus;
    t.request.model.time = 8.0;
    t.request.voxelSize = 0.02;
    t.request.device = Device::Cpu;
    t.request.half = true;
    t.request.output = (dir / "hero.vdb").string();
    t.tiles = 3;
    t.tileBytes = 100e6;
    const BlobTree model = loadModel(kPopulus, t.request.model);
    t.threshold = model.threshold();
    t.time = model.time();
    t.scene = kPopulus;
    SlurmOptions o;
    o.exe = exe;
    const SlurmArray array = planTileArray(t, o);
    EXPECT_EQ(array.farmDir, (dir / "hero.vdb.tiles.farm").string());
    fs::create_directories(array.farmDir);
    std::ofstream(array.scriptPath) << array.script;
    std::ofstream(array.planPath) << array.planJson;
    for (int k = 0; k < 3; ++k) {
        const std::string command =
            "cd " + shellQuote(array.farmDir) +
            " && SLURM_ARRAY_JOB_ID=77 SLURM_ARRAY_TASK_ID=" + std::to_string(k) +
            " bash array.sh > /dev/null 2>&1";
        EXPECT_EQ(std::system(command.c_str()), 0) << "tile " << k + 1;
    }
    const FarmPlan farm = readFarmPlan(array.farmDir);
    EXPECT_EQ(farm.tiles, 3);
    FarmState state = assessFarm(farm);
    EXPECT_EQ(state.good, 3u) << describeChunk(state.chunks[0]);
    // A tile lost: that one submitted again.
    fs::rename(tilePath(farm.dir, 1), dir / "kept.vdb");
    state = assessFarm(farm);
    EXPECT_EQ(describeChunk(state.chunks[1]), "ended (exit 0), tile 2 missing");
    EXPECT_EQ(chunksToRetry(farm, state), std::vector<size_t>{1});
    // A tile of another plan (another voxel size) in its place is not this
    // plan's.
    const std::string stale = exe + " bake " + kPopulus +
                              " --time 8 --voxel-size 0.03 --device cpu --tile 2/3 -o " +
                              shellQuote(tilePath(farm.dir, 1)) + " > /dev/null";
    ASSERT_EQ(std::system(stale.c_str()), 0);
    EXPECT_EQ(assessFarm(farm).chunks[1].missing, std::vector<long long>{2});
    // Nor is this plan's tile 1 copied into tile 2's place.
    fs::copy_file(tilePath(farm.dir, 0), tilePath(farm.dir, 1),
                  fs::copy_options::overwrite_existing);
    EXPECT_EQ(assessFarm(farm).chunks[1].missing, std::vector<long long>{2});
    EXPECT_TRUE(assessFarm(farm).chunks[0].missing.empty());
    fs::rename(dir / "kept.vdb", tilePath(farm.dir, 1));
    auto farmCommand = [&](const std::string& args) {
        const std::string command = exe + " farm " + args + " " + shellQuote(farm.dir) + " > " +
                                    shellQuote((dir / "farm.txt").string()) + " 2>&1";
        return WEXITSTATUS(std::system(command.c_str()));
    };
    // What the last command printed, and whether it holds `text`.
    auto printed = [&] { return fileContents(dir / "farm.txt"); };
    auto says = [&](const std::string& text) { return printed().find(text) != std::string::npos; };
    // A merge that fails (its output cannot be written) leaves the farm not
    // complete, the tiles kept: exit 1, and --finish merges them later.
    fs::create_directories(dir / "hero.vdb");
    EXPECT_NE(farmCommand("--finish"), 0) << printed();
    EXPECT_EQ(farmCommand(""), 1) << printed();
    EXPECT_TRUE(says("3 of 3 tiles written and of this plan, not merged")) << printed();
    fs::remove(dir / "hero.vdb");
    ASSERT_EQ(farmCommand("--finish"), 0) << printed();
    EXPECT_TRUE(says("merged 3 tiles into")) << printed();
    const std::string a = fileContents(single), b = fileContents(dir / "hero.vdb");
    constexpr size_t kUuidEnd = 57;
    ASSERT_GT(a.size(), kUuidEnd);
    EXPECT_EQ(a.size(), b.size());
    EXPECT_TRUE(a.substr(kUuidEnd) == b.substr(kUuidEnd)) << "the merged tiles differ";
    for (int k = 0; k < 3; ++k)
        EXPECT_FALSE(fs::exists(tilePath(farm.dir, size_t(k))));
    // Merged, the farm is complete; the output removed, it is not.
    state = assessFarm(farm);
    EXPECT_TRUE(state.merged);
    EXPECT_EQ(state.good, 3u);
    EXPECT_NE(fileContents(fs::path(farm.dir) / "manifest.json").find("\"complete\": true"),
              std::string::npos);
    // --finish again on the merged farm: still merged, nothing submitted.
    EXPECT_EQ(farmCommand("--finish"), 0) << printed();
    EXPECT_TRUE(assessFarm(farm).merged);
    EXPECT_EQ(farmCommand(""), 0) << printed();
    EXPECT_TRUE(says("3 of 3 tiles written and of this plan, merged into")) << printed();
    fs::remove(dir / "hero.vdb");
    state = assessFarm(farm);
    EXPECT_FALSE(state.merged);
    EXPECT_EQ(state.good, 0u);
}

}  // namespace

TEST(FarmTiles, AFifoOrALineCambiumNeverWritesInTheFarmDirectoryIsRefused)
{
    // A FIFO where the farm keeps its job list or a chunk's history would
    // block `cambium farm` for ever on its read: refused by name, exit 2.
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_farm_fifo");
    TileFarmRequest t;
    t.request.input = kPopulus;
    t.request.model.time = 2.0;
    t.request.voxelSize = 0.05;
    t.request.device = Device::Cpu;
    t.request.output = (dir / "hero.vdb").string();
    t.tiles = 2;
    t.tileBytes = 100e6;
    const BlobTree model = loadModel(kPopulus, t.request.model);
    t.threshold = model.threshold();
    t.time = model.time();
    t.scene = kPopulus;
    SlurmOptions o;
    o.exe = CAMBIUM_EXE;
    const SlurmArray array = planTileArray(t, o);
    fs::create_directories(array.farmDir);
    std::ofstream(array.scriptPath) << array.script;
    std::ofstream(array.planPath) << array.planJson;
    for (const fs::path& fifo :
         {fs::path(array.farmDir) / "jobs", fs::path(chunkHistoryPath(array.farmDir, 0))}) {
        ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << fifo;
        const test::Result r = test::run("farm " + shellQuote(array.farmDir));
        EXPECT_EQ(r.status, 2) << r.err;
        EXPECT_NE(r.err.find(fifo.filename().string() + ": is a device, FIFO or socket"),
                  std::string::npos)
            << r.err;
        fs::remove(fifo);
    }
    // Lines cambium never writes (they were skipped: a job list of "12; rm"
    // made squeue answer "Invalid job id", every live job unseen) are
    // refused by line; a chunk history's last line cut short by a crash is
    // read as not written.
    std::ofstream(fs::path(array.farmDir) / "jobs") << "1234\n12; rm\n";
    const test::Result jobs = test::run("farm " + shellQuote(array.farmDir));
    EXPECT_EQ(jobs.status, 2) << jobs.err;
    EXPECT_NE(jobs.err.find("jobs:2: '12; rm' is not a Slurm job id"), std::string::npos)
        << jobs.err;
    {
        // A list of 30,000 ids held it for squeue's two minutes (sweep 20):
        // the last 1,000 are asked about (the earlier ended before them).
        std::ofstream many(fs::path(array.farmDir) / "jobs");
        for (int k = 0; k < 30000; ++k)
            many << 1000 + k << "\n";
    }
    const fs::path bin = dir / "bin", asked = dir / "squeue.args";
    fs::create_directories(bin);
    std::ofstream(bin / "squeue") << "#!/bin/sh\necho \"$@\" > " << asked.string() << "\n";
    fs::permissions(bin / "squeue", fs::perms::owner_all);
    const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "/usr/bin:/bin";
    ::setenv("PATH", (bin.string() + ":" + path).c_str(), 1);
    const test::Result many = test::run("farm " + shellQuote(array.farmDir));
    ::setenv("PATH", path.c_str(), 1);
    EXPECT_NE(many.status, 2) << many.err;
    const std::string args = test::fileContents(asked);
    EXPECT_NE(args.find("-j 30000,30001,"), std::string::npos) << args.substr(0, 200);
    EXPECT_NE(args.find(",30999"), std::string::npos);
    EXPECT_EQ(args.find("29999"), std::string::npos);
    {
        // A Slurm without a controller fails at once, and was asked again
        // for two minutes without a word (sweep 27): it is said at the first
        // failure; a squeue that is not there is not asked again.
        std::ofstream(bin / "squeue")
            << "#!/bin/sh\necho 'squeue: error: Could not establish a configuration source' "
               ">&2\nexit 1\n";
        ::setenv("PATH", (bin.string() + ":" + path).c_str(), 1);
        ::setenv("CAMBIUM_SLURM_SECONDS", "3", 1);
        const test::Result down = test::run("farm " + shellQuote(array.farmDir));
        fs::remove(bin / "squeue");
        std::ofstream(bin / "squeue") << "#!/bin/sh\nexit 127\n";
        fs::permissions(bin / "squeue", fs::perms::owner_all);
        const test::Result missing = test::run("farm " + shellQuote(array.farmDir));
        ::unsetenv("CAMBIUM_SLURM_SECONDS");
        ::setenv("PATH", path.c_str(), 1);
        EXPECT_NE(down.out.find("note: squeue failed (squeue: error: Could not establish a "
                                "configuration source): asking again every 2 s for up to 3 s"),
                  std::string::npos)
            << down.out;
        EXPECT_NE(down.out.find("not knowing which chunks are queued or running: squeue does "
                                "not answer"),
                  std::string::npos)
            << down.out;
        EXPECT_NE(missing.out.find("not knowing which chunks are queued or running: squeue "
                                   "cannot be run"),
                  std::string::npos)
            << missing.out;
        EXPECT_EQ(missing.out.find("asking again"), std::string::npos) << missing.out;
    }
    fs::remove(fs::path(array.farmDir) / "jobs");
    const std::string history = chunkHistoryPath(array.farmDir, 0);
    std::ofstream(history) << "137 78\nsubmitted again\n0 79\n13";
    const std::vector<ChunkEvent> read = readChunkEvents(array.farmDir, 0);
    ASSERT_EQ(read.size(), 3u);
    EXPECT_EQ(read[2].status, 0);
    for (const std::string bad : {"137 78\nok\n", "1 2 3\n", "256 78\n", "-1 78\n", "0 x\n"}) {
        std::ofstream(history) << bad;
        cambium::test::expectInputError([&] { readChunkEvents(array.farmDir, 0); },
                                        "task-0.status:", bad);
    }
}

TEST(FarmArray, ACacheThatHoldsTheFarmIsNotCopiedIntoIt)
{
    // The submission copies the user's compiled kernels into the farm's
    // directory; a PoCL cache holding that directory copied itself, a level
    // deeper each time (140 levels, until the path was too long).
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_farm_cache");
    const fs::path bin = dir / "bin", cache = dir / "pocl";
    fs::create_directories(bin);
    fs::create_directories(cache / "kernels");
    fs::create_directories(cache / "out");
    std::ofstream(cache / "kernels" / "k.bin") << "x";
    // A Slurm that answers (sinfo: cores and memory of a node; sbatch: a job).
    for (const auto& [name, answer] : {std::pair{"sinfo", "2 4000"}, std::pair{"sbatch", "4242"}}) {
        std::ofstream(bin / name) << "#!/bin/sh\necho " << answer << "\n";
        fs::permissions(bin / name, fs::perms::owner_all);
    }
    const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "/usr/bin:/bin";
    ::setenv("PATH", (bin.string() + ":" + path).c_str(), 1);
    ::setenv("POCL_CACHE_DIR", cache.c_str(), 1);
    const auto r =
        cambium::test::run("bake " + kPopulus + " --frames 1-2 --voxel-size 0.05 --slurm -o " +
                           (cache / "out" / "s.####.vdb").string());
    ::setenv("PATH", path.c_str(), 1);
    ::unsetenv("POCL_CACHE_DIR");
    EXPECT_EQ(r.status, 0) << r.err;
    size_t entries = 0;
    for (auto it = fs::recursive_directory_iterator(cache);
         it != fs::recursive_directory_iterator(); ++it)
        ++entries;
    EXPECT_LT(entries, 40u) << "the cache was copied into itself";
    EXPECT_TRUE(fs::exists(cache / "out" / "s.frames.vdb.farm" / "plan.json"));
    EXPECT_FALSE(fs::exists(cache / "out" / "s.frames.vdb.farm" / "cache" / "pocl" / "out"));
}

TEST(FarmArray, ASlurmThatDoesNotAnswerIsStoppedAndNamed)
{
    // A hung sbatch held `bake --slurm` silently for ever; each Slurm
    // command now has a time limit (two minutes; a test sets one second).
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_farm_hung");
    const fs::path bin = dir / "bin";
    fs::create_directories(bin);
    for (const auto& [name, body] :
         {std::pair{"sinfo", "echo 2 4000"}, std::pair{"sbatch", "sleep 30; echo 4242"}}) {
        std::ofstream(bin / name) << "#!/bin/sh\n" << body << "\n";
        fs::permissions(bin / name, fs::perms::owner_all);
    }
    const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "/usr/bin:/bin";
    ::setenv("PATH", (bin.string() + ":" + path).c_str(), 1);
    ::setenv("CAMBIUM_SLURM_SECONDS", "1", 1);
    const auto start = std::chrono::steady_clock::now();
    const auto r =
        cambium::test::run("bake " + kPopulus + " --frames 1-2 --voxel-size 0.05 --slurm -o " +
                           (dir / "s.####.vdb").string());
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ::setenv("PATH", path.c_str(), 1);
    ::unsetenv("CAMBIUM_SLURM_SECONDS");
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_NE(r.err.find("sbatch did not answer in 1 s and was stopped"), std::string::npos)
        << r.err;
    EXPECT_LT(seconds, 25.0) << "the hung sbatch was waited for";
    // The limit is whole seconds, as written (1e30 was read as 1, "abc" and
    // 0 were ignored for the default, silently): refused before anything.
    for (const char* bad : {"1e30", "abc", "0", "-1", "99999999999999999999", ""}) {
        ::setenv("CAMBIUM_SLURM_SECONDS", bad, 1);
        ::setenv("PATH", (bin.string() + ":" + path).c_str(), 1);
        const auto refused =
            cambium::test::run("bake " + kPopulus + " --frames 1-2 --voxel-size 0.05 --slurm -o " +
                               (dir / "bad.####.vdb").string());
        ::setenv("PATH", path.c_str(), 1);
        ::unsetenv("CAMBIUM_SLURM_SECONDS");
        EXPECT_EQ(refused.status, 2) << bad << ": " << refused.err;
        EXPECT_NE(refused.err.find("CAMBIUM_SLURM_SECONDS: '" + std::string(bad) +
                                   "' is not a whole number of seconds from 1 to 86400"),
                  std::string::npos)
            << refused.err;
        EXPECT_FALSE(fs::exists(dir / "bad.frames.vdb.farm")) << bad;
    }
}

TEST(FarmArray, SlurmsAnswersAreCheckedAndAStoppedSubmissionLeavesNothingRunning)
{
    namespace fs = std::filesystem;
    const fs::path dir = cambium::test::freshDir("cambium_farm_answers");
    const fs::path bin = dir / "bin", log = dir / "scancel.log";
    fs::create_directories(bin);
    auto fake = [&](const std::string& name, const std::string& body) {
        std::ofstream(bin / name) << "#!/bin/sh\n" << body << "\n";
        fs::permissions(bin / name, fs::perms::owner_all);
    };
    const std::string path = std::getenv("PATH") ? std::getenv("PATH") : "/usr/bin:/bin";
    ::setenv("PATH", (bin.string() + ":" + path).c_str(), 1);
    ::setenv("CAMBIUM_SLURM_SECONDS", "2", 1);
    auto bake = [&](const std::string& name) {
        return cambium::test::run("bake " + kPopulus +
                                  " --frames 1-2 --voxel-size 0.05 --slurm -o " +
                                  (dir / name / "s.####.vdb").string());
    };
    // (1) Nodes of 1 MB: no task fits, refused before anything is written
    // (it was submitted).
    fake("sinfo", "echo 1 1");
    fake("sbatch", "echo 4242");
    fs::create_directories(dir / "small");
    auto r = bake("small");
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("MB of memory, and the largest node Slurm lists (sinfo) has 1 MB"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(fs::exists(dir / "small" / "s.frames.vdb.farm"));
    // (2) An answer that is not a job id ("42 42" went into the job list).
    fake("sinfo", "echo 2 4000");
    fake("sbatch", "echo 42 42");
    fs::create_directories(dir / "twice");
    r = bake("twice");
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_NE(r.err.find("sbatch refused"), std::string::npos) << r.err;
    // (3) The final job's sbatch stopped for its time after submitting it:
    // the array and the final job waiting on it are both cancelled.
    const fs::path count = dir / "sbatch.count";
    fake("sbatch", "if [ -e " + count.string() + " ]; then sleep 30; fi; touch " + count.string() +
                       "; echo 4242");
    fake("squeue", "echo '4243 afterany:4242(unfulfilled)'; echo '5555 afterany:42420'");
    fake("scancel", "echo \"$@\" >> " + log.string());
    fs::create_directories(dir / "stopped");
    r = bake("stopped");
    EXPECT_EQ(r.status, 1) << r.err;
    EXPECT_NE(r.err.find("sbatch did not answer in 2 s"), std::string::npos) << r.err;
    EXPECT_EQ(cambium::test::fileContents(log), "4242\n4243\n");
    ::setenv("PATH", path.c_str(), 1);
    ::unsetenv("CAMBIUM_SLURM_SECONDS");
}
