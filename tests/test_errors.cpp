// Nothing is lost: for every command and output kind, a write that fails
// fails (exit 1, the reason named) and leaves the old file and no temporary;
// outputs that are not regular files are refused before any work; a signal
// removes the temporary; one run at a time writes a sequence; --resume
// cleans stale temporaries and bakes damaged frames again.
#include "bake/vdb_io.h"
#include "cli_util.h"
#include "core/files.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
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

fs::path freshDir(const std::string& name)
{
    const fs::path dir = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

/// Every file of a directory with its contents: what "nothing changed" compares.
std::map<std::string, std::string> snapshot(const fs::path& dir)
{
    std::map<std::string, std::string> files;
    for (const auto& e : fs::directory_iterator(dir))
        files[e.path().filename().string()] = e.is_regular_file() ? fileContents(e.path()) : "(not a regular file)";
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
        {"out.0002.vdb", "bake " + kPopulus + " --frames 2 --voxel-size 0.05 --device cpu -o DIR/out.####.vdb"},
        {"out.obj", "mesh " + vdb + " -o OUT"},
        {"out.ply", "mesh " + vdb + " -o OUT"},
        {"out.png", "render " + vdb + " --width 48 --height 32 --device cpu -o OUT"},
        {"out.exr", "render " + vdb + " --width 48 --height 32 --device cpu -o OUT"},
    };
}

std::string expand(std::string args, const fs::path& dir, const std::string& name)
{
    for (auto [key, value] : {std::pair<std::string, std::string>{"OUT", (dir / name).string()},
                              std::pair<std::string, std::string>{"DIR", dir.string()}})
        for (size_t at; (at = args.find(key)) != std::string::npos;)
            args.replace(at, key.size(), value);
    return args;
}

TEST(NothingIsLost, AFailedWriteFailsAndKeepsTheOldFileForEveryOutputKind)
{
    // The injected failure: a file size limit of 0 (SIGXFSZ ignored), so
    // every write(2) of the output fails with EFBIG.
    for (const OutputKind& k : outputKinds()) {
        const fs::path dir = freshDir("cambium_errors_efbig");
        const std::string args = expand(k.args, dir, k.name);
        const Result good = run(args);
        ASSERT_EQ(good.status, 0) << args << "\n" << good.err;
        const auto before = snapshot(dir);
        ASSERT_EQ(before.size(), 1u) << args;
        const Result bad = run(args, 0);
        EXPECT_EQ(bad.status, 1) << args << "\n" << bad.err;
        EXPECT_NE(bad.err.find((dir / k.name).string() + ": cannot write the output: File too large"),
                  std::string::npos)
            << bad.err;
        EXPECT_EQ(snapshot(dir), before) << args;  // the old file whole, no temporary
        fs::remove_all(dir);
    }
}

TEST(NothingIsLost, AFullFilesystemFailsTheBakeTheSequenceAndTheRender)
{
    const fs::path dir = freshDir("cambium_errors_full");
    if (::geteuid() != 0 || std::system(("mount -t tmpfs -o size=256k tmpfs " + dir.string() + " 2>/dev/null").c_str()))
        GTEST_SKIP() << "cannot mount a tmpfs here (not root, or no permission)";
    std::ofstream(dir / "keep.vdb") << "a good file";
    const auto before = snapshot(dir);
    for (const std::string& args :
         {"bake " + kScene + " --voxel-size 0.02 --device cpu -o " + (dir / "keep.vdb").string(),
          "render " + fixtureVdb() + " --width 512 --height 512 --device cpu -o " + (dir / "keep.exr").string()}) {
        const Result r = run(args);
        EXPECT_EQ(r.status, 1) << args << "\n" << r.out << r.err;
        EXPECT_NE(r.err.find("No space left on device"), std::string::npos) << r.err;
        EXPECT_EQ(snapshot(dir), before) << args;
    }
    // A sequence stops at the first frame that does not fit; every frame
    // that is there is whole.
    const Result r = run("bake " + kPopulus + " --frames 8-27:4 --voxel-size 0.01 --jobs 1 --device cpu -o " +
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

TEST(NothingIsLost, OutputsThatAreNotRegularFilesAreRefusedBeforeWork)
{
    const fs::path dir = freshDir("cambium_errors_kinds");
    ASSERT_EQ(::mkfifo((dir / "fifo.vdb").c_str(), 0644), 0);
    ASSERT_EQ(::mkfifo((dir / "seq.0002.vdb").c_str(), 0644), 0);
    fs::create_directories(dir / "d.ply");
    const std::string vdb = fixtureVdb();
    const std::pair<std::string, std::string> cases[] = {
        {"bake " + kScene + " -o /dev/full", "/dev/full: is a character device, not a regular file"},
        {"bake " + kScene + " -o /dev/null", "/dev/null: is a character device"},
        {"bake " + kScene + " -o " + (dir / "fifo.vdb").string(), "fifo.vdb: is a FIFO"},
        {"bake " + kPopulus + " --frames 1-3 -o " + (dir / "seq.####.vdb").string(), "seq.0002.vdb: is a FIFO"},
        {"mesh " + vdb + " -o " + (dir / "d.ply").string(), "d.ply: is a directory"},
        {"bake " + kScene + " -o " + dir.string(), ": is a directory"},
        {"bake " + kScene + " -o ''", "-o: the output path is empty"},
        {"mesh " + vdb + " -o ''", "unknown mesh format"},
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

TEST(NothingIsLost, ASignalDuringTheWriteRemovesTheTemporary)
{
    const fs::path dir = freshDir("cambium_errors_signal");
    const std::string out = (dir / "tree.vdb").string();
    const std::string cmd = std::string(CAMBIUM_EXE) + " bake " + kPopulus + " --voxel-size 0.01 --device cpu -o " +
                            out + " >/dev/null 2>&1 & echo $!";
    FILE* p = ::popen(cmd.c_str(), "r");
    long pid = 0;
    ASSERT_EQ(std::fscanf(p, "%ld", &pid), 1);
    ::pclose(p);
    // Wait for the temporary to appear, then stop the process there.
    const std::string tmp = out + ".tmp-" + std::to_string(pid);
    bool seen = false;
    for (int i = 0; i < 60000 && !seen; ++i) {
        seen = fs::exists(tmp);
        if (!seen)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    ASSERT_TRUE(seen) << "the bake never wrote " << tmp;
    ::kill(pid_t(pid), SIGTERM);
    for (int i = 0; i < 2000 && ::kill(pid_t(pid), 0) == 0; ++i)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_TRUE(snapshot(dir).empty()) << "left: " << snapshot(dir).begin()->first;
}

TEST(NothingIsLost, OneSequenceAtATimePerPattern)
{
    const fs::path dir = freshDir("cambium_errors_lock");
    const std::string pattern = (dir / "tree.####.vdb").string();
    const OutputLock held(pattern);  // as another run would hold it
    const Result r = run("bake " + kPopulus + " --frames 1-2 --voxel-size 0.05 --device cpu -o " + pattern);
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("another cambium (pid " + std::to_string(::getpid()) + ")"), std::string::npos) << r.err;
    EXPECT_EQ(snapshot(dir).size(), 1u);  // the lock file only: no frame written
}

TEST(NothingIsLost, ResumeRemovesStaleTemporariesAndBakesDamagedFramesAgain)
{
    const fs::path dir = freshDir("cambium_errors_resume");
    const std::string pattern = (dir / "tree.####.vdb").string();
    const std::string bake = "bake " + kPopulus + " --frames 2-4 --voxel-size 0.05 --device cpu -o " + pattern;
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
    EXPECT_NE(r.out.find("removed " + (dir / "tree.0003.vdb.tmp-999999").string()), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("tree.0004.vdb: a truncated .vdb file"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir / "tree.0003.vdb.tmp-999999"));
    EXPECT_TRUE(fs::exists(dir / "bush.0003.vdb.tmp-999999"));
    EXPECT_EQ(fileContents(dir / "tree.0002.vdb"), second);  // kept, not rewritten
    EXPECT_EQ(fs::file_size(third), whole.size());            // baked again, whole
    EXPECT_NO_THROW(inspectVdb(third));
}

}  // namespace
