// Nothing is lost: for every command and output kind, a write that fails
// fails (exit 1, the reason named) and leaves the old file and no temporary;
// outputs that are not regular files are refused before any work; a signal
// removes the temporary; one run at a time writes a sequence; --resume
// cleans stale temporaries and bakes damaged frames again.
#include "temp_dir.h"
#include "test_util.h"
#include "io/vdb.h"
#include "cli_util.h"
#include "core/files.h"

#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <sstream>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sys/stat.h>
#include <thread>

namespace {

using namespace cambium;
using namespace cambium::test;
namespace fs = std::filesystem;

const std::string kExamples = CAMBIUM_SOURCE_DIR "/examples/";
const std::string kScene = kExamples + "sphere_and_cone.json";
const std::string kPopulus = kExamples + "populus/populus.json";

using cambium::test::freshDir;

/// Every file of a directory with its contents: what "nothing changed" compares.
std::map<std::string, std::string> snapshot(const fs::path& dir)
{
    std::map<std::string, std::string> files;
    for (const auto& e : fs::directory_iterator(dir))
        files[e.path().filename().string()] =
            e.is_regular_file() ? fileContents(e.path()) : "(not a regular file)";
    return files;
}

/// A small baked level set for the commands that read one.
const std::string& fixtureVdb()
{
    static const std::string path = [] {
        const fs::path dir = freshDir("cambium_errors_fixture");
        const std::string vdb = (dir / "s.vdb").string();
        const Result r = run("bake " + kScene + " -o " + vdb + " --voxel-size 0.05 --device cpu");
        EXPECT_EQ(r.status, 0) << r.err;
        return vdb;
    }();
    return path;
}

/// One output of each kind: the command line that writes OUT (a file in the
/// test's directory) and the name of OUT.
struct OutputKind {
    std::string name, args;
};

std::vector<OutputKind> outputKinds()
{
    const std::string vdb = fixtureVdb();
    return {
        {"out.vdb", "bake " + kScene + " --voxel-size 0.05 --device cpu -o OUT"},
        {"out.0002.vdb",
         "bake " + kPopulus + " --frames 2 --voxel-size 0.05 --device cpu -o DIR/out.####.vdb"},
        {"out.obj", "mesh " + vdb + " -o OUT"},
        {"out.ply", "mesh " + vdb + " -o OUT"},
        {"out.png", "render " + vdb + " --width 48 --height 32 --device cpu -o OUT"},
        {"out.exr", "render " + vdb + " --width 48 --height 32 --device cpu -o OUT"},
    };
}

/// ARGS with each KEY replaced by its value.
std::string substitute(std::string s, const std::vector<std::pair<std::string, std::string>>& vars)
{
    for (const auto& [key, value] : vars)
        for (size_t at; (at = s.find(key)) != std::string::npos;)
            s.replace(at, key.size(), value);
    return s;
}

TEST(NothingIsLost, AFailedWriteFailsAndKeepsTheOldFileForEveryOutputKind)
{
    // The injected failure: a file size limit of 0, SIGXFSZ at its default
    // (`ulimit -f 0`): cambium ignores the signal, so every write(2) of the
    // output fails with EFBIG (killed by SIGXFSZ, every command left its
    // temporary, sweep 20).
    for (const OutputKind& k : outputKinds()) {
        const fs::path dir = freshDir("cambium_errors_efbig");
        const std::string args =
            substitute(k.args, {{"OUT", (dir / k.name).string()}, {"DIR", dir.string()}});
        const Result good = run(args);
        ASSERT_EQ(good.status, 0) << args << "\n" << good.err;
        const auto before = snapshot(dir);
        ASSERT_EQ(before.size(), 1u) << args;
        const Result bad = run(args, 0);
        EXPECT_EQ(bad.status, 1) << args << "\n" << bad.err;
        EXPECT_NE(
            bad.err.find((dir / k.name).string() + ": cannot write the output: File too large"),
            std::string::npos)
            << bad.err;
        EXPECT_EQ(snapshot(dir), before) << args;  // the old file whole, no temporary
        fs::remove_all(dir);
    }
}

TEST(NothingIsLost, AFullFilesystemFailsTheBakeTheSequenceAndTheRender)
{
    const fs::path dir = freshDir("cambium_errors_full");
    if (::geteuid() != 0 ||
        std::system(("mount -t tmpfs -o size=700k tmpfs " + dir.string() + " 2>/dev/null").c_str()))
        GTEST_SKIP() << "cannot mount a tmpfs here (not root, or no permission)";
    // (Sizes between the bake's disk estimate, which is low on purpose, and
    // what it writes: the estimate passes, the write fails.  A plan whose
    // estimate does not fit is refused before work: BadInput below.)
    std::ofstream(dir / "keep.vdb") << "a good file";
    const auto before = snapshot(dir);
    for (const std::string& args :
         {"bake " + kScene + " --voxel-size 0.02 --device cpu -o " + (dir / "keep.vdb").string(),
          "render " + fixtureVdb() + " --width 512 --height 512 --device cpu -o " +
              (dir / "keep.exr").string()}) {
        const Result r = run(args);
        EXPECT_EQ(r.status, 1) << args << "\n" << r.out << r.err;
        EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
        EXPECT_EQ(snapshot(dir), before) << args;
    }
    // A sequence stops at the first frame that does not fit; every frame
    // that is there is whole.  (Its estimate: 2.4 MB; its frames: 2.6 MB and
    // 8.1 MB, with the twigs as they are: thickened, the estimate is over
    // the 5 MB.)
    ASSERT_EQ(std::system(("mount -o remount,size=5m " + dir.string()).c_str()), 0);
    const Result r = run("bake " + kPopulus +
                         " --frames 8-12:4 --voxel-size 0.01 --min-radius 0 --jobs 1 --device cpu "
                         "-o " +
                         (dir / "tree.####.vdb").string());
    EXPECT_EQ(r.status, 1) << r.out << r.err;
    EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
    for (const auto& [name, text] : snapshot(dir)) {
        if (name == "keep.vdb")
            continue;
        EXPECT_EQ(name.find(".tmp-"), std::string::npos) << name;
        EXPECT_NO_THROW(inspectVdb((dir / name).string())) << name;
    }
    std::system(("umount " + dir.string()).c_str());
}

TEST(NothingIsLost, AFrameOrTileThatIsALinkIsRefused)
{
    // A part of many outputs is not written through a link: a farm's retry
    // of frame 2, linked by hand to frame 3, overwrote frame 3 with exit 0
    // (sweep 25); two frames linked to one file outside the pattern, a tile
    // linked to another and mesh/render frames did the same (sweep 26).
    const fs::path dir = freshDir("cambium_errors_linked_frame");
    const std::string pattern = (dir / "p.####.vdb").string();
    ASSERT_EQ(run("bake " + kPopulus + " --frames 3-3 --voxel-size 0.1 -o " + pattern).status, 0);
    fs::copy_file(dir / "p.0003.vdb", dir / "x.vdb");
    fs::create_symlink("p.0003.vdb", dir / "p.0002.vdb");
    fs::create_symlink("x.vdb", dir / "p.0004.vdb");
    fs::create_symlink("x.vdb", dir / "m.0003.obj");
    fs::create_symlink("x.vdb", dir / "tile-2.vdb");
    const std::string before = fileContents(dir / "p.0003.vdb"), x = fileContents(dir / "x.vdb");
    const std::pair<std::string, std::string> cases[] = {
        {"bake " + kPopulus + " --frames 2-2 --voxel-size 0.1 -o " + pattern, "p.0002.vdb"},
        {"bake " + kPopulus + " --frames 4-4 --voxel-size 0.1 --resume -o " + pattern,
         "p.0004.vdb"},
        {"mesh " + pattern + " --frames 3-3 -o " + (dir / "m.####.obj").string(), "m.0003.obj"},
        {"bake " + kPopulus + " --voxel-size 0.1 --tile 2/3 -o " + (dir / "tile-2.vdb").string(),
         "tile-2.vdb: a symbolic link, where a tile of a farm is written"},
    };
    for (const auto& [args, expected] : cases) {
        const Result r = run(args);
        EXPECT_EQ(r.status, 2) << args << "\n" << r.err;
        EXPECT_NE(r.err.find(expected), std::string::npos) << args << "\n" << r.err;
        EXPECT_NE(r.err.find("a symbolic link, where a "), std::string::npos) << r.err;
    }
    EXPECT_EQ(fileContents(dir / "p.0003.vdb"), before);
    EXPECT_EQ(fileContents(dir / "x.vdb"), x);
}

TEST(NothingIsLost, OutputsThatAreNotRegularFilesAreRefusedBeforeWork)
{
    const fs::path dir = freshDir("cambium_errors_kinds");
    ASSERT_EQ(::mkfifo((dir / "fifo.vdb").c_str(), 0644), 0);
    ASSERT_EQ(::mkfifo((dir / "seq.0002.vdb").c_str(), 0644), 0);
    fs::create_directories(dir / "d.ply");
    const std::string vdb = fixtureVdb();
    const std::pair<std::string, std::string> cases[] = {
        {"bake " + kScene + " -o /dev/full",
         "/dev/full: is a character device, not a regular file"},
        {"bake " + kScene + " -o /dev/null", "/dev/null: is a character device"},
        {"bake " + kScene + " -o " + (dir / "fifo.vdb").string(), "fifo.vdb: is a FIFO"},
        {"bake " + kPopulus + " --frames 1-3 -o " + (dir / "seq.####.vdb").string(),
         "seq.0002.vdb: is a FIFO"},
        {"mesh " + vdb + " -o " + (dir / "d.ply").string(), "d.ply: is a directory"},
        {"bake " + kScene + " -o " + dir.string(), ": is a directory"},
        // (an input: the sequence's camera, framed on its last frame, opened
        // that frame before its check and waited for ever, sweep 24)
        {"render " + (dir / "seq.####.vdb").string() + " --frames 2-2 --width 8 --height 8 -o " +
             (dir / "r.####.png").string(),
         "seq.0002.vdb: is a device, FIFO or socket"},
        // (every option's empty value refused as such, before its own check)
        {"bake " + kScene + " -o ''", "--output: an empty value"},
        {"mesh " + vdb + " -o ''", "--output: an empty value"},
    };
    const auto before = snapshot(dir);
    for (const auto& [args, expected] : cases) {
        const Result r = run(args);
        EXPECT_EQ(r.status, 2) << args;
        EXPECT_NE(r.err.find(expected), std::string::npos) << args << "\n" << r.err;
        EXPECT_EQ(r.out, "") << args;  // refused before any work
    }
    EXPECT_EQ(snapshot(dir), before);
    struct stat st;
    ASSERT_EQ(::stat("/dev/full", &st), 0);
    EXPECT_TRUE(S_ISCHR(st.st_mode));
}

/// The state letter of process `pid` (R, S, T stopped, Z a zombie), or 0
/// when there is no such process.
char processState(long pid)
{
    std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
    std::string line;
    if (!std::getline(in, line) || line.rfind(')') == std::string::npos)
        return 0;
    return line[line.rfind(')') + 2];
}

/// The pid of `cambium ARGS` started in the background with the writer's
/// test seam set (it stops itself with SIGSTOP once a temporary exists).
long startStoppingInWrite(const std::string& args)
{
    const std::string cmd = "CAMBIUM_TEST_STOP_IN_WRITE=1 " + std::string(CAMBIUM_EXE) + " " +
                            args + " >/dev/null 2>&1 & echo $!";
    FILE* p = ::popen(cmd.c_str(), "r");
    long pid = 0;
    if (std::fscanf(p, "%ld", &pid) != 1)
        pid = 0;
    ::pclose(p);
    return pid;
}

/// Whether process `pid` ended within a minute (gone, or a zombie no one
/// reaps here: it has finished all the same).
bool endsWithinAMinute(long pid)
{
    const auto start = std::chrono::steady_clock::now();
    char state;
    while ((state = processState(pid)) != 0 && state != 'Z' &&
           std::chrono::steady_clock::now() - start < std::chrono::seconds(60))
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
    return state == 0 || state == 'Z';
}

TEST(NothingIsLost, ASignalDuringTheWriteRemovesTheTemporary)
{
    const fs::path dir = freshDir("cambium_errors_signal");
    const std::string out = (dir / "tree.vdb").string();
    // The bake stops itself once its temporary exists (the writer's test
    // seam): the signal comes then, not in a race with the write.
    const long pid =
        startStoppingInWrite("bake " + kScene + " --voxel-size 0.05 --device cpu -o " + out);
    ASSERT_NE(pid, 0);
    const auto start = std::chrono::steady_clock::now();
    char state = processState(pid);
    while (state != 'T' && state != 0 && state != 'Z' &&
           std::chrono::steady_clock::now() - start < std::chrono::minutes(5)) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        state = processState(pid);
    }
    ASSERT_EQ(state, 'T') << "the bake did not stop in its write";
    const std::string tmp = out + ".tmp-" + std::to_string(pid);
    EXPECT_TRUE(fs::exists(tmp));
    ::kill(pid_t(pid), SIGTERM);
    ::kill(pid_t(pid), SIGCONT);
    EXPECT_TRUE(endsWithinAMinute(pid)) << pid << " still runs";
    EXPECT_TRUE(snapshot(dir).empty()) << "left: " << snapshot(dir).begin()->first;
    // A temporary that a killed bake left (its process gone) is removed by
    // the next bake of the file, which says so.
    std::ofstream(dir / "tree.vdb.tmp-99999997") << "half a file";
    const Result r = run("bake " + kScene + " --voxel-size 0.05 --device cpu -o " + out);
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("removed " + out + ".tmp-99999997, a temporary file left"),
              std::string::npos)
        << r.out;
    const auto left = snapshot(dir);
    ASSERT_EQ(left.size(), 1u);
    EXPECT_EQ(left.begin()->first, "tree.vdb");
}

TEST(NothingIsLost, ASignalToALocalTiledBakeEndsItsTileAndRemovesItsTiles)
{
    // The tiles' bakes stop themselves in their writes (the writer's test
    // seam); the first one's stop is when the signal reaches the parent
    // (the parent alone, as `kill` sends it; Ctrl-C reaches both): the
    // tile's bake must end and remove its temporary, and the parent the
    // tiles' directory.
    const fs::path dir = freshDir("cambium_errors_tiles_signal");
    const std::string out = (dir / "tree.vdb").string();
    const long pid = startStoppingInWrite("bake " + kScene +
                                          " --voxel-size 0.05 --device cpu --tiles 3 -o " + out);
    ASSERT_NE(pid, 0);
    // The first tile's bake, stopped with its temporary made.
    const fs::path tiles = dir / (".tree.vdb.tiles-" + std::to_string(pid));
    long child = 0;
    const auto start = std::chrono::steady_clock::now();
    while (child == 0 && std::chrono::steady_clock::now() - start < std::chrono::minutes(5)) {
        std::error_code ec;
        for (const auto& e : fs::directory_iterator(tiles, ec)) {
            const std::string name = e.path().filename().string();
            if (name.rfind("tile-1.vdb.tmp-", 0) == 0)
                child = std::stol(name.substr(15));
        }
        if (child == 0 || processState(child) != 'T') {
            child = 0;
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
    }
    ASSERT_NE(child, 0) << "the first tile's bake did not stop in its write";
    // (SIGTERM: a background job of a script starts with SIGINT ignored,
    // which cambium keeps, as for nohup; the handler is the same.)
    ::kill(pid_t(pid), SIGTERM);
    for (const long q : {pid, child})
        EXPECT_TRUE(endsWithinAMinute(q)) << q << " still runs";
    ::kill(pid_t(child), SIGKILL);  // (nothing, when it ended as it should)
    ::kill(pid_t(pid), SIGKILL);
    EXPECT_TRUE(snapshot(dir).empty()) << "left: " << snapshot(dir).begin()->first;
    EXPECT_FALSE(fs::exists(tiles));
}

TEST(NothingIsLost, OneSequenceAtATimePerPattern)
{
    const fs::path dir = freshDir("cambium_errors_lock");
    const std::string pattern = (dir / "tree.####.vdb").string();
    const OutputLock held(pattern);  // as another run would hold it
    const Result r =
        run("bake " + kPopulus + " --frames 1-2 --voxel-size 0.05 --device cpu -o " + pattern);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("another cambium (pid " + std::to_string(::getpid()) + ")"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(snapshot(dir).size(), 1u);  // the lock file only: no frame written
}

TEST(NothingIsLost, ResumeRemovesStaleTemporariesAndBakesDamagedFramesAgain)
{
    const fs::path dir = freshDir("cambium_errors_resume");
    const std::string pattern = (dir / "tree.####.vdb").string();
    const std::string bake =
        "bake " + kPopulus + " --frames 2-4 --voxel-size 0.05 --device cpu -o " + pattern;
    ASSERT_EQ(run(bake).status, 0);
    // A killed run's temporary, another pattern's temporary, a damaged frame.
    std::ofstream(dir / "tree.0003.vdb.tmp-999999") << "half a frame";
    std::ofstream(dir / "bush.0003.vdb.tmp-999999") << "not ours";
    const std::string third = (dir / "tree.0004.vdb").string();
    const std::string whole = fileContents(third);
    fs::resize_file(third, whole.size() * 9 / 10);
    const std::string second = fileContents(dir / "tree.0002.vdb");

    const Result r = run(bake + " --resume");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("removed " + (dir / "tree.0003.vdb.tmp-999999").string()),
              std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("tree.0004.vdb: a truncated .vdb file"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir / "tree.0003.vdb.tmp-999999"));
    EXPECT_TRUE(fs::exists(dir / "bush.0003.vdb.tmp-999999"));
    EXPECT_EQ(fileContents(dir / "tree.0002.vdb"), second);  // kept, not rewritten
    EXPECT_EQ(fs::file_size(third), whole.size());           // baked again, whole
    EXPECT_NO_THROW(inspectVdb(third));
}

}  // namespace

namespace {

/// The table of bad inputs: every input kind and option, each refused with
/// exit status 2 and a message naming the file or option, before any output
/// changes.  A new input kind or option adds its rows here.
struct BadInput {
    std::string args;  ///< IN: the inputs' directory, OUT: the outputs' directory, VDB: a good .vdb
    std::string expected;  ///< in the message: the file, option or place, and the problem
};

void writeText(const fs::path& p, const std::string& text)
{
    std::ofstream(p, std::ios::binary) << text;
}

TEST(BadInput, EveryCaseIsRefusedByNameWithStatus2AndNoOutputChanged)
{
    const fs::path in = freshDir("cambium_bad_in"), out = freshDir("cambium_bad_out");
    const std::string vdb = fixtureVdb(), good = fileContents(vdb);
    // Inputs.
    std::string deep;
    for (int i = 0; i < 20000; ++i)
        deep += R"({"type": "blend", "children": [)";
    deep += R"({"type": "sphere", "center": [0,0,0], "radius": 1})";
    for (int i = 0; i < 20000; ++i)
        deep += "]}";
    writeText(in / "deep.json", R"({"root": )" + deep + "}");
    writeText(in / "dup.json",
              R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 1, "radius": 2}})");
    writeText(in / "nan.json", R"({"root": {"type": "sphere", "center": [0,NaN,0], "radius": 1}})");
    writeText(in / "neg.json",
              R"({"root": {"type": "cone", "p0": [0,0,0], "p1": [0,1,0], "r0": -1, "r1": 0.1}})");
    writeText(in / "type.json", R"({"root": {"type": "spehre", "center": [0,0,0], "radius": 1}})");
    writeText(in / "big.json", R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 3e6}})");
    writeText(in / "sharp.json",
              R"({"root": {"type": "convolution_segment", "p0": [0, 0, 0], "p1": [0, 1, 0], )"
              R"("r0": 0.1, "r1": 0.1, "kernel_width": 1e9}})");
    writeText(in / "heavy.json",
              R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 1, "weight": 1e39}})");
    // (warps and operators past the kernels' float: sweep 12, each exit 0
    // with a wrong surface on the default device)
    const std::string cone =
        R"({"type": "cone", "p0": [0, 0, 0], "p1": [0, 1, 0], "r0": 0.2, "r1": 0.1})";
    writeText(in / "twist.json", R"({"root": {"type": "twist", "origin": [0, 0, 0], "axis": )"
                                 R"([0, 1, 0], "rate": 1e20, "children": [)" +
                                     cone + "]}}");
    writeText(in / "taper.json", R"({"root": {"type": "taper", "origin": [0, 0, 0], "axis": )"
                                 R"([0, 1, 0], "length": 1, "scale0": 1, "scale1": 1e-8, )"
                                 R"("children": [)" +
                                     cone + "]}}");
    writeText(in / "ricci.json",
              R"({"root": {"type": "ricci", "n": 256, "children": [{"type": "sphere", "center": )"
              R"([0, 0, 0], "radius": 1}, {"type": "sphere", "center": [0.8, 0, 0], "radius": )"
              R"(0.7}]}})");
    writeText(in / "moved.json",
              R"({"root": {"type": "transform", "translate": [-1e5, 0, 0], "children": [)"
              R"({"type": "cone", "p0": [1e5, 0, 0], "p1": [1e5, 1, 0], "r0": 0.2, "r1": 0.1}]}})");
    // (translations of -1e6 and +1e6 cancel in double, not in the kernels'
    // float: the cone baked as a stepped slab, exit 0)
    {
        // Nine warps in a row: one more than the kernels' frames hold.
        std::string warps = R"({"type": "sphere", "center": [0, 0, 0], "radius": 1})";
        for (int i = 0; i < 9; ++i)
            warps = R"({"type": "transform", "translate": [0, 0, 0], "children": [)" + warps + "]}";
        writeText(in / "warps.json", R"({"root": )" + warps + "}");
    }
    writeText(in / "nested.json",
              R"({"root": {"type": "transform", "translate": [-1e6, 0, 0], "children": [)"
              R"({"type": "transform", "translate": [1e6, 0, 0], "children": [)"
              R"({"type": "cone", "p0": [0, 0, 0], "p1": [0, 1, 0], "r0": 0.1, "r1": 0.05}]}]}})");
    // A unit sphere drawn 10 and 100 times larger by a transform or a taper:
    // the memory estimate counted its own area (exit 1, out of memory, after
    // half a minute), and a scale of [100, 1, 100] was said to reach 2e4.
    writeText(in / "scaled.json", R"({"root": {"type": "transform", "scale": 10, "children": [)"
                                  R"({"type": "sphere", "center": [0, 0, 0], "radius": 1}]}})");
    writeText(in / "stretched.json",
              R"({"root": {"type": "transform", "scale": [100, 1, 100], "children": [)"
              R"({"type": "sphere", "center": [0, 0, 0], "radius": 1}]}})");
    writeText(in / "tapered.json",
              R"({"root": {"type": "taper", "origin": [0, 0, 0], "axis": [0, 1, 0], "length": 1,)"
              R"( "scale0": 100, "scale1": 100, "children": [)"
              R"({"type": "sphere", "center": [0, 0, 0], "radius": 1}]}})");
    writeText(in / "nul.json",
              R"({"root": {"type": "sph\u0000ere", "center": [0,0,0], "radius": 1}})");
    writeText(in / "far.json",
              R"({"root": {"type": "sphere", "center": [1e300,0,0], "radius": 1}})");
    writeText(in / "vast.json",
              R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 1e14}})");
    writeText(in / "tiny.json",
              R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 1e-6}})");
    writeText(in / "empty.json", "");
    writeText(in / "binary.json", std::string("{\0\1\2", 4));
    fs::create_directories(in / "dir.json");
    writeText(in / "bad.l", "Axiom: A\nA --> B(\n");
    writeText(in / "explode.l", "derivation length: 60\nAxiom: A\nA --> AA\n");
    writeText(in / "unbalanced.l", "Axiom: F[F\n");
    writeText(in / "turnnan.l", "Axiom: F+(0/0)F\n");
    writeText(in / "hex.l", "Axiom: F(0x10)\n");
    writeText(in / "hex.txt", "1 -1 0 0 0 0 0x10 0 0.1 0.1\n");
    writeText(in / "far.l", "Axiom: f(1e300)F\n");
    writeText(in / "cycle.txt", "1 2 0 0 0 0 1 0 0.1 0.1\n2 1 0 1 0 0 2 0 0.1 0.1\n");
    writeText(in / "self.txt", "1 1 0 0 0 0 1 0 0.1 0.1\n");
    writeText(in / "nine.txt", "1 -1 0 0 0 0 1 0 0.1\n");
    writeText(in / "nanr.txt", "1 -1 0 0 0 0 1 0 nan 0.1\n");
    writeText(in / "negr.txt", "1 -1 0 0 0 0 1 0 -0.1 0.1\n");
    writeText(in / "twice.txt", "1 -1 0 0 0 0 1 0 0.1 0.1\n1 -1 0 0 0 0 1 0 0.1 0.1\n");
    writeText(in / "point.txt", "1 -1 0 0 0 0 1 0 0.1 0.1\n2 1 0 1 0 0 1 0 0.1 0.05\n");
    writeText(in / "orphan.txt", "1 7 0 0 0 0 1 0 0.1 0.1\n");
    writeText(in / "stem.txt", "1 -1 0 0 0 0 1 0 0.1 0.1\n2 1 0 1 0 0.3 2 0 0.08 0.05\n");
    std::string growth = fileContents(kPopulus);
    writeText(in / "growth_dup.json", "{\"years\": 3, " + growth.substr(growth.find('{') + 1));
    writeText(in / "trunc100.vdb", good.substr(0, 100));
    writeText(in / "trunc90.vdb", good.substr(0, good.size() * 9 / 10));
    // A sequence whose second frame is cut short: refused before the first
    // frame's mesh or picture is written.
    writeText(in / "good.1.vdb", good);
    writeText(in / "good.2.vdb", good);
    writeText(in / "part.1.vdb", good);
    writeText(in / "part.2.vdb", good.substr(0, good.size() * 9 / 10));
    std::string flipped = good;
    flipped[flipped.size() * 2 / 3] ^= 0x10;  // a bit changed inside a grid's compressed data
    writeText(in / "flipped.vdb", flipped);
    // ... and one whose second frame has a byte changed (the first frame's
    // mesh was written before the second's checksum was read)
    writeText(in / "flip.1.vdb", good);
    writeText(in / "flip.2.vdb", flipped);
    writeText(in / "text.vdb", "not a vdb at all\n");
    writeText(in / "zeros.vdb", std::string(4096, '\0'));
    writeText(in / "index.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    writeText(in / "noface.obj", "v 0 0 0\n");
    writeText(in / "far.obj", "v 0 0 0\nv 1e38 0 1\nv 0 1 0\nf 1 2 3\n");
    writeText(in / "back.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -9\n");
    writeText(in / "index.ply",
              "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float "
              "y\nproperty float z\nelement face 2\nproperty list uchar int "
              "vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 7\n");
    {
        // A binary PLY whose header claims 2^31 faces and holds one.
        std::string ply =
            "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty "
            "float y\nproperty float z\nelement face 2147483648\nproperty list uchar int "
            "vertex_indices\nend_header\n";
        const float xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
        ply.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
        const int32_t face[3] = {0, 1, 2};
        ply.push_back(char(3));
        ply.append(reinterpret_cast<const char*>(face), sizeof face);
        writeText(in / "liar.ply", ply);
    }
    writeText(in / "bad.ply", "ply\nformat binary_big_endian 1.0\nend_header\n");
    writeText(in / "growing.json",
              R"({"base": {"type": "sphere", "radius": 1, "cells": 2}, "levels": 4,
                  "details": [{"type": "tentacle", "spacing": 0.8, "seed": 2, "levels": [1, 2],
                               "length": {"keys": [[1, 0.01], [3, 1000]]}}]})");
    {
        std::string edits;  // twenty edits each allowed alone, together past any size
        for (int i = 0; i < 20; ++i)
            edits += std::string(i ? "," : "") + R"({"at": [0, 0, 1], "radius": 100, "gain": 100})";
        writeText(in / "far_edits.json",
                  R"({"base": {"type": "sphere", "radius": 1}, "levels": 6, "details": )"
                  R"([{"type": "rock", "amplitude": 0.08, "seed": 3}], "edits": [)" +
                      edits + "]}");
    }
    {
        // 4 KB of file, 3.5e13 active voxels in tiles (a 32768-voxel cube)
        openvdb::initialize();
        auto tiles = openvdb::FloatGrid::create(0.3f);
        tiles->setName("surface");
        tiles->setGridClass(openvdb::GRID_LEVEL_SET);
        tiles->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
        tiles->tree().fill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(32767)), -0.3f,
                           true);
        openvdb::io::File((in / "tiles.vdb").string()).write({tiles});
        writeText(in / "tiles_base.json", R"({"base": {"type": "vdb", "file": "tiles.vdb"}})");
        // A sphere's band and 100 active tiles of 128^3: 2.1e8 voxels that fit
        // in memory as floats (750 of them aborted mesh and shape for memory,
        // and 600 took a shape past a minute, sweep 21)
        auto many = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
            0.5f, openvdb::Vec3f(0.0f), 0.1f);
        many->setName("surface");
        for (int k = 0; k < 100; ++k)
            many->tree().addTile(2, openvdb::Coord(128 * (1 + k % 10), 128 * (1 + k / 10), 0),
                                 -0.3f, true);
        openvdb::io::File((in / "many_tiles.vdb").string()).write({many});
        writeText(in / "many_tiles_base.json",
                  R"({"base": {"type": "vdb", "file": "many_tiles.vdb"}, "levels": 2})");
        // two grids of one name, and a level set with nothing in it
        auto sphere = openvdb::FloatGrid::create(0.3f);
        sphere->setName("surface");
        sphere->setGridClass(openvdb::GRID_LEVEL_SET);
        sphere->setTransform(openvdb::math::Transform::createLinearTransform(0.1));
        openvdb::io::File((in / "empty.vdb").string()).write({sphere});
        sphere->tree().setValue(openvdb::Coord(0), -0.1f);
        openvdb::io::File((in / "twice.vdb").string()).write({sphere, sphere->deepCopy()});
        {
            // two colour grids beside one surface (one was picked)
            auto cd = openvdb::Vec3SGrid::create();
            cd->setName("Cd");
            cd->setTransform(sphere->transform().copy());
            openvdb::io::File((in / "twocd.vdb").string()).write({sphere, cd, cd->deepCopy()});
        }
        // what OpenVDB's tools take for granted of a level set, broken
        openvdb::FloatGrid::Ptr nan = sphere->deepCopy();
        nan->tree().setValue(openvdb::Coord(3, 4, 5), std::nanf(""));
        openvdb::io::File((in / "nan.vdb").string()).write({nan});
        openvdb::FloatGrid::Ptr flat = sphere->deepCopy();
        flat->transform().preScale(openvdb::Vec3d(1.0, 1.0, 0.5));
        openvdb::io::File((in / "flat.vdb").string()).write({flat});
        // voxels too large to mesh (volumeToMesh wrote infinities), mirrored
        // ones (a mesh inside out), and a float tree relabelled as vectors
        // (decoded as vectors, then the tools spun forever)
        openvdb::FloatGrid::Ptr huge = sphere->deepCopy();
        huge->setTransform(openvdb::math::Transform::createLinearTransform(1e300));
        openvdb::io::File((in / "huge.vdb").string()).write({huge});
        openvdb::FloatGrid::Ptr mirror = sphere->deepCopy();
        mirror->transform().preScale(openvdb::Vec3d(-1.0, 1.0, 1.0));
        openvdb::io::File((in / "mirror.vdb").string()).write({mirror});
        openvdb::io::File((in / "one.vdb").string()).write({sphere});
        std::string relabelled = fileContents(in / "one.vdb");
        for (size_t at; (at = relabelled.find("Tree_float_5_4_3")) != std::string::npos;)
            relabelled.replace(at, 16, "Tree_vec3s_5_4_3");
        writeText(in / "relabelled.vdb", relabelled);
        openvdb::FloatGrid::Ptr fog = openvdb::FloatGrid::create(0.0f);
        fog->setName("surface");
        fog->setGridClass(openvdb::GRID_LEVEL_SET);
        fog->tree().setValue(openvdb::Coord(0), 1.0f);
        openvdb::io::File((in / "fog.vdb").string()).write({fog});
    }
    {
        // 80 bytes whose PNG header claims 11000 x 11000 grey pixels
        const std::string hex =
            "89504e470d0a1a0a0000000d4948445200002af800002af80800000000eb44c5560000001749444154789"
            "c63601805a360148c8251300a46c150070007d000019b79c96f0000000049454e44ae426082";
        std::string bytes;
        for (size_t i = 0; i < hex.size(); i += 2)
            bytes.push_back(char(std::stoi(hex.substr(i, 2), nullptr, 16)));
        writeText(in / "liar.png", bytes);
    }
    {
        // A PNG whose compressed data is damaged (its chunk's CRC made right):
        // libpng printed its own line ahead of cambium's.
        std::string png = fileContents(CAMBIUM_SOURCE_DIR "/docs/images/bush.png");
        const size_t idat = png.find("IDAT");
        const uint32_t length = uint32_t(uint8_t(png[idat - 4])) << 24 |
                                uint32_t(uint8_t(png[idat - 3])) << 16 |
                                uint32_t(uint8_t(png[idat - 2])) << 8 | uint8_t(png[idat - 1]);
        png[idat + 200] = char(png[idat + 200] ^ 0xff);
        uint32_t crc = 0xffffffffu;  // CRC-32 of the chunk's type and data
        for (size_t i = idat; i < idat + 4 + length; ++i) {
            crc ^= uint8_t(png[i]);
            for (int k = 0; k < 8; ++k)
                crc = crc & 1 ? (crc >> 1) ^ 0xedb88320u : crc >> 1;
        }
        crc ^= 0xffffffffu;
        for (int k = 0; k < 4; ++k)
            png[idat + 4 + length + size_t(k)] = char(crc >> (24 - 8 * k));
        writeText(in / "zlib.png", png);
    }
    {
        // A PNG cut at 70 %, within a chunk.
        const std::string png = fileContents(CAMBIUM_SOURCE_DIR "/docs/images/bush.png");
        writeText(in / "cut.png", png.substr(0, png.size() * 7 / 10));
    }
    // A name OpenImageIO's "null" reader makes a picture of.
    writeText(in / "empty.null", "");
    // Outputs that are inputs under other names: a link, a second hard link.
    fs::create_symlink("trunc90.vdb", in / "alias.ply");
    fs::create_symlink("flipped.vdb", in / "alias.png");
    writeText(in / "model.json", fileContents(kScene));
    fs::create_hard_link(in / "model.json", in / "model.vdb");
    // ... and inputs a model or shape names inside it: a growth file's bark
    // photo, a strokes file; a frame that is the input, two frames one file.
    {
        std::string grow = fileContents(kPopulus);
        const std::string bark = R"("bark": {)";
        grow.replace(grow.find(bark), bark.size(), bark + R"("photo": "bark.png", )");
        writeText(in / "grow.json", grow);
        writeText(in / "bark.png", fileContents(CAMBIUM_SOURCE_DIR "/docs/images/bush.png"));
    }
    fs::create_symlink("bark.png", in / "photo.vdb");
    fs::create_symlink("grow.json", in / "grown.0002.vdb");
    writeText(in / "strokes.json", R"([{"at": [0, 0, 1], "radius": 0.5, "value": 1}])");
    writeText(in / "stroked.json",
              R"({"base": {"type": "cube"}, "levels": 2, "blend": {"a": {"details": []},
                  "b": {"details": [{"type": "rock", "amplitude": 0.05}]},
                  "alpha": {"type": "strokes", "file": "strokes.json"}}})");
    fs::create_symlink("strokes.json", in / "strokes.obj");
    // Numbers read past their meaning: a seed of 1.5, keys a span of 2e308
    // apart, 0x10 in an OBJ, a growth file's year 0 (not its last); a tile
    // of a frame as a whole surface.
    writeText(in / "zero.vdb", "");
    writeText(in / "flat.obj",
              "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 0 0\nf 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n");
    writeText(in / "flat.json", R"({"base": {"type": "mesh", "file": "flat.obj"}, "levels": 1})");
    writeText(
        in / "near1.json",
        R"({"threshold": 0.999999, "root": {"type": "sphere", "center": [0,0,0], "radius": 1}})");
    writeText(
        in / "near0.json",
        R"({"threshold": 1e-30, "root": {"type": "sphere", "center": [0,0,0], "radius": 1}})");
    writeText(in / "afar.json",
              R"({"root": {"type": "sphere", "center": [100000,0,0], "radius": 0.01}})");
    writeText(in / "farcube.obj",
              "v 1e7 0 0\nv 1e7 0 1\nv 1e7 1 0\nv 1e7 1 1\nv 10000001 0 0\n"
              "v 10000001 0 1\nv 10000001 1 0\nv 10000001 1 1\nf 1 3 4 2\n"
              "f 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n");
    writeText(in / "farshape.json", R"({"base": {"type": "mesh", "file": "farcube.obj"},
                                        "levels": 2})");
    writeText(in / "seed.json", R"({"base": {"type": "sphere"}, "levels": 2,
                                     "details": [{"type": "rock", "seed": 1.5}]})");
    writeText(in / "span.json", R"({"base": {"type": "sphere"}, "levels": 2, "details":
        [{"type": "rock", "amplitude": {"keys": [[-1e308, 0.01], [1e308, 0.05]]}}]})");
    writeText(in / "hex.obj",
              "v 0x10 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\n"
              "f 2 4 3\n");
    // A sphere of radius 0.01 weighted 1000: its surface lies 28 out, and
    // the estimate counted the 0.01 (a shape of it ran out of memory after
    // 57 s, exit 1).
    writeText(in / "weighted.json", R"({"root": {"type": "sphere", "center": [0, 0, 0], )"
                                    R"("radius": 0.01, "support": 60, "weight": 1000}})");
    writeText(in / "heavy_base.json", R"({"base": {"type": "model", "file": ")" +
                                          (in / "weighted.json").string() +
                                          R"(", "fine_voxel_size": 0.0001}, "levels": 1})");
    writeText(in / "year0.json", R"({"base": {"type": "model", "file": ")" + kPopulus +
                                     R"(", "year": 0, "voxel_size": 0.5}, "levels": 1})");
    ASSERT_EQ(run("bake " + kScene + " --tile 1/2 --voxel-size 0.05 --device cpu -o " +
                  (in / "tile.vdb").string())
                  .status,
              0);
    writeText(in / "tiled.json", R"({"base": {"type": "vdb", "file": "tile.vdb"}, "levels": 1})");
    // A mesh sequence whose second frame has a NaN point (frame 1's picture
    // was written first), and an output frame that is a directory (found
    // after frame 1's mesh was written).
    writeText(in / "mseq.1.obj",
              "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    writeText(in / "mseq.2.obj",
              "v 0 0 0\nv nan 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
    fs::create_directories(out / "dir.2.obj");
    fs::create_directories(out / "rdir.2.png");
    // Outputs that must survive every refusal.
    for (const char* name : {"out.vdb", "out.ply", "out.obj", "out.png", "out.exr", "seq.0001.vdb"})
        writeText(out / name, std::string("a good ") + name);
    writeText(out / "twin.0001.vdb", "a good twin.0001.vdb");
    fs::create_symlink("twin.0001.vdb", out / "twin.0002.vdb");
    const auto before = snapshot(out);
    const auto inputsBefore = snapshot(in);

    const std::string S = kScene, P = kPopulus, L = kExamples + "lsystems/sympodial.l";
    const std::vector<BadInput> cases = {
        // scenes and models
        {"bake IN/deep.json -o OUT/out.vdb", "deep.json: root.children[0]"},
        {"info IN/deep.json", "nested more than 512 levels deep"},
        {"bake IN/dup.json -o OUT/out.vdb", "dup.json: root: duplicate key 'radius'"},
        {"bake IN/nan.json -o OUT/out.vdb", "nan.json: JSON syntax error: parse error at line 1"},
        {"bake IN/neg.json -o OUT/out.vdb", "neg.json: root.r0: must be greater than 0"},
        // (the kernels sample in float: 1e39 was infinite, the surface inside out)
        // (a band of 3 voxels of 23437.5 was written as infinities, exit 0)
        {"bake IN/big.json --half -o OUT/out.vdb",
         "big.json: --half stores distances as 16-bit floats, at most 65504, and the band "
         "reaches 7.031e+04 (3 voxels of 23437.5)"},
        // (written with exit 0 on two x values: floats 1e7 from the origin)
        {"shape IN/farshape.json -o OUT/out.obj",
         "farshape.json: the shape's base, 1 across (voxels of its 512th), reaches 1e+07 from the "
         "origin, 5.12e+09 voxels of 0.00195312: beyond 1048576 voxels"},
        {"bake IN/heavy.json -o OUT/out.vdb",
         "heavy.json: root.weight: must be within -1e+06 and 1e+06 (got 1e+39)"},
        // (a terraced surface in the kernels' float, exit 0)
        {"bake IN/sharp.json -o OUT/out.vdb",
         "sharp.json: root.kernel_width: must be at most 100 / max(r0, r1) = 1000 (got 1e+09)"},
        {"bake IN/twist.json -o OUT/out.vdb",
         "twist.json: root.rate: must be at most 1e+06 degrees a unit in magnitude (got 1e+20)"},
        {"bake IN/taper.json -o OUT/out.vdb",
         "taper.json: root.scale1: must be from 0.001 to 1000 (got 1e-08)"},
        {"bake IN/ricci.json -o OUT/out.vdb", "ricci.json: root.n: must be at most 64 (got 256)"},
        {"bake IN/moved.json -o OUT/out.vdb",
         "moved.json: a primitive or warp, in its own frame before the transforms above it (in "
         "world units), reaches 1e+05 from the origin"},
        // (the message named no file)
        {"bake IN/warps.json -o OUT/out.vdb",
         "warps.json: the BlobTree nests too deeply for the field kernels: it needs 1 stack "
         "entries and 9 nested warps"},
        {"bake IN/nested.json -o OUT/out.vdb",
         "nested.json: a primitive or warp, in its own frame before the transforms above it (in "
         "world units), reaches 2e+06 from the origin"},
        // (a voxel of 1e9 over the bush baked 7 leaves of nothing, exit 0)
        {"bake IN/scaled.json -o OUT/out.vdb --voxel-size 100",
         "scaled.json: --voxel-size 100 is larger than the whole model, whose field reaches 40 "
         "across: no voxel would resolve its surface (automatic: 0.0781)"},
        {"bake IN/scaled.json -o OUT/out.vdb --voxel-size 0.0001",
         "scaled.json: a voxel size of 0.0001 for a surface 40 across (4e+05 voxels) needs about "
         "9.68 TB of memory"},
        {"bake IN/stretched.json -o OUT/out.vdb --voxel-size 0.001",
         "stretched.json: a voxel size of 0.001 for a surface 400 across (4e+05 voxels) needs "
         "about 9.68 TB of memory"},
        {"bake IN/tapered.json -o OUT/out.vdb --voxel-size 0.001",
         "tapered.json: a voxel size of 0.001 for a surface 565.7 across (5.66e+05 voxels) needs "
         "about 9.68 TB of memory"},
        {"bake IN/type.json -o OUT/out.vdb",
         "root.type: unknown node type 'spehre' (did you mean 'sphere'?)"},
        // (the message ended at the NUL, its quote unclosed)
        {"bake IN/nul.json -o OUT/out.vdb", "nul.json: root.type: unknown node type 'sph\\x00ere'"},
        {"bake IN/far.json -o OUT/out.vdb", "far.json: the model reaches 1e+300 from the origin"},
        {"bake IN/vast.json -o OUT/out.vdb",
         "vast.json: the surface is 4e+14 across: 512 voxels across it would be larger than 1e+09"},
        {"bake IN/tiny.json -o OUT/out.vdb", "tiny.json: the surface is only 4e-06 across"},
        {"bake IN/empty.json -o OUT/out.vdb", "empty.json: JSON syntax error"},
        {"bake IN/binary.json -o OUT/out.vdb", "binary.json: a binary file, not a scene file"},
        {"bake IN/dir.json -o OUT/out.vdb", "dir.json: is a directory, not a scene file"},
        {"bake VDB -o OUT/out.vdb", ": is a .vdb file (a baked level set), not a skeleton file"},
        {"bake /dev/zero -o OUT/out.vdb", "/dev/zero: is a device, FIFO or socket"},
        {"bake IN/missing.json -o OUT/out.vdb",
         "missing.json: cannot read the scene file: No such file"},
        {"eval IN/dup.json -- 0 0 0", "duplicate key 'radius'"},
        {"eval " + S + " -- nan 0 0", "eval: the point (nan, 0, 0) must have finite coordinates"},
        {"eval " + S + " 1e160 0 0",
         "eval: the point (1e+160, 0, 0) must have finite coordinates within 1e+15"},
        {"eval " + S + " -- 0 0", "point"},
        // (the model within cambium's coordinates too, as bake checks it: a
        // cone to z = 1e300 evaluated to a NaN gradient, exit 0; sweep 18)
        {"eval IN/far.json 0 0 0.05", "far.json: the model reaches 1e+300 from the origin"},
        // (bench read checks a --file as render and mesh do before its plain
        // OpenVDB peer reads it: a damaged one crashed the peer, exit 1)
        {"bench read --file IN/far.json --repeat 1", "far.json: not a .vdb file"},
        // L-systems
        // (NaN coordinates were printed with exit 0, and the bake told
        // "internode 0: its two ends coincide", naming no file)
        {"lsystem IN/turnnan.l --print-skeleton",
         "turnnan.l:1:11: '0/0' is not a number: a module's parameter must be a finite number"},
        {"bake IN/far.l -o OUT/out.vdb",
         "far.l: module 0 of the derived string (f(1e+300)): the turtle reaches 1e+300 from the "
         "origin"},
        {"bake IN/bad.l -o OUT/out.vdb", "bad.l:2"},
        {"bake IN/explode.l -o OUT/out.vdb", "explode.l: derivation step"},
        {"bake IN/unbalanced.l -o OUT/out.vdb", "unbalanced.l"},
        {"lsystem " + L + " --steps -1", "--steps: Value -1 not in range"},
        {"lsystem " + L + " --steps 1000000000", "--steps: Value 1000000000 not in range"},
        {"lsystem " + L + " --max-modules 0", "--max-modules: Value 0 not in range"},
        {"lsystem " + L + " --max-modules 1e11", "--max-modules"},
        {"lsystem " + L + " --seed -3", "--seed"},
        {"lsystem IN/missing.l", "missing.l: cannot read the L-system file"},
        // skeletons
        {"bake IN/cycle.txt -o OUT/out.vdb", "cycle.txt:1: internode 1 is its own ancestor"},
        {"bake IN/self.txt -o OUT/out.vdb",
         "self.txt:1: internode 1 is its own ancestor (parents in a cycle: 1 -> 1)"},
        {"bake IN/nine.txt -o OUT/out.vdb", "nine.txt:1: expected 10 fields"},
        {"bake IN/nanr.txt -o OUT/out.vdb", "nanr.txt:1: r0 is not a finite number"},
        // Hexadecimal numbers in decimal formats (read as 16 without a word).
        {"bake IN/hex.txt -o OUT/out.vdb", "hex.txt:1: y1 is not a finite number ('0x10')"},
        {"lsystem IN/hex.l", "bad number in '0x10' (numbers are decimal"},
        // ... and on the command line (strtold read 0x10 as 16, 1p3 as 8000)
        {"eval " + S + " -- 0x10 0 0", "point: '0x10' is not a decimal number"},
        {"lsystem " + L + " --seed 1p3", "--seed: '1p3' is not a decimal number"},
        {"bake IN/negr.txt -o OUT/out.vdb", "negr.txt:1: r0 must be greater than 0"},
        {"bake IN/twice.txt -o OUT/out.vdb", "twice.txt:2: id 1 appears twice"},
        {"bake IN/point.txt -o OUT/out.vdb",
         "point.txt:2: internode 2 has no length (its two points are the same)"},
        {"bake IN/orphan.txt -o OUT/out.vdb",
         "orphan.txt:1: internode 1 has parent 7, which is not in the file"},
        // (a skeleton file's default junctions, blend, ignored both, exit 0)
        {"bake IN/stem.txt -o OUT/out.vdb --bend 30",
         "stem.txt: --bend needs --junctions pcm or smooth (a skeleton file's default junctions "
         "are blend, which builds none)"},
        {"bake IN/stem.txt -o OUT/out.vdb --primitives convolution",
         "stem.txt: --primitives convolution or mixed needs --junctions pcm or smooth"},
        // growth parameter files and their options
        {"bake IN/growth_dup.json -o OUT/out.vdb", "growth_dup.json: duplicate key 'years'"},
        {"bake " + P + " --time -1 -o OUT/out.vdb", "--time must be between 0 and 27 years"},
        {"bake " + P + " --time 99 -o OUT/out.vdb", "--time must be between 0 and 27 years"},
        {"growth " + P + " --year -3 --print-stats", "--year/--time must be between 0 and 27"},
        {"growth " + P + " --seed -1 --print-stats", "--seed"},
        {"bake " + P + " --junctions pcm -o OUT/out.vdb", "a growth parameter file sets its own"},
        // sequences
        {"bake " + P + " --frames 1-3 -o OUT/seq.vdb",
         "-o OUT/seq.vdb: a sequence needs a run of '#'"},
        {"bake " + P + " --frames 5-1 -o OUT/seq.####.vdb",
         "--frames 5-1: the last frame must not come before"},
        {"bake " + P + " --frames 1-99999999999 -o OUT/seq.####.vdb",
         "--frames 1-99999999999: 99999999999 frames"},
        {"bake " + P + " --frames x -o OUT/seq.####.vdb", "--frames x: expected FRAME"},
        {"bake " + P + " --frames 1-3 --fps-per-year 0 -o OUT/seq.####.vdb",
         "--fps-per-year must be a positive"},
        {"bake " + P + " --frames 1-300 -o OUT/seq.####.vdb", "frame 28 is year 28"},
        // (13.6 TB estimated, and a million frame paths checked: a few s)
        {"bake " + P +
             " --frames 1-1000000 --fps-per-year 100000 --voxel-size 0.005 -o OUT/h.####.vdb",
         "1,000,000 frames of OUT/h.####.vdb (roughly"},
        {"bake " + P +
             " --frames 1-1000000 --fps-per-year 100000 --voxel-size 0.005 -o OUT/h.####.vdb "
             "--dry-run",
         "TB of disk, and OUT has"},
        {"bake " + P + " --frames 1-3 --jobs 0 -o OUT/seq.####.vdb",
         "--jobs: Value 0 not in range"},
        {"bake " + S + " --frames 1-3 -o OUT/seq.####.vdb",
         "--frames needs a growth parameter file"},
        // bake options and outputs
        {"bake " + S + " --voxel-size 0 -o OUT/out.vdb",
         "--voxel-size must be a number from 0.0001"},
        {"bake " + S + " --voxel-size nan -o OUT/out.vdb",
         "--voxel-size must be a number from 0.0001"},
        {"bake " + S + " --voxel-size 1e-4 -o OUT/out.vdb", "a voxel size of 0.0001 for a surface"},
        {"bake " + S + " --half-width 0 -o OUT/out.vdb", "--half-width must be between 1 and 64"},
        {"bake " + S + " --device gpu -o OUT/out.vdb", "--device"},
        {"bake " + S + " --threads 0 -o OUT/out.vdb", "--threads: Value 0 not in range"},
        {"bake " + S + " --junctions knot -o OUT/out.vdb",
         "--junctions must be pcm, smooth or blend"},
        {"bake " + S + " --bend 100 -o OUT/out.vdb", "--bend must be between -90 and 90"},
        {"bake " + S + " --primitives cubes -o OUT/out.vdb",
         "--primitives must be cone, convolution or mixed"},
        {"bake " + S + " -o OUT", "OUT: is a directory, not an output file"},
        {"bake " + S + " -o ''", "--output: an empty value"},
        {"bake " + S + " -o /dev/null", "/dev/null: is a character device"},
        {"bake IN/bad.l -o IN/bad.l", "bad.l: unknown output format '.l' (use .vdb)"},
        {"bake " + S + " -o OUT/x.png", "x.png: unknown output format '.png' (use .vdb)"},
        {"bake " + S + " -o OUT/noext",
         "noext: the name has no extension to tell the output format (use .vdb)"},
        {"info IN/index.obj", "index.obj: a mesh file, not a model"},
        {"bake IN/model.json -o IN/model.vdb", "model.vdb: is the input"},
        {"mesh IN/trunc90.vdb -o IN/alias.ply", "alias.ply: is the input"},
        {"render IN/flipped.vdb -o IN/alias.png", "alias.png: is the input"},
        {"bake IN/grow.json --year 2 --voxel-size 0.3 -o IN/photo.vdb",
         "photo.vdb: is the input IN/bark.png"},
        {"bake IN/grow.json --frames 1-2 --voxel-size 0.3 -o IN/grown.####.vdb",
         "grown.0002.vdb: is the input IN/grow.json"},
        {"bake " + P + " --frames 1-2 --voxel-size 0.3 -o OUT/twin.####.vdb",
         "twin.0002.vdb: is the same file as OUT/twin.0001.vdb (two outputs would write one "
         "file)"},
        {"shape IN/stroked.json -o IN/strokes.obj", "strokes.obj: is the input IN/strokes.json"},
        {"bake IN/near1.json -o OUT/out.vdb", "threshold: must be at most 0.99 (got 0.999999)"},
        // (the float kernels saw no surface: "thinner than a voxel")
        {"bake IN/near0.json -o OUT/out.vdb", "threshold: must be at least 0.001 (got 1e-30)"},
        {"bake IN/afar.json --voxel-size 0.0002 -o OUT/out.vdb",
         "afar.json: the surface reaches 1e+05 from the origin, 5e+08 voxels of 0.0002: beyond "
         "1048576 voxels, where single-precision positions"},
        // (it was "the mesh has no triangles of any area")
        {"shape " + kExamples + "shapes/rock.json --voxel-size 1e9 -o OUT/out.vdb",
         "rock.json: the mesh, 2.03 across, is less than a thousandth of a voxel of 1e+09"},
        {"shape IN/seed.json -o OUT/out.obj", "details[0].seed: must be a whole number (got 1.5)"},
        {"shape IN/span.json -o OUT/out.obj", "amplitude.keys[0][0]: must be between"},
        {"render --mesh IN/hex.obj -o OUT/out.png", "hex.obj:1: 'v' expects 3 numbers"},
        {"shape IN/year0.json -o OUT/out.obj", "at year 0 the tree has not begun to grow"},
        {"bake IN/weighted.json -o OUT/out.vdb --voxel-size 0.0001",
         "weighted.json: a voxel size of 0.0001 for a surface 60.02 across (6e+05 voxels) needs "
         "about"},
        {"shape IN/heavy_base.json -o OUT/out.obj",
         "heavy_base.json: base IN/weighted.json: a voxel size of 0.0001 for a surface 60.02 "
         "across (6e+05 voxels) needs about"},
        {"shape " + kExamples + "shapes/rock.json --frames 0-1 --time 1 -o OUT/r.#.vdb",
         "--time excludes --frames"},
        {"shape IN/tiled.json -o OUT/out.obj",
         "tile.vdb: is tile 1/2 of a frame baked in tiles, a part of its surface"},
        // (meshed or rendered, half the surface with exit 0)
        {"mesh IN/tile.vdb -o OUT/out.obj",
         "tile.vdb: is tile 1/2 of a frame baked in tiles, a part of its surface"},
        {"render IN/tile.vdb -o OUT/out.png",
         "tile.vdb: is tile 1/2 of a frame baked in tiles, a part of its surface"},
        {"bake " + S + " --tile 4096/4096 --voxel-size 0.05 -o OUT/out.vdb",
         "--tile 4096/4096: the frame spans 2 layers of 128 voxels"},
        {"growth " + P + " --seed 18446744073709551616",
         "--seed: Value 18446744073709551616 not in range 0 to 9000000000000000"},
        {"bake " + S + " -o OUT/no/such/dir/out.vdb",
         "out.vdb: cannot write the output: No such file"},
        {"bake " + S, "--output is required"},
        {"bake " + S + " -o OUT/out.vdb --no-such-option", "--no-such-option"},
        // reading .vdb files
        {"mesh IN/trunc100.vdb -o OUT/out.ply", "trunc100.vdb: a truncated .vdb file"},
        {"mesh IN/trunc90.vdb -o OUT/out.ply", "trunc90.vdb: a truncated .vdb file: grid"},
        {"render IN/trunc90.vdb -o OUT/out.png", "trunc90.vdb: a truncated .vdb file"},
        {"mesh IN/flipped.vdb -o OUT/out.ply",
         "flipped.vdb: a damaged .vdb file: its bytes do not match the checksum"},
        {"mesh IN/text.vdb -o OUT/out.ply", "text.vdb: not a .vdb file"},
        {"mesh IN/zeros.vdb -o OUT/out.ply", "zeros.vdb: not a .vdb file"},
        {"mesh IN -o OUT/out.ply", ": is a directory, not a .vdb file"},
        {"mesh IN/missing.vdb -o OUT/out.ply",
         "missing.vdb: cannot read the .vdb file: No such file"},
        {"mesh VDB -o OUT/out.ply --grid nope", "no grid named 'nope'"},
        {"mesh VDB -o OUT/out.ply --adaptivity 2", "--adaptivity must be between 0 and 1"},
        {"mesh VDB -o OUT/out.stl", "out.stl: unknown mesh format '.stl'"},
        {"mesh VDB -o OUT/out.ply --frames 1-3",
         "a sequence needs an input and an output with a run of '#'"},
        // rendering
        {"render VDB -o OUT/out.png --width 0", "--width and --height must be between 1 and 16384"},
        {"render VDB -o OUT/out.png --width 16384 --height 16384",
         "a picture this large needs about"},
        {"render VDB -o OUT/out.png --spp 0", "--spp must be between 1 and 4096"},
        {"render VDB -o OUT/out.png --camera sideways", "--camera sideways: expected auto"},
        // A view narrower than float rays resolve (1e-9 degrees: every ray
        // missed, an empty picture with exit 0).
        {"render VDB -o OUT/out.png --camera look:5,5,5:0,0,0:1e-9",
         "--camera look:5,5,5:0,0,0:1e-9: the field of view must be from 0.0001 to below 180 "
         "degrees (got 1e-09)"},
        // Each fault named (one message named all three)
        {"render VDB -o OUT/out.png --camera look:1,1,1:1,1,1", "the eye is the target"},
        {"render VDB -o OUT/out.png --camera look:0,5,0:0,0,0", "the view is vertical"},
        {"render VDB -o OUT/out.png --camera look:5,5,5:0,0", "look: takes 6 or 7 numbers"},
        {"render VDB -o OUT/out.png --camera look:5,5,0x5:0,0,0", "EZ '0x5' is not a finite"},
        {"render VDB -o OUT/out.png --camera turntable:ten", "the angle 'ten' is not a finite"},
        {"render VDB -o OUT/out.png --camera look:1e300,0,0:0,0,0",
         "EX 1e+300 is beyond the 1e+15"},
        {"preview " + S + " --once --render-device gpu -o OUT/p.png", "--render-device must be"},
        {"render VDB -o OUT/out.png --device gpu", "--device"},
        {"render VDB -o OUT/out.tif", "out.tif: unknown image format '.tif'"},
        {"render -o OUT/out.png", "nothing to render"},
        {"render --mesh IN/index.obj -o OUT/out.png", "index.obj:4: vertex index 9 out of range"},
        {"render --mesh IN/noface.obj -o OUT/out.png", "noface.obj: the mesh has no faces"},
        // (Embree's build aborted the program on it)
        {"render --mesh IN/far.obj -o OUT/out.png",
         "far.obj:2: vertex 2 lies 1e+38 from the origin, beyond the 1e+15 cambium reads"},
        {"render --mesh IN/back.obj -o OUT/out.png",
         "back.obj:4: vertex index -9 out of range (the file has 3 vertices before it)"},
        {"render --mesh IN/index.ply -o OUT/out.png",
         "index.ply: vertex index 7 out of range (the file has 3 vertices) (face 1)"},
        {"render --mesh IN/liar.ply -o OUT/out.png",
         "liar.ply: the file ends inside element 'face' (1 of 2147483648)"},
        {"render --mesh IN/bad.ply -o OUT/out.png",
         "bad.ply:2: PLY format 'binary_big_endian' is not read"},
        {"render --mesh IN/dir.json -o OUT/out.png", "dir.json: unknown mesh format '.json'"},
        // Options for grids mean nothing to a mesh (they were ignored).
        {"render --mesh IN/index.obj --grid density -o OUT/out.png", "--mesh excludes --grid"},
        {"render --mesh IN/index.obj --device opencl -o OUT/out.png", "--mesh excludes --device"},
        // active tiles: a few bytes in the file, terabytes as voxels
        {"mesh IN/tiles.vdb -o OUT/out.ply",
         "tiles.vdb: grid 'surface' has 3.52e+13 active voxels in tiles, which as voxels needs "
         "about 158 TB"},
        {"render IN/tiles.vdb --via-mesh -o OUT/out.png", "not a narrow-band level set"},
        {"render IN/tiles.vdb -o OUT/out.png", "not a narrow-band level set"},
        // (its peer, OpenVDB's volumeToMesh, ran out of memory, exit 1, sweep 20)
        {"bench read --file IN/tiles.vdb --repeat 1", "not a narrow-band level set"},
        {"mesh IN/many_tiles.vdb -o OUT/out.ply",
         "many_tiles.vdb: grid 'surface' has 2.1e+08 active voxels in tiles (one value each"},
        {"render IN/many_tiles.vdb --via-mesh -o OUT/out.png", "2.1e+08 active voxels in tiles"},
        {"shape IN/many_tiles_base.json -o OUT/out.obj", "2.1e+08 active voxels in tiles"},
        {"bench read --file IN/many_tiles.vdb --repeat 1", "2.1e+08 active voxels in tiles"},
        {"shape IN/tiles_base.json -o OUT/out.ply", "not a narrow-band level set"},
        {"mesh IN/empty.vdb -o OUT/out.ply",
         "empty.vdb: the level set has no active voxels: nothing to mesh"},
        {"render IN/empty.vdb -o OUT/out.png", "empty.vdb: the level set has no active voxels"},
        {"mesh IN/twice.vdb -o OUT/out.ply",
         "twice.vdb: more than one grid is named 'surface': which one is meant?"},
        {"render IN/twocd.vdb -o OUT/out.png",
         "twocd.vdb: more than one grid is named 'Cd': which one is meant?"},
        {"mesh IN/nan.vdb -o OUT/out.ply",
         "nan.vdb: grid 'surface' has a voxel at (3, 4, 5) whose value is not a number"},
        {"render IN/nan.vdb -o OUT/out.png", "nan.vdb: grid 'surface' has a voxel at (3, 4, 5)"},
        {"mesh IN/flat.vdb -o OUT/out.ply",
         "flat.vdb: grid 'surface' has voxels of 0.1 x 0.1 x 0.05: a level set's are cubes"},
        {"mesh IN/huge.vdb -o OUT/out.ply",
         "huge.vdb: grid 'surface' has voxels of 1e+300 x 1e+300 x 1e+300 (the transform's "
         "determinant inf): not a usable level set"},
        {"render IN/mirror.vdb -o OUT/out.png",
         "mirror.vdb: grid 'surface' has voxels of 0.1 x 0.1 x 0.1 (the transform's determinant "
         "-0.001)"},
        {"mesh IN/relabelled.vdb -o OUT/out.ply",
         "relabelled.vdb: grid 'surface' has the tree type Tree_vec3s_5_4_3, not a float level "
         "set's Tree_float_5_4_3"},
        {"mesh IN/fog.vdb -o OUT/out.ply",
         "fog.vdb: grid 'surface' has the background 0, not a level set's positive half-width"},
        // photos that lie
        // A photo for a model of no bark colour (it was ignored, exit 0)
        {"bake " + S + " --bark-photo IN/bark.png -o OUT/out.vdb",
         "bark.png: the bark photo would paint nothing: no cone or segment of "},
        {"bake " + P + " --year 3 --voxel-size 0.02 --bark-photo IN/cut.png -o OUT/out.vdb",
         "cut.png: a truncated or damaged PNG: its chunk IDAT at byte"},
        {"bake " + P + " --year 3 --voxel-size 0.02 --bark-photo IN/zlib.png -o OUT/out.vdb",
         "zlib.png: cannot read the png image: PNG read error: IDAT: incorrect data check"},
        {"bake 'IN/a\x1b[31mred\nx.json' -o OUT/out.vdb",
         "a\\x1b[31mred\\x0ax.json: cannot read the scene file"},
        // (a volume's slices were all written into one slice's room: a crash)
        {"bake " + P + " --year 3 --voxel-size 0.02 --bark-photo VDB -o OUT/out.vdb",
         ": not a PNG, JPEG, TIFF, OpenEXR, Radiance HDR, BMP or WebP image (its first bytes "
         "are 20 42 44 56 00 00 00 00)"},
        // (OpenImageIO's null reader invented a picture for the name)
        {"bake " + P + " --year 3 --voxel-size 0.02 --bark-photo IN/empty.null -o OUT/out.vdb",
         "empty.null: not a PNG, JPEG, TIFF, OpenEXR, Radiance HDR, BMP or WebP image (its first "
         "bytes are none: it is empty)"},
        {"bake " + P + " --year 3 --voxel-size 0.02 --bark-photo IN/liar.png -o OUT/out.vdb",
         "liar.png: its header says 11000 x 11000 pixels, more than the 50 million pixels read"},
        // shapes
        {"shape IN/far_edits.json -o OUT/out.ply",
         "details and edits edits[0] (radius 100, gain 100), edits[1] (radius 100, gain 100)"},
        {"shape IN/far_edits.json -o OUT/out.vdb", "and 17 more push it beyond any size"},
        // (frame 1 fits; its voxel size makes frame 2's tentacles, 500 long,
        // too many voxels: refused before frame 1 is written)
        {"shape IN/growing.json --frames 1-3 -o OUT/g.####.vdb",
         "growing.json: the band at voxel size 0.0039"},
        {"shape IN/growing.json --frames 1-3 -o OUT/g.####.vdb",
         "use a larger voxel size (frame 2)"},
        // farms and the preview server
        {"bake " + P + " --frames 1-2 --slurm --dry-run --slurm-arg=--array=0-99 -o OUT/s.####.vdb",
         "--slurm-arg '--array=0-99': --array is set by cambium's job scripts"},
        // (sbatch takes an unambiguous prefix of a long option: --arr is --array)
        {"bake " + P + " --frames 1-2 --slurm --dry-run --slurm-arg=--arr=0-9 -o OUT/s.####.vdb",
         "--slurm-arg '--arr=0-9': --array is set by cambium's job scripts"},
        {"bake " + P + " --frames 1-2 --slurm --dry-run --slurm-arg=partition=x -o OUT/s.####.vdb",
         "--slurm-arg 'partition=x': one sbatch option, as -x"},
        {"bake " + S + " --year 5 -o OUT/out.vdb",
         "a time (--year, --time, a shape base's \"year\") is for growth parameter files"},
        {"bake " + S + " --resume -o OUT/out.vdb", "--resume requires --frames"},
        {"bake IN/seed.json -o OUT/out.vdb",
         "seed.json: a shape file (docs/shape-format.md), not a model: `cambium shape`"},
        {"info IN/zero.vdb", "zero.vdb: not a .vdb file"},
        {"mesh IN/part.#.vdb --frames 1-2 -o OUT/part.#.obj", "part.2.vdb: a truncated .vdb file"},
        {"render IN/part.#.vdb --frames 1-2 -o OUT/part.#.png",
         "part.2.vdb: a truncated .vdb file"},
        {"render --mesh IN/mseq.#.obj --frames 1-2 -o OUT/mseq.#.png",
         "mseq.2.obj:2: vertex 2 has a value nan"},
        {"mesh IN/good.#.vdb --frames 1-2 -o OUT/dir.#.obj", "dir.2.obj: is a directory"},
        {"render IN/good.#.vdb --frames 1-2 -o OUT/rdir.#.png", "rdir.2.png: is a directory"},
        {"mesh IN/flip.#.vdb --frames 1-2 -o OUT/flip.#.obj",
         "flip.2.vdb: a damaged .vdb file: its bytes do not match the checksum"},
        {"render IN/flip.#.vdb --frames 1-2 -o OUT/flip.#.png",
         "flip.2.vdb: a damaged .vdb file: its bytes do not match the checksum"},
        // Empty values (they were taken as no option: one frame baked, the
        // whole frame for --tile '', the default junctions)
        {"bake " + S + " --frames '' --resume -o OUT/out.vdb", "--frames: an empty value"},
        {"bake " + S + " --tile '' -o OUT/out.vdb", "--tile: an empty value"},
        {"bake " + S + " --junctions '' -o OUT/out.vdb", "--junctions: an empty value"},
        {"render VDB --frames '' -o OUT/out.png", "--frames: an empty value"},
        // The benchmarks' cases and sizes (a voxel size of 0 aborted)
        {"bench bake --case 1000:0 --skip-cpu --repeat 1",
         "--case 1000:0: the voxel size must be a number from 0.0001 to 1e9 (got 0)"},
        {"bench bake --case 1e3:0.01",
         "a whole number from 1 to 1000000 and a decimal number"},  // (no IN: substituted)
        {"bench render --width 0 --internodes 10", "--width: Value 0 not in range"},
        {"bench mesh --voxel-size 0", "--voxel-size: Value 0 not in range"},
        // (refused after the year table was printed)
        {"bench growth --fps-per-year 1e9",
         "--fps-per-year must be a positive number of at most 1e6 (got 1000000000)"},
        // ... and their memory, before any work (they ran into the limit)
        {"bench bake --case 20000:0.0001 --skip-cpu --repeat 1",
         "tree of 20000 internodes: a voxel size of 0.0001"},
        {"bench render --internodes 10 --width 16384 --height 16384",
         "--width 16384 --height 16384: a picture this large needs about"},
        {"bench growth --years 27 --voxel-size 0.0001 --device cpu",
         "year 27: a voxel size of 0.0001"},
        // (found by the preview it ran, after the table's header: exit 1)
        {"bench preview --years 1 --width -5",
         "--width and --height: from 1 to 16384 (got -5 x 480)"},
        {"bench preview --years 0", "--years: 0 is not a year of the tree of"},
        {"bench growth --years 28", "--years: 28 is not a year of the tree of"},
        {"shape IN/flat.json --voxel-size 0.05 -o OUT/out.vdb",
         "flat.json: the closed mesh encloses no volume"},
        {"bake " + P + " --frames 1-2 --fps-per-year 1e7 -o OUT/seq.####.vdb",
         "--fps-per-year must be a positive number of at most 1e6 (got 10000000)"},
        {"bake " + P + " --frames 1-2 --slurm --dry-run --slurm-arg '--x\nid' -o OUT/s.####.vdb",
         "--slurm-arg '--x\\x0aid': a control character (code 10) in an sbatch option"},
        {"preview " + S + " --port 99999 -o OUT/p.png",
         "--port must be from 1 to 65535, or 0 for a free one (got 99999)"},
        {"preview " + S + " --port -1 -o OUT/p.png", "--port must be from 1 to 65535"},
        // (what --once would not use: the page's port, its background years)
        {"preview " + S + " --once --port 8000 -o OUT/p.png", "--port excludes --once"},
        {"preview " + S + " --once --frames 1-3 -o OUT/p.png", "--frames excludes --once"},
        // the command line itself
        {"", "A subcommand is required"},
        {"bogus", "unknown command 'bogus' (the commands: info, eval, bake"},
        {"bench", "A subcommand is required"},
        // (CLI11's own message came as two lines, without cambium's prefix)
        {"bake IN/dup.json --voxel-size x -o OUT/out.vdb",
         "cambium: error: Could not convert: --voxel-size = x (cambium bake --help lists the "
         "options)\n"},
    };
    ASSERT_GE(cases.size(), 60u);
    for (const BadInput& c : cases) {
        const std::vector<std::pair<std::string, std::string>> vars = {
            {"IN", in.string()}, {"OUT", out.string()}, {"VDB", vdb}};
        const std::string args = substitute(c.args, vars);
        const Result r = run(args);
        EXPECT_EQ(r.status, 2) << args << "\n" << r.err;
        EXPECT_NE(r.err.find(substitute(c.expected, vars)), std::string::npos) << args << "\n"
                                                                               << r.err;
        EXPECT_LT(r.err.size(), 600u) << args << ": one short message";
        // One error line; the only other lines are progress notes of long
        // plans (nothing a library prints on its own).
        std::istringstream lines(r.err);
        int errors = 0;
        for (std::string line; std::getline(lines, line);) {
            errors += line.rfind("cambium: error: ", 0) == 0;
            EXPECT_TRUE(line.rfind("cambium: error: ", 0) == 0 ||
                        line.rfind("cambium: planning ", 0) == 0 ||
                        line.rfind("cambium: working: ", 0) == 0)
                << args << ": a line not cambium's: " << line;
        }
        EXPECT_EQ(errors, 1) << args << "\n" << r.err;
        EXPECT_EQ(r.out, "") << args << ": refused before any work";
        EXPECT_EQ(snapshot(out), before) << args;
    }
    EXPECT_EQ(snapshot(in), inputsBefore);
}

}  // namespace

namespace {

/// A .vdb's bytes without its header's UUID (36 characters after the magic
/// number, three version numbers and the grid-offsets flag: bytes 21-56),
/// which OpenVDB makes anew for every file.
std::string withoutUuid(const fs::path& p)
{
    std::string s = fileContents(p);
    EXPECT_GT(s.size(), 57u);
    return s.size() > 57 ? s.erase(21, 36) : s;
}

TEST(Determinism, TwoBakesAndTwoSequencesGiveTheSameFilesApartFromTheUuid)
{
    const fs::path dir = freshDir("cambium_determinism");
    for (const char* name : {"a.vdb", "b.vdb"})
        ASSERT_EQ(run("bake " + kExamples + "branch_junction.json --voxel-size 0.02 -o " +
                      (dir / name).string())
                      .status,
                  0);
    EXPECT_EQ(withoutUuid(dir / "a.vdb"), withoutUuid(dir / "b.vdb"));
    EXPECT_NE(fileContents(dir / "a.vdb"),
              fileContents(dir / "b.vdb"));  // the UUIDs differ: the test sees them
    for (const char* jobs : {"1", "2"})
        ASSERT_EQ(run("bake " + kPopulus + " --frames 3-5 --voxel-size 0.04 --jobs " + jobs +
                      " -o " + (dir / (std::string("j") + jobs + ".####.vdb")).string())
                      .status,
                  0);
    for (const char* frame : {"0003", "0004", "0005"})
        EXPECT_EQ(withoutUuid(dir / (std::string("j1.") + frame + ".vdb")),
                  withoutUuid(dir / (std::string("j2.") + frame + ".vdb")))
            << frame;
}

}  // namespace

TEST(BadInput, TooLittleAddressSpaceToStartIsOutOfMemoryNotAnAbort)
{
    // log4cplus, which OpenVDB loads, starts a thread in its initializer,
    // before main: under 124-155 MB of address space every command, even
    // --version, ended in "terminate called" (SIGABRT, sweep 27).  From the
    // limit at which the libraries cannot even be mapped (the loader's exit
    // 127) up to one at which it runs, every limit ends in exit 1 naming
    // the memory, or runs.
    if (test::addressSanitized())
        GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit";
    int refused = 0;
    for (long long mb = 96; mb <= 320; mb += 8) {
        const Result r = run("--version", -1, mb << 20);
        if (r.status == 127 || r.status == 0)
            continue;
        EXPECT_EQ(r.status, 1) << mb << " MB\n" << r.err;
        EXPECT_NE(r.err.find("cambium: failed: out of memory: the address space this process "
                             "may use (ulimit -v) is "),
                  std::string::npos)
            << mb << " MB\n"
            << r.err;
        ++refused;
    }
    EXPECT_GT(refused, 0) << "no limit between 96 and 320 MB was refused";
    EXPECT_EQ(run("--version", -1, 320LL << 20).status, 0);
}

TEST(BadInput, ARowOfSamplesLargerThanMemoryIsRefusedBeforeTheRender)
{
    // Each thread holds a row's samples at once: 16384 pixels at 4096
    // samples are some 17 GB a thread (it ran out of memory after seconds,
    // exit 1, sweep 20).  Refused under 3 GB of address space, every device.
    if (test::addressSanitized())
        GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit";
    const auto dir = test::freshDir("render_row_samples");
    const std::string out = (dir / "wide.png").string();
    for (const char* how : {"", " --device opencl", " --via-mesh"}) {
        const Result r = run(
            "render " + fixtureVdb() + " --width 16384 --height 1 --spp 4096" + how + " -o " + out,
            -1, 3000LL << 20);
        EXPECT_EQ(r.status, 2) << how << "\n" << r.err;
        EXPECT_NE(r.err.find("--width 16384 at --spp 4096: the rows' 67,108,864 samples that"),
                  std::string::npos)
            << r.err;
        EXPECT_FALSE(std::filesystem::exists(out));
    }
}

/// A cambium file of n^3 leaves, `spacing` voxels apart on a grid from the
/// origin, each crossed by a plane: a level set whose leaves cost what their
/// values and internal nodes cost, in a small file.
void writeLeafPlanes(const std::string& path, int n, int spacing, double voxel)
{
    LevelSetGrids g;
    g.surface = openvdb::FloatGrid::create(float(3.0 * voxel));
    g.surface->setName(kSurfaceGrid);
    g.surface->setTransform(openvdb::math::Transform::createLinearTransform(voxel));
    g.surface->setGridClass(openvdb::GRID_LEVEL_SET);
    auto acc = g.surface->getAccessor();
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j)
            for (int k = 0; k < n; ++k) {
                auto* leaf = acc.touchLeaf(openvdb::Coord(i * spacing, j * spacing, k * spacing));
                for (auto it = leaf->beginValueAll(); it; ++it) {
                    it.setValue(float(voxel) * (float(it.getCoord().z() & 7) - 3.5f));
                    it.setValueOn();
                }
            }
    writeVdb(g, path, VdbFileInfo());
}

TEST(BadInput, LeavesWhoseValuesWouldNotFitAreRefusedBeforeTheyAreDecoded)
{
    // 64,000 leaves (125 MB of values, a 16 MB file: a plane through each)
    // meshed under 330 MB of address space: the topology fits, the values do
    // not.  Decoding them ran out of memory, where Blosc's own allocation
    // failed and it carried on and crashed in LZ4 (SIGSEGV here at 300-360
    // MB; sweep 24: a needle's 437,508 leaves, one run in three); now the
    // read is refused once the topology is known, nothing written.
    if (test::addressSanitized())
        GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit";
    const auto dir = test::freshDir("leaves_that_do_not_fit");
    const std::string in = (dir / "planes.vdb").string(), out = (dir / "planes.ply").string();
    writeLeafPlanes(in, 40, 8, 0.1);
    const Result r = run("mesh " + in + " -o " + out, -1, 330LL << 20);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find(in + ": reading grid 'surface' (64,000 leaves) needs about "),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));
    // bench read's peers read it whole and mesh it: checked before they run
    // (the plain OpenVDB peer ran out of memory where cambium's read fitted,
    // and crashed in Blosc, sweep 25).
    const Result b = run("bench read --file " + in + " --repeat 1", -1, 700LL << 20);
    EXPECT_EQ(b.status, 2) << b.err;
    EXPECT_NE(b.err.find(in + ": reading it whole and meshing it needs about "), std::string::npos)
        << b.err;
}

TEST(BadInput, AShapesBaseOfSparseLeavesIsRefusedBeforeItIsResampled)
{
    // 4,096 leaves, each alone in its internal node of 128^3 voxels (32 KB):
    // OpenVDB resamples a level set by meshing it, whose trees of those
    // nodes ran out of memory and aborted (sweep 24: 40,000 such leaves,
    // "terminate called" under 3 GB); refused, under 600 MB of address space, by its meshing
    // estimate before the resampling.
    if (test::addressSanitized())
        GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit";
    const auto dir = test::freshDir("sparse_shape_base");
    writeLeafPlanes((dir / "sparse.vdb").string(), 16, 128, 0.01);
    writeText(dir / "shape.json",
              R"({"base": {"type": "vdb", "file": "sparse.vdb"}, "levels": 1})");
    const std::string out = (dir / "out.vdb").string();
    const Result r = run("shape " + (dir / "shape.json").string() + " -o " + out, -1, 600LL << 20);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("sparse.vdb (its surface, to resample it to voxels of"), std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("(4,096 leaves, 2,097,152 active voxels) needs about"), std::string::npos)
        << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));
}

TEST(BadInput, ABandLargerThanItsEstimateIsRefusedOnceItsTopologyIsKnown)
{
    // Two coincident spheres of radius 0.01 and support 30 sum to a surface
    // 14 out: the primitives' areas estimated 3,770 voxels, and the bake
    // made 463 M (3.7 GB; at 0.0015 past a minute).  Their topology search
    // finds the band's 2.9 M leaves in 2 s: refused then, under 2.5 GB of
    // address space, with nothing written.
    if (test::addressSanitized())
        GTEST_SKIP() << "AddressSanitizer reserves more address space than the limit";
    const auto dir = test::freshDir("band_from_topology");
    const std::string in = (dir / "two.json").string(), out = (dir / "two.vdb").string();
    writeText(dir / "two.json",
              R"({"root": {"type": "blend", "children": [)"
              R"({"type": "sphere", "center": [0, 0, 0], "radius": 0.01, "support": 30},)"
              R"({"type": "sphere", "center": [0, 0, 0], "radius": 0.01, "support": 30}]}})");
    const Result r =
        run("bake " + in + " --voxel-size 0.002 --device cpu -o " + out, -1, 2500LL << 20);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("two.json: sampling the band's 2,942,719 leaves (its topology search "
                         "found them) needs about"),
              std::string::npos)
        << r.err;
    EXPECT_FALSE(std::filesystem::exists(out));
}
