// The cambium binary end to end: `info` on the bundled examples, clear errors
// and a non-zero exit for malformed scenes.
#include "cli_util.h"
#include "temp_dir.h"

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>
#include <sys/wait.h>

namespace {

using cambium::test::Result;
using cambium::test::run;

const std::string kExamples = CAMBIUM_SOURCE_DIR "/examples/";

/// A command line (after the sub-command) and the message it must fail with.
struct Refusal {
    std::string args, expected;
};

/// Each case exits with status 2 and its message.
void expectRefused(const std::string& command, const std::vector<Refusal>& cases)
{
    for (const Refusal& c : cases) {
        const Result e = run(command + " " + c.args);
        EXPECT_EQ(e.status, 2) << c.args;
        EXPECT_NE(e.err.find(c.expected), std::string::npos) << e.err;
    }
}

/// A directory of its own for a test, and a small baked .vdb in it.
std::filesystem::path bakedDir(const std::string& name, std::string& vdb)
{
    const auto dir =
        std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    vdb = (dir / "s.vdb").string();
    const Result r =
        run("bake " + kExamples + "sphere_and_cone.json -o " + vdb + " --voxel-size 0.05");
    EXPECT_EQ(r.status, 0) << r.err;
    return dir;
}

TEST(Cli, InfoPrintsCountsDepthAndBounds)
{
    const Result r = run("info " + kExamples + "branch_junction.json");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("nodes      11: 7 primitives, 3 operators, 1 warp"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("cone                   5"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("pcm                    1"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("depth      4"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("bounds     min"), std::string::npos) << r.out;
    EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST(Cli, MalformedScenesFailWithAClearMessage)
{
    const auto path = std::filesystem::temp_directory_path() /
                      ("cambium_cli_bad_" + std::to_string(::getpid()) + ".json");
    const std::pair<const char*, const char*> cases[] = {
        {R"({"root": {"type": "blend", "children": [{"type": "sphere", "center": [0,0,0], "radius": 1},
             {"type": "cone", "p0": [0,0,0], "p1": [0,2,0], "r0": -0.3, "r1": 0.1}]}})",
         ": root.children[1].r0: must be greater than 0 (got -0.3)"},
        {R"({"root": {"type": "cone", "p0": [0,0,0], "r0": 0.3, "r1": 0.1}})",
         ": root.p1: missing"},
        {R"({"root": {"type": "spher", "center": [0,0,0], "radius": 1}})",
         ": root.type: unknown node type 'spher' (did you mean 'sphere'?)"},
        {"{\"root\": {\"type\": \"sphere\",\n \"center\": [0, NaN, 0], \"radius\": 1}}",
         ": JSON syntax error: parse error at line 2, column"},
        {R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 1e999}})",
         ": JSON syntax error: number overflow parsing '1e999'"},
    };
    for (const auto& [text, expected] : cases) {
        {
            std::ofstream f(path);
            f << text;
        }
        const Result r = run("info " + path.string());
        EXPECT_EQ(r.status, 2) << expected;
        EXPECT_TRUE(r.out.empty()) << r.out;
        EXPECT_NE(r.err.find("cambium: error: " + path.string() + expected), std::string::npos)
            << r.err;
    }
    std::filesystem::remove(path);
}

TEST(Cli, MissingSceneFails)
{
    const Result r = run("info /nonexistent/scene.json");
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(r.err.find("/nonexistent/scene.json: cannot read the model or .vdb file"),
              std::string::npos)
        << r.err;
}

TEST(Cli, EvalPrintsTheFieldAtAPoint)
{
    // On the sphere of radius 1 of the issue's example, far from the cone.
    const Result r = run("eval " + kExamples + "sphere_and_cone.json -- 0 -1 0");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("field     0.5 "), std::string::npos) << r.out;
}

TEST(Cli, VersionListsTheLibrariesAndAnOpenCLDevice)
{
    const Result r = run("version");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("OpenVDB      10."), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("Embree       3."), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("OpenCL"), std::string::npos) << r.out;
}

TEST(Cli, BakeWritesALevelSetAndSaysWhatItDid)
{
    const auto out = std::filesystem::temp_directory_path() /
                     ("cambium_cli_bake_" + std::to_string(::getpid()) + ".vdb");
    std::filesystem::remove(out);
    const Result r =
        run("bake " + kExamples + "sphere_and_cone.json -o " + out.string() + " --voxel-size 0.05");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(std::filesystem::exists(out));
    EXPECT_NE(r.out.find("active voxels"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("peak memory"), std::string::npos) << r.out;
    // Without --voxel-size the summary states the automatic choice.
    const Result a =
        run("bake " + kExamples + "sphere_and_cone.json -o " + out.string() + " --device cpu");
    ASSERT_EQ(a.status, 0) << a.err;
    EXPECT_NE(a.out.find("(auto: 512 voxels across"), std::string::npos) << a.out;
    std::filesystem::remove(out);
}

TEST(Cli, DryRunPrintsThePlanOfAnyBakeAndWritesNothing)
{
    const auto dir =
        std::filesystem::temp_directory_path() / ("cambium_cli_dry_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    const std::string populus = kExamples + "populus/populus.json";
    const std::string out = (dir / "one.vdb").string();
    // One bake: its voxel size is the one the bake then uses (year 6: the
    // same at any year, and its bake 0.3 s to year 27's 4 s).
    Result r = run("bake " + populus + " --year 6 -o " + out + " --dry-run");
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* line : {"plan: bake ", "voxel size ", "band: about ", "time: roughly ",
                             "memory: about ", "disk: at least about ", "nothing baked"})
        EXPECT_NE(r.out.find(line), std::string::npos) << line << "\n" << r.out;
    std::smatch m;
    ASSERT_TRUE(std::regex_search(r.out, m, std::regex("voxel size ([0-9.e-]+)"))) << r.out;
    const std::string planned = m[1];
    // A sequence (a million frames' plan is a second, not minutes) and tiles.
    r = run("bake " + populus + " --frames 1-100000 --fps-per-year 50000 --voxel-size 0.05 -o " +
            (dir / "s.####.vdb").string() + " --dry-run");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("plan: bake 100,000 frames"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("s.0001.vdb to "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("s.100000.vdb"), std::string::npos) << r.out;  // (widened)
    r = run("bake " + populus + " --tiles 3 -o " + out + " --dry-run");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("as 3 tiles"), std::string::npos) << r.out;
    // A frame within --max-memory is one bake, as its run then says (the
    // plan said "as 1 tiles, merged").
    r = run("bake " + populus + " --year 6 --max-memory 1T -o " + out + " --dry-run");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("as one bake (the frame's estimate is within --max-memory)"),
              std::string::npos)
        << r.out;
    EXPECT_TRUE(std::filesystem::is_empty(dir));
    // Then the bake: the planned voxel size.
    r = run("bake " + populus + " --year 6 -o " + out + " --device cpu");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("voxel size " + planned + " "), std::string::npos) << r.out;
    std::filesystem::remove_all(dir);
}

TEST(Cli, InfoDescribesAVdbFileAndChecksIt)
{
    // `cambium info FILE.vdb`: each grid with its type, class, active voxels,
    // leaves, bounds, memory and cambium's metadata, read from the file's
    // metadata alone; --check reads every byte against the checksum and
    // names a changed file (exit 2).  A single bake of a grown tree records
    // its year as cambium_time.
    std::string vdb;
    const auto dir = bakedDir("cambium_cli_info", vdb);
    const Result r = run("info " + vdb);
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* text :
         {"grid       surface: float level set, ", "grid       Cd: vec3s", " active voxels in ",
          " leaves", "  index    (", "  world    (", "in core; ",
          "in the file (blosc + active values)", "cambium_half_width     3",
          "cambium_voxel_size     0.05", "checksum   present, not verified"})
        EXPECT_NE(r.out.find(text), std::string::npos) << text << "\n" << r.out;
    const Result c = run("info " + vdb + " --check");
    ASSERT_EQ(c.status, 0) << c.err;
    EXPECT_NE(c.out.find("checksum   holds"), std::string::npos) << c.out;
    {
        std::fstream f(vdb, std::ios::in | std::ios::out | std::ios::binary);
        f.seekp(-20, std::ios::end);
        f.put('\x5a');
    }
    const Result bad = run("info " + vdb + " --check");
    EXPECT_EQ(bad.status, 2);
    EXPECT_NE(bad.err.find("do not match the checksum"), std::string::npos) << bad.err;
    EXPECT_EQ(bad.out, "") << "refused: nothing printed before the error";
    // Any name: the magic number says it is a .vdb.
    const std::string other = (dir / "frame.data").string();
    std::filesystem::copy_file(vdb, other);
    EXPECT_EQ(run("info " + other).status, 0);
    EXPECT_EQ(run("info " + kExamples + "sphere_and_cone.json --check").status, 2);
    const std::string grown = (dir / "grown.vdb").string();
    ASSERT_EQ(
        run("bake " + kExamples + "populus/populus.json --year 3 --voxel-size 0.02 -o " + grown)
            .status,
        0);
    EXPECT_NE(run("info " + grown).out.find("cambium_time           3\n"), std::string::npos);
    // Its checksum's key renamed (one byte, as an editor would): not "none
    // (not written by cambium)" beside cambium's other metadata.
    {
        std::string bytes = cambium::test::fileContents(grown);
        const size_t key = bytes.find("cambium_checksum");
        ASSERT_NE(key, std::string::npos);
        bytes[key + 15] = 'X';
        std::ofstream(grown, std::ios::binary) << bytes;
    }
    const Result renamed = run("info " + grown);
    EXPECT_EQ(renamed.status, 0) << renamed.err;
    EXPECT_NE(renamed.out.find("checksum   missing: "), std::string::npos) << renamed.out;
    const Result renamedCheck = run("info " + grown + " --check");
    EXPECT_EQ(renamedCheck.status, 2);
    EXPECT_NE(renamedCheck.err.find("cambium's metadata without its checksum"), std::string::npos)
        << renamedCheck.err;
    // A report that cannot be written is a failure (exit 0 lost it).
    const Result full = run("info " + grown + " >/dev/full");
    EXPECT_EQ(full.status, 1);
    EXPECT_NE(full.err.find("cannot write to standard output"), std::string::npos) << full.err;
    // mesh and render refuse it too (it was decoded as another tool's file,
    // its trees unchecked)
    for (const char* command : {"mesh", "render"}) {
        const Result used = run(std::string(command) + " " + grown + " -o " + dir.string() + "/x." +
                                (command[0] == 'm' ? "obj" : "png"));
        EXPECT_EQ(used.status, 2) << command;
        EXPECT_NE(used.err.find("cambium's metadata without its checksum"), std::string::npos)
            << used.err;
    }
    std::filesystem::remove_all(dir);
}

TEST(Cli, BakeKeepsColourOnTheShellTheBandOrNowhere)
{
    // --colour shell (the default) keeps fewer Cd voxels than band; none
    // writes no Cd; anything else is refused before any work.
    std::string vdb;
    const auto dir = bakedDir("cambium_cli_colour", vdb);
    const std::string two = kExamples + "operators.json";
    auto colourVoxels = [&](const std::string& mode) -> std::string {
        const std::string out = (dir / (mode + ".vdb")).string();
        const Result b = run("bake " + two + " --voxel-size 0.02 --colour " + mode + " -o " + out);
        EXPECT_EQ(b.status, 0) << b.err;
        const Result i = run("info " + out);
        const size_t at = i.out.find("grid       Cd: vec3s, ");
        return at == std::string::npos ? std::string("no Cd")
                                       : i.out.substr(at, i.out.find('\n', at) - at);
    };
    const std::string shell = colourVoxels("shell"), band = colourVoxels("band"),
                      none = colourVoxels("none");
    EXPECT_NE(shell, band);
    EXPECT_NE(band.find("leaves"), std::string::npos) << band;
    EXPECT_EQ(none, "no Cd");
    expectRefused("bake " + two + " -o " + (dir / "x.vdb").string(),
                  {{"--colour rainbow", "--colour must be shell, band or none (got 'rainbow')"}});
    EXPECT_FALSE(std::filesystem::exists(dir / "x.vdb"));
    std::filesystem::remove_all(dir);
}

/// Whether the dynamic loader's trace (LD_DEBUG=files) of a run shows
/// OpenImageIO loaded.
bool loadsOpenImageIO(const std::string& args, Result& r)
{
    ::setenv("LD_DEBUG", "files", 1);
    r = run(args);
    ::unsetenv("LD_DEBUG");
    return r.err.find("file=libOpenImageIO.so") != std::string::npos;
}

// OpenImageIO and its some 240 libraries cost a command 0.4 s and 130 MB
// before main (issue 16): only the commands that read or write an image
// load it (io/image_codec.h), and those still work.
TEST(Cli, OnlyCommandsWithImagesLoadOpenImageIO)
{
    std::string vdb;
    const auto dir = bakedDir("cambium_cli_startup", vdb);
    Result r;
    EXPECT_FALSE(loadsOpenImageIO(
        "bake " + kExamples + "sphere_and_cone.json -o " + vdb + " --voxel-size 0.05", r));
    EXPECT_EQ(r.status, 0);
    EXPECT_NE(r.err.find("file=libopenvdb"), std::string::npos)  // the trace is there
        << r.err.substr(0, 2000);
    EXPECT_FALSE(loadsOpenImageIO("mesh " + vdb + " -o " + (dir / "s.ply").string(), r));
    EXPECT_EQ(r.status, 0);
    const std::string png = (dir / "s.png").string();
    EXPECT_TRUE(loadsOpenImageIO("render " + vdb + " -o " + png + " --width 32 --height 24", r));
    EXPECT_EQ(r.status, 0);
    EXPECT_GT(std::filesystem::file_size(png), 100u);
    std::filesystem::remove_all(dir);
}

// `cambium prepare` (run by tools/setup.sh) builds every program the bake
// and the march use into the program cache.
TEST(Cli, PrepareCachesEveryOpenCLProgram)
{
    const auto dir =
        std::filesystem::temp_directory_path() / ("cambium_prepare_" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir);
    ::setenv("CAMBIUM_CACHE_DIR", dir.c_str(), 1);
    const Result r = run("prepare");
    ::unsetenv("CAMBIUM_CACHE_DIR");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("prepared the OpenCL kernels on"), std::string::npos) << r.out;
    int programs = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir / "opencl"))
        programs += e.path().extension() == ".bin";
    EXPECT_EQ(programs, 4);  // values, surface, points; the march
    std::filesystem::remove_all(dir);
}

TEST(Cli, MeshWritesAMeshOfABakedGrid)
{
    std::string vdb;
    const auto dir = bakedDir("cambium_cli_mesh", vdb);
    const std::string ply = (dir / "s.ply").string();
    const Result r = run("mesh " + vdb + " -o " + ply);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find(" triangles"), std::string::npos) << r.out;
    EXPECT_TRUE(std::filesystem::file_size(ply) > 1000);
    expectRefused(
        "mesh",
        {
            {(dir / "missing.vdb").string() + " -o " + ply,
             "cannot read the .vdb file: No such file"},
            {vdb + " -o " + ply + " --grid density",
             "no grid named 'density' (it holds: surface, Cd)"},
            {vdb + " -o " + ply + " --grid Cd",
             "grid 'Cd' has the tree type Tree_vec3s_5_4_3, not a float level set's"},
            {vdb + " -o " + (dir / "s.stl").string(), "unknown mesh format '.stl'"},
            {vdb + " -o /nonexistent/dir/s.obj", "/nonexistent/dir/s.obj: cannot write the output"},
            {vdb + " -o " + ply + " --adaptivity 2", "--adaptivity must be between 0 and 1"},
        });
    std::filesystem::remove_all(dir);
}

TEST(Cli, MeshMeshesASequenceFrameByFrame)
{
    const auto dir =
        std::filesystem::temp_directory_path() / ("cambium_cli_seq_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    for (const char* f : {"0003", "0004"})
        ASSERT_EQ(run("bake " + kExamples + "sphere_and_cone.json -o " + (dir / "t.").string() + f +
                      ".vdb --voxel-size 0.06")
                      .status,
                  0);
    const std::string in = (dir / "t.####.vdb").string(), out = (dir / "m.####.obj").string();
    // A missing frame is found before any mesh is written.
    const Result missing = run("mesh '" + in + "' --frames 3-5 -o '" + out + "'");
    EXPECT_EQ(missing.status, 2);
    EXPECT_NE(missing.err.find("t.0005.vdb: no such file (frame 5 of --frames 3-5)"),
              std::string::npos)
        << missing.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "m.0003.obj"));
    const Result noFrames = run("mesh '" + in + "' -o '" + out + "'");
    EXPECT_EQ(noFrames.status, 2);
    EXPECT_NE(noFrames.err.find("a sequence needs"), std::string::npos) << noFrames.err;
    const Result r = run("mesh '" + in + "' --frames 3-4 -o '" + out + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(std::filesystem::exists(dir / "m.0003.obj"));
    EXPECT_TRUE(std::filesystem::exists(dir / "m.0004.obj"));
    std::filesystem::remove_all(dir);
}

TEST(Cli, RenderDrawsABakedGridAndRefusesBadOptions)
{
    std::string vdb;
    const auto dir = bakedDir("cambium_cli_render", vdb);
    const std::string png = (dir / "s.png").string();
    const Result r =
        run("render " + vdb + " -o " + png + " --width 64 --height 48 --spp 2 --device opencl");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("64 x 48, 2 samples per pixel"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("OpenCL NanoVDB march"), std::string::npos) << r.out;
    EXPECT_TRUE(std::filesystem::file_size(png) > 100);
    const Result c = run("render " + vdb + " -o " + png + " --width 64 --height 48");
    ASSERT_EQ(c.status, 0) << c.err;
    EXPECT_NE(c.out.find("OpenVDB's level-set ray intersector"), std::string::npos)
        << c.out;  // the default device (the faster here, issue 16)
    const Result m = run("render " + vdb + " -o " + png + " --width 64 --height 48 --via-mesh");
    ASSERT_EQ(m.status, 0) << m.err;
    EXPECT_NE(m.out.find("Embree"), std::string::npos) << m.out;
    const std::string ply = (dir / "s.ply").string();
    ASSERT_EQ(run("mesh " + vdb + " -o " + ply).status, 0);
    const Result fromMesh = run("render --mesh " + ply + " -o " + png + " --width 64 --height 48");
    ASSERT_EQ(fromMesh.status, 0) << fromMesh.err;
    EXPECT_NE(fromMesh.out.find("Embree on the mesh's triangles"), std::string::npos)
        << fromMesh.out;
    expectRefused(
        "render",
        {
            {"--mesh " + ply + " " + vdb + " -o " + png,
             "--mesh renders a mesh file instead of a .vdb"},
            {"-o " + png, "nothing to render"},
            {"--mesh " + (dir / "m.stl").string() + " -o " + png, "unknown mesh format '.stl'"},
            {vdb + " -o " + (dir / "s.jpg").string(), "unknown image format '.jpg'"},
            {vdb + " -o " + png + " --camera orbit",
             "--camera orbit: expected auto, turntable:ANGLE (degrees) or look:"},
            {vdb + " -o " + png + " --width 0", "--width and --height must be between 1 and 16384"},
            {vdb + " -o " + png + " --spp 0", "--spp must be between 1 and 4096"},
            {vdb + " -o " + png + " --device gpu", "--device must be opencl or cpu (got 'gpu')"},
            {vdb + " -o " + png + " --grid Cd",
             "grid 'Cd' has the tree type Tree_vec3s_5_4_3, not a float level set's"},
            {(dir / "missing.vdb").string() + " -o " + png,
             "cannot read the .vdb file: No such file"},
        });
    std::filesystem::remove_all(dir);
}

TEST(Cli, BakeRefusesBadInputBeforeAnyWork)
{
    const auto dir = std::filesystem::temp_directory_path() /
                     ("cambium_cli_bad_bake_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string out = (dir / "out.vdb").string();
    const auto empty = dir / "empty.json";
    {
        std::ofstream f(empty);
        f << R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 1, "weight": -1}})";
    }
    struct Case {
        std::string args, expected;
    };
    const Case cases[] = {
        {kExamples + "sphere_and_cone.json -o /nonexistent/dir/out.vdb",
         "/nonexistent/dir/out.vdb: cannot write the output"},
        {kExamples + "sphere_and_cone.json -o " + out + " --voxel-size 1e-4",
         "a voxel size of 0.0001 for a surface"},
        {kExamples + "sphere_and_cone.json -o " + out + " --voxel-size -2",
         "--voxel-size must be a number from 0.0001 to 1e9 (got -2)"},
        {empty.string() + " -o " + out, "the model has no surface"},
        {kExamples + "sphere_and_cone.json -o " + out + " --device gpu",
         "--device must be opencl or cpu"},
        {kExamples + "sphere_and_cone.json -o " + out + " --half-width 0.5",
         "--half-width must be between 1 and 64"},
    };
    for (const Case& c : cases) {
        const Result r = run("bake " + c.args);
        EXPECT_EQ(r.status, 2) << c.args;
        EXPECT_NE(r.err.find(c.expected), std::string::npos) << r.err;
        // Nothing written: no output, no temporary file.
        for (const auto& e : std::filesystem::directory_iterator(dir))
            EXPECT_EQ(e.path().extension(), ".json") << e.path();
    }
    std::filesystem::remove_all(dir);
}

TEST(Cli, TheTilesAdviceNeverAsksForMoreTilesThanTheFrameHasLayers)
{
    // 500,000 twigs nested in one point: a frame 6 layers of 128 voxels
    // across whose estimate is hundreds of GB.  At one tile a layer the
    // advice was "use a larger --voxel-size or more than 6 --tiles".
    const auto dir = cambium::test::freshDir("cambium_cli_tiles_advice");
    const auto deep = dir / "deep.l";
    {
        std::ofstream f(deep);
        f << "Axiom: ";
        for (int i = 0; i < 500000; ++i)
            f << "[F(0.001)+(1)";
        f << std::string(500000, ']') << "\nderivation length: 0\n";
    }
    const Result r =
        run("bake " + deep.string() + " --tiles 4096 -o " + (dir / "out.vdb").string());
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find("of memory, and this machine has"), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("more than 6 --tiles"), std::string::npos) << r.err;
    EXPECT_FALSE(std::filesystem::exists(dir / "out.vdb"));
}

TEST(Cli, InfoAndBakeReadTheBenchmarkSkeletonFormat)
{
    const auto dir = std::filesystem::temp_directory_path() /
                     ("cambium_cli_skeleton_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const auto sk = dir / "tree.txt";
    {
        std::ofstream f(sk);
        f << "# id parent x0 y0 z0 x1 y1 z1 r0 r1\n"
             "0 -1 0 0 0 0 1 0 0.1 0.08\n"
             "1 0 0 1 0 0.3 1.5 0 0.05 0.04\n";
    }
    const Result info = run("info " + sk.string());
    ASSERT_EQ(info.status, 0) << info.err;
    EXPECT_NE(info.out.find("2 primitives"), std::string::npos) << info.out;
    const std::string out = (dir / "tree.vdb").string();
    const Result r = run("bake " + sk.string() + " -o " + out + " --voxel-size 0.01");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(std::filesystem::exists(out));
    {
        std::ofstream f(sk);
        f << "0 -1 0 0 0 0 1 0 0.1\n";
    }
    const Result bad = run("bake " + sk.string() + " -o " + out + " --voxel-size 0.01");
    EXPECT_EQ(bad.status, 2);
    EXPECT_NE(bad.err.find("tree.txt:1: expected 10 fields"), std::string::npos) << bad.err;
    std::filesystem::remove_all(dir);
}

TEST(Cli, LSystemPrintsItsStringAndSkeletonAndBakes)
{
    const auto dir = std::filesystem::temp_directory_path() /
                     ("cambium_cli_lsystem_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const auto algae = dir / "algae.l";
    {
        std::ofstream f(algae);
        f << "Axiom: A\nA --> AB\nB --> A\n";  // cpfg's simplest file, as it is
    }
    const Result s = run("lsystem " + algae.string() + " --steps 5 --print-string");
    ASSERT_EQ(s.status, 0) << s.err;
    EXPECT_EQ(s.out, "ABAABABAABAAB\n");
    const std::string honda = kExamples + "lsystems/honda_monopodial.l";
    const Result sk = run("lsystem " + honda + " --steps 3 --print-skeleton");
    ASSERT_EQ(sk.status, 0) << sk.err;
    // The printed skeleton is one cambium bake reads: 7 internodes after 3 steps.
    const auto txt = dir / "honda.txt";
    {
        std::ofstream f(txt);
        f << sk.out;
    }
    const Result info = run("info " + txt.string());
    ASSERT_EQ(info.status, 0) << info.err;
    EXPECT_NE(info.out.find("7 primitives"), std::string::npos) << info.out;
    // An L-system bakes directly.
    const std::string vdb = (dir / "honda.vdb").string();
    const Result b = run("bake " + honda + " -o " + vdb + " --voxel-size 0.05");
    ASSERT_EQ(b.status, 0) << b.err;
    EXPECT_TRUE(std::filesystem::exists(vdb));
    // Skeletons can be built with the junction rules too.
    const Result rules = run("info " + txt.string() + " --junctions pcm --bend 10");
    ASSERT_EQ(rules.status, 0) << rules.err;
    EXPECT_NE(rules.out.find("pcm"), std::string::npos) << rules.out;
    expectRefused(
        "bake",
        {
            {honda + " -o " + vdb + " --junctions ridge",
             "--junctions must be pcm, smooth or blend (got 'ridge')"},
            {honda + " -o " + vdb + " --bend 95", "--bend must be between -90 and 90 degrees"},
            {honda + " -o " + vdb + " --junctions blend --bend 5",
             "--bend needs --junctions pcm or smooth"},
            {honda + " -o " + vdb + " --primitives nurbs",
             "--primitives must be cone, convolution or mixed"},
            {honda + " -o " + vdb + " --regrowth 3", "--regrowth must be between 0 and 1"},
        });
    expectRefused("lsystem", {
                                 {algae.string() + " --steps 30 --max-modules 1000",
                                  "derivation step 15 would make 1597 modules"},
                                 {(dir / "missing.l").string(), "cannot read the L-system file"},
                             });
    std::filesystem::remove_all(dir);
}

TEST(Cli, GrowthPrintsStatsAndBakesASequence)
{
    const std::string populus = kExamples + "populus/populus.json";
    const Result st = run("growth " + populus + " --year 10 --print-stats");
    ASSERT_EQ(st.status, 0) << st.err;
    for (const char* part :
         {"at t = 10 (year 10 of 27)", "order  branches  internodes", "    0         1", "  all ",
          "bud scale scar rings", "BlobTree: ", " operators", "gbb"})
        EXPECT_NE(st.out.find(part), std::string::npos) << part << "\n" << st.out;
    const Result sk = run("growth " + populus + " --year 2 --print-skeleton");
    ASSERT_EQ(sk.status, 0) << sk.err;
    EXPECT_NE(sk.out.find("# order age"), std::string::npos);

    const auto dir = std::filesystem::temp_directory_path() /
                     ("cambium_cli_growth_" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    const std::string pattern = (dir / "p.###.vdb").string();
    const Result b =
        run("bake " + populus + " --frames 3-5 --voxel-size 0.04 --device cpu -o " + pattern);
    ASSERT_EQ(b.status, 0) << b.err;
    for (const char* f : {"p.003.vdb", "p.004.vdb", "p.005.vdb"})
        EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
    EXPECT_NE(b.out.find("3 frames (3 baked, 0 reused, 0 kept, 0 empty)"), std::string::npos)
        << b.out;
    // A line a farm manager parses for each frame, in the order they end.
    {
        std::istringstream lines(b.out);
        std::vector<std::string> frames;
        for (std::string line; std::getline(lines, line);)
            if (line.rfind("frame ", 0) == 0)
                frames.push_back(line);
        ASSERT_EQ(frames.size(), 3u) << b.out;
        const std::regex done(
            R"(frame ([123])/3 done [0-9]+\.[0-9]{2} s -> (.*/p\.00[345]\.vdb) \(baked, frame [345], year .*\))");
        for (size_t i = 0; i < frames.size(); ++i) {
            std::smatch m;
            ASSERT_TRUE(std::regex_match(frames[i], m, done)) << frames[i];
            EXPECT_EQ(m[1].str(), std::to_string(i + 1));
            EXPECT_TRUE(std::filesystem::exists(m[2].str())) << frames[i];
        }
    }
    const Result again = run("bake " + populus +
                             " --frames 3-5 --voxel-size 0.04 --device cpu --resume -o " + pattern);
    ASSERT_EQ(again.status, 0) << again.err;
    EXPECT_NE(again.out.find("3 frames (0 baked, 0 reused, 3 kept, 0 empty)"), std::string::npos)
        << again.out;
    // Rendering the sequence: one camera for all frames, framed on the last,
    // so the young tree covers less of the picture than the older one.
    const Result r = run("render " + pattern + " --frames 3-5 --width 96 --height 96 -o " +
                         (dir / "p.###.png").string() + " --device opencl");
    ASSERT_EQ(r.status, 0) << r.err;
    std::vector<double> covered;
    for (size_t at = 0; (at = r.out.find(" % of pixels", at)) != std::string::npos; ++at) {
        const size_t from = r.out.rfind(", ", at);
        covered.push_back(std::stod(r.out.substr(from + 2, at - from - 2)));
    }
    ASSERT_EQ(covered.size(), 3u) << r.out;
    EXPECT_LT(covered[0], 0.75 * covered[2]) << r.out;
    EXPECT_NE(r.out.find("conversion included"), std::string::npos)
        << "later frames reuse the kernel";
    // One tree, at a time of its life.
    const std::string one = (dir / "one.vdb").string();
    const Result single =
        run("bake " + populus + " --time 4.5 --no-leaves --voxel-size 0.04 -o " + one);
    ASSERT_EQ(single.status, 0) << single.err;
    EXPECT_TRUE(std::filesystem::exists(one));
    expectRefused(
        "bake",
        {
            {populus + " --frames 1-40 -o " + pattern,
             "frame 28 is year 28 at 1 frames a year, outside the tree's 0 to 27"},
            {populus + " --frames 1-3 -o " + (dir / "x.vdb").string(), "a run of '#'"},
            {populus + " --time 30 -o " + one, "--time must be between 0 and 27"},
            {populus + " --junctions blend -o " + one, "a growth parameter file sets its own"},
            {kExamples + "sphere_and_cone.json --frames 1-3 -o " + pattern,
             "--frames needs a growth parameter file"},
            {populus + " --slurm -o " + one, "it needs one of them"},
            {populus + " --tiles 2 --slurm --chunk 3 -o " + one, "--chunk counts frames"},
        });
    expectRefused("growth", {
                                {populus + " --year 28", "--year/--time must be between 0 and 27"},
                                {kExamples + "sphere_and_cone.json", "curves: missing"},
                            });
    std::filesystem::remove_all(dir);
}

TEST(Cli, ASequencesEmptyFrameIsMeshedAndRenderedAsNothing)
{
    // Frame 0 of a growth is empty on purpose (nothing a voxel thick yet):
    // a sequence's mesh and picture of it are an empty mesh and the sky (the
    // whole sequence was refused for it); the lone file is still refused.
    const std::string populus = kExamples + "populus/populus.json";
    const auto dir = cambium::test::freshDir("cambium_cli_empty");
    const std::string pattern = (dir / "p.#.vdb").string();
    const Result b =
        run("bake " + populus + " --frames 0-1 --voxel-size 0.05 --device cpu -o " + pattern);
    ASSERT_EQ(b.status, 0) << b.err;
    EXPECT_NE(b.out.find("1 empty"), std::string::npos) << b.out;
    const Result m = run("mesh " + pattern + " --frames 0-1 -o " + (dir / "p.#.obj").string());
    ASSERT_EQ(m.status, 0) << m.err;
    EXPECT_NE(m.out.find("p.0.obj: 0 vertices, 0 triangles"), std::string::npos) << m.out;
    EXPECT_EQ(m.out.find("p.1.obj: 0 vertices"), std::string::npos) << m.out;
    for (const char* device : {"cpu", "opencl"}) {
        const Result r = run("render " + pattern + " --frames 0-1 --width 32 --height 24 -o " +
                             (dir / "p.#.png").string() + " --device " + device);
        ASSERT_EQ(r.status, 0) << r.err;
        const size_t zero = r.out.find("p.0.png: 32 x 24, 1 sample per pixel, 0.0 % of pixels"),
                     one = r.out.find("p.1.png: 32 x 24");
        ASSERT_NE(zero, std::string::npos) << r.out;
        ASSERT_NE(one, std::string::npos) << r.out;
        const std::string sky = "an empty frame: the background";
        EXPECT_NE(r.out.substr(zero, one - zero).find(sky), std::string::npos) << r.out;
        EXPECT_EQ(r.out.substr(one).find(sky), std::string::npos) << r.out;
    }
    // The statistics of time 0 (the tree not yet grown) are a report, not
    // an error (they printed, then exit 2 "the skeleton has no internodes").
    const Result g = run("growth " + populus + " --time 0 --print-stats");
    EXPECT_EQ(g.status, 0) << g.err;
    EXPECT_NE(g.out.find("BlobTree: none (nothing has grown yet)"), std::string::npos) << g.out;
    expectRefused("mesh", {{(dir / "p.0.vdb").string() + " -o " + (dir / "lone.obj").string(),
                            "no active voxels: nothing to mesh"}});
    expectRefused("render", {{(dir / "p.0.vdb").string() + " -o " + (dir / "lone.png").string(),
                              "no active voxels: nothing to see"}});
}

TEST(Cli, UnknownCommandIsAUsageError)
{
    const Result r = run("frobnicate");
    EXPECT_NE(r.status, 0);
}

}  // namespace
