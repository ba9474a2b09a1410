// The live preview's loop: an edit makes a new picture (unchanged leaves
// reused); a bad edit keeps the last good picture and names the problem and
// its place; a burst of edits is one update, for the last; an interrupted
// bake writes nothing.
#include "farm/slurm.h"
#include "preview/loop.h"
#include "preview/preview.h"
#include "core/error.h"
#include "io/image_file.h"

#include "cli_util.h"
#include "temp_dir.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>
#include <tuple>
#include <vector>

namespace {

using namespace cambium;
using cambium::test::fileContents;
namespace fs = std::filesystem;

const std::string kPopulus = CAMBIUM_SOURCE_DIR "/examples/populus/populus.json";

/// A copy of the Populus in `dir` with "branching_angle" set to `angle`.
void writeSpecies(const fs::path& path, const std::string& angle)
{
    std::string text = fileContents(kPopulus);
    const std::string key = "\"branching_angle\": 55";
    const size_t at = text.find(key);
    EXPECT_NE(at, std::string::npos);
    text.replace(at, key.size(), "\"branching_angle\": " + angle);
    // (Written beside and renamed, as editors save.)
    std::ofstream(path.string() + ".tmp") << text;
    fs::rename(path.string() + ".tmp", path);
}

PreviewSettings settingsFor(const fs::path& dir)
{
    PreviewSettings s;
    s.input = (dir / "tree.json").string();
    s.model.time = 5.0;
    s.voxelSize = 0.03;
    s.device = Device::Cpu;
    s.renderDevice = Device::Cpu;
    s.width = 80;
    s.height = 60;
    // A fixed view: pictures of the same text compare byte for byte.
    s.camera = "look:6,3,6:0,2,0";
    s.output = (dir / "preview.png").string();
    return s;
}

}  // namespace

TEST(PreviewSession, AnEditMakesANewPictureAndABadOneKeepsTheLast)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_session");
    writeSpecies(dir / "tree.json", "55");
    PreviewSession session(settingsFor(dir));
    using O = PreviewUpdate::Outcome;
    PreviewUpdate u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_GT(u.activeVoxels, 0u);
    EXPECT_EQ(u.reusedLeaves, 0u);
    EXPECT_TRUE(u.rebaked && u.regrown);
    const std::string first = fileContents(dir / "preview.png");
    ASSERT_FALSE(first.empty());
    // The same text: nothing done.
    EXPECT_EQ(session.update().outcome, O::Unchanged);
    // Another time (the year slider): baked again, not grown again; the
    // camera orbited: rendered again, not baked.
    PreviewView view = session.view();
    view.time = 4.0;
    session.setView(view);
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_TRUE(u.rebaked);
    EXPECT_FALSE(u.regrown);
    EXPECT_NE(fileContents(dir / "preview.png"), first);
    view.azimuth = 90.0;
    session.setView(view);
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_FALSE(u.rebaked);
    const std::string turned = fileContents(dir / "preview.png");
    // Back to the first view: the first picture again, byte for byte.
    view.time = 5.0;
    view.azimuth = 0.0;
    session.setView(view);
    ASSERT_EQ(session.update().outcome, O::Rendered);
    EXPECT_EQ(fileContents(dir / "preview.png"), first);
    EXPECT_NE(turned, first);
    // Another branching angle: a new picture; the trunk's leaves reused.
    writeSpecies(dir / "tree.json", "40");
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_TRUE(u.regrown);
    EXPECT_GT(u.reusedLeaves, 0u);
    EXPECT_LT(u.reusedLeaves, u.leaves);
    const std::string second = fileContents(dir / "preview.png");
    EXPECT_NE(second, first);
    // Bad edits: named, with the place in the file; the picture kept.
    std::ofstream(dir / "tree.json") << "{\"years\": 27, ";
    u = session.update();
    EXPECT_EQ(u.outcome, O::Failed);
    EXPECT_TRUE(u.inputError);
    EXPECT_NE(u.error.find("tree.json"), std::string::npos) << u.error;
    EXPECT_EQ(fileContents(dir / "preview.png"), second);
    writeSpecies(dir / "tree.json", "-400");
    u = session.update();
    EXPECT_EQ(u.outcome, O::Failed);
    EXPECT_NE(u.error.find("branching_angle"), std::string::npos) << u.error;
    EXPECT_EQ(fileContents(dir / "preview.png"), second);
    // Deleted: named, the picture kept; made again: pictured.
    fs::remove(dir / "tree.json");
    u = session.update();
    EXPECT_EQ(u.outcome, O::Failed);
    EXPECT_TRUE(u.inputError);
    EXPECT_NE(u.error.find("tree.json"), std::string::npos) << u.error;
    EXPECT_EQ(fileContents(dir / "preview.png"), second);
    // Back to the first text: its picture again, byte for byte.
    writeSpecies(dir / "tree.json", "55");
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_EQ(fileContents(dir / "preview.png"), first);
    EXPECT_EQ(u.pictures, 6u);
}

TEST(PreviewSession, AnInterruptedBakeWritesNothing)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_interrupt");
    writeSpecies(dir / "tree.json", "55");
    PreviewSettings s = settingsFor(dir);
    s.model.time = 27.0;
    s.voxelSize = 0.01;  // (seconds of work: interrupted well before its end)
    PreviewSession session(s);
    std::atomic<bool> interrupt{true};
    EXPECT_EQ(session.update(&interrupt).outcome, PreviewUpdate::Outcome::Interrupted);
    EXPECT_FALSE(fs::exists(dir / "preview.png"));
    // Raised while the bake runs.
    interrupt = false;
    std::thread raise([&] {
        std::this_thread::sleep_for(std::chrono::milliseconds(300));
        interrupt = true;
    });
    const PreviewUpdate u = session.update(&interrupt);
    raise.join();
    EXPECT_EQ(u.outcome, PreviewUpdate::Outcome::Interrupted) << u.total << " s";
    EXPECT_FALSE(fs::exists(dir / "preview.png"));
    // (No temporary left either.)
    std::vector<std::string> files;
    for (const auto& entry : fs::directory_iterator(dir))
        files.push_back(entry.path().filename().string());
    EXPECT_EQ(files, std::vector<std::string>{"tree.json"});
}

TEST(PreviewLoop, ABurstOfEditsIsOneUpdateForTheLast)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_loop");
    writeSpecies(dir / "tree.json", "55");
    PreviewSession session(settingsFor(dir));
    ManualChanges changes;
    std::atomic<bool> stop{false};
    std::mutex mutex;
    std::vector<PreviewUpdate> updates;
    PreviewLoopOptions options;
    options.quiet = std::chrono::milliseconds(300);
    options.updated = [&](const PreviewUpdate& u) {
        std::lock_guard<std::mutex> lock(mutex);
        // (An update a late save interrupted is no picture: not counted.)
        if (u.outcome != PreviewUpdate::Outcome::Interrupted)
            updates.push_back(u);
    };
    std::thread loop([&] { runPreviewLoop(session, changes, stop, options); });
    auto count = [&] {
        std::lock_guard<std::mutex> lock(mutex);
        return updates.size();
    };
    auto waitFor = [&](size_t n) {
        for (int i = 0; i < 600 && count() < n; ++i)
            std::this_thread::sleep_for(std::chrono::milliseconds(50));
        return count() >= n;
    };
    ASSERT_TRUE(waitFor(1));
    // Five saves within the quiet time: one update, of the last.
    for (const char* angle : {"50", "45", "40", "35", "30"}) {
        writeSpecies(dir / "tree.json", angle);
        changes.notify();
    }
    ASSERT_TRUE(waitFor(2));
    std::this_thread::sleep_for(std::chrono::milliseconds(1000));
    stop = true;
    loop.join();
    ASSERT_EQ(updates.size(), 2u);
    EXPECT_EQ(updates[0].outcome, PreviewUpdate::Outcome::Rendered) << updates[0].error;
    EXPECT_EQ(updates[1].outcome, PreviewUpdate::Outcome::Rendered) << updates[1].error;
    // The picture is the last text's, as a session of its own makes it.
    const std::string burst = fileContents(dir / "preview.png");
    PreviewSettings alone = settingsFor(dir);
    alone.output = (dir / "alone.png").string();
    PreviewSession fresh(alone);
    ASSERT_EQ(fresh.update().outcome, PreviewUpdate::Outcome::Rendered);
    EXPECT_TRUE(fileContents(dir / "alone.png") == burst);
}

TEST(PreviewLoop, InotifySeesTheFileWrittenOrRenamedOverAndNothingElse)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_inotify");
    writeSpecies(dir / "tree.json", "55");
    InotifyChanges changes((dir / "tree.json").string());
    const auto none = std::chrono::milliseconds(0), some = std::chrono::milliseconds(2000);
    EXPECT_FALSE(changes.wait(none));
    // Another file of the directory: not a change.
    std::ofstream(dir / "other.json") << "{}";
    EXPECT_FALSE(changes.wait(std::chrono::milliseconds(200)));
    // Written in place, and written beside and renamed over it.
    std::ofstream(dir / "tree.json", std::ios::app) << " ";
    EXPECT_TRUE(changes.wait(some));
    writeSpecies(dir / "tree.json", "40");
    EXPECT_TRUE(changes.wait(some));
    EXPECT_FALSE(changes.wait(none));
    // Deleted (a change: the page says the file is gone), and made again.
    fs::remove(dir / "tree.json");
    EXPECT_TRUE(changes.wait(some));
    writeSpecies(dir / "tree.json", "55");
    EXPECT_TRUE(changes.wait(some));
    EXPECT_FALSE(changes.wait(std::chrono::milliseconds(200)));
    // A directory that is not there: bad input, named.
    try {
        InotifyChanges missing((dir / "no" / "tree.json").string());
        ADD_FAILURE() << "watched a missing directory";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("cannot watch"), std::string::npos) << e.what();
    }
}

TEST(PreviewCommand, OncePicturesAndRefusesBadInputWithStatus2)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_command");
    writeSpecies(dir / "tree.json", "55");
    const std::string png = (dir / "p.png").string();
    const std::string common = " --time 3 --device cpu --height 48 --once -o " + png;
    const cambium::test::Result r =
        cambium::test::run("preview " + (dir / "tree.json").string() + common + " --width 64");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("picture 1: "), std::string::npos) << r.out;
    EXPECT_TRUE(fs::exists(png));
    const struct {
        std::string args, expected;
    } bad[] = {
        {(dir / "missing.json").string() + common, "missing.json"},
        {(dir / "tree.json").string() + common + " --voxel-size -1", "--voxel-size"},
        // The band's limits as bake's (bake/bake.h: checkVoxelSize).
        {(dir / "tree.json").string() + common + " --voxel-size 1e-5",
         "--voxel-size must be a number from 0.0001 to 1e9 (got 1e-05)"},
        {(dir / "tree.json").string() + common + " --width 0",
         "--width and --height must be between 1 and 16384"},
        {(dir / "tree.json").string() + common + " --camera sideways", "sideways"},
        {(dir / "tree.json").string() + " --once -o " + (dir / "p.txt").string(), "p.txt"},
        // (the picture a link to the model: --once wrote over the model)
        {(dir / "tree.json").string() + common.substr(0, common.find(" -o ")) + " -o " +
             (dir / "self.png").string(),
         "self.png: is the input"},
    };
    fs::create_symlink("tree.json", dir / "self.png");
    const std::string model = fileContents(dir / "tree.json");
    for (const auto& b : bad) {
        const cambium::test::Result e = cambium::test::run("preview " + b.args);
        EXPECT_EQ(e.status, 2) << b.args << ": " << e.err;
        EXPECT_NE(e.err.find(b.expected), std::string::npos) << b.args << ": " << e.err;
    }
    EXPECT_EQ(fileContents(dir / "tree.json"), model);
    // A file that does not read: exit 2 with --once, the picture kept.
    const std::string before = fileContents(png);
    writeSpecies(dir / "tree.json", "-400");
    const cambium::test::Result e =
        cambium::test::run("preview " + (dir / "tree.json").string() + common);
    EXPECT_EQ(e.status, 2);
    // (one line as every command's error, and no picture report)
    EXPECT_EQ(e.err.rfind("cambium: error: ", 0), 0u) << e.err;
    EXPECT_NE(e.err.find("branching_angle"), std::string::npos) << e.err;
    EXPECT_EQ(e.out, "");
    EXPECT_EQ(fileContents(png), before);
}

TEST(PreviewSession, FramesBakedInTheBackgroundAreShownAtOnceAndFollowTheFile)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_frames");
    writeSpecies(dir / "tree.json", "55");
    PreviewSettings s = settingsFor(dir);
    s.frames = {3.0, 4.0};
    PreviewSession session(s);
    using O = PreviewUpdate::Outcome;
    EXPECT_FALSE(session.prebake());  // (not before the first picture)
    ASSERT_EQ(session.update().outcome, O::Rendered);
    // One frame a call, then none left; an interrupt stops one.
    std::atomic<bool> interrupt{true};
    EXPECT_FALSE(session.prebake(&interrupt));
    EXPECT_EQ(session.prebakedFrames(), 0u);
    EXPECT_TRUE(session.prebake());
    EXPECT_TRUE(session.prebake());
    EXPECT_FALSE(session.prebake());
    EXPECT_EQ(session.prebakedFrames(), 2u);
    // The slider on year 3: no bake, and the picture a session of its own
    // makes of year 3.
    PreviewView view = session.view();
    view.time = 3.0;
    session.setView(view);
    PreviewUpdate u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_TRUE(u.prebaked);
    EXPECT_EQ(u.bake, 0.0);
    PreviewSettings alone = settingsFor(dir);
    alone.model.time = 3.0;
    alone.output = (dir / "alone.png").string();
    PreviewSession fresh(alone);
    ASSERT_EQ(fresh.update().outcome, O::Rendered);
    EXPECT_TRUE(fileContents(dir / "alone.png") == fileContents(dir / "preview.png"));
    // A new text: the frames are baked again for it.
    writeSpecies(dir / "tree.json", "40");
    EXPECT_TRUE(session.prebake());
    EXPECT_EQ(session.prebakedFrames(), 1u);
    view.time = 4.0;
    session.setView(view);
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_FALSE(u.prebaked);  // (year 4 of the new text is not baked yet)
    // Memory: the kept frames stop at the cap (one frame's bytes and a half
    // keep one), and the frames past it are baked when shown.
    PreviewSettings capped = settingsFor(dir);
    capped.frames = {3.0, 4.0};
    capped.output = (dir / "capped.png").string();
    capped.framesMemory = 1.5 * session.prebakedBytes();  // (one frame of the text)
    PreviewSession small(capped);
    ASSERT_EQ(small.update().outcome, O::Rendered);
    EXPECT_TRUE(small.prebake());
    EXPECT_FALSE(small.prebakeFull());
    EXPECT_FALSE(small.prebake());
    EXPECT_TRUE(small.prebakeFull());
    EXPECT_EQ(small.prebakedFrames(), 1u);
    EXPECT_LE(small.prebakedBytes(), capped.framesMemory);
    PreviewView later = small.view();
    later.time = 4.0;
    small.setView(later);
    u = small.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_FALSE(u.prebaked);
    capped.framesMemory = -1.0;
    EXPECT_THROW(PreviewSession{capped}, InputError);
    // Years outside the tree's, or a file of another kind: refused first.
    PreviewSettings late = settingsFor(dir);
    late.frames = {28.0};
    EXPECT_THROW(PreviewSession{late}, InputError);
    // The picture's limits are render's, named by its options.
    for (const auto& [w, spp, option] : {std::tuple{0, 1, "--width"},
                                         {16385, 1, "--width"},
                                         {64, 0, "--spp"},
                                         {64, 4097, "--spp"}}) {
        PreviewSettings bad = settingsFor(dir);
        bad.width = w;
        bad.spp = spp;
        try {
            PreviewSession{bad};
            ADD_FAILURE() << w << " " << spp;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(option), std::string::npos) << e.what();
        }
    }
}

TEST(PreviewSession, AShapeFileIsSynthesisedBakedAndPictured)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_shape");
    const std::string rock = fileContents(CAMBIUM_SOURCE_DIR "/examples/shapes/rock.json");
    std::ofstream(dir / "rock.json") << rock;
    PreviewSettings s;
    s.input = (dir / "rock.json").string();
    s.device = Device::Cpu;
    s.width = 64;
    s.height = 48;
    s.output = (dir / "preview.png").string();
    PreviewSession session(s);
    using O = PreviewUpdate::Outcome;
    PreviewUpdate u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_GT(u.activeVoxels, 0u);
    const std::string first = fileContents(dir / "preview.png");
    // A rougher rock: another picture.
    std::string rougher = rock;
    rougher.replace(rougher.find("0.08"), 4, "0.25");
    std::ofstream(dir / "rock.json") << rougher;
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_NE(fileContents(dir / "preview.png"), first);
    // A bad edit: named by the shape reader, the picture kept.
    std::string bad = rock;
    bad.replace(bad.find("\"levels\": 6"), 11, "\"levels\": 99");
    std::ofstream(dir / "rock.json") << bad;
    u = session.update();
    EXPECT_EQ(u.outcome, O::Failed);
    EXPECT_TRUE(u.inputError);
    EXPECT_NE(u.error.find("levels"), std::string::npos) << u.error;
}

TEST(PreviewBench, ASigtermEndsItWith143NotAnAbort)
{
    // The signal's cleanup removes the bench's scratch directory; its loop's
    // thread then failed to watch the file and let the exception out:
    // "terminate called", exit 134.  (Sent after 6 s, while the edits run;
    // on a slower machine sooner, where 143 holds too.)
    const fs::path dir = cambium::test::freshDir("cambium_bench_preview_signal");
    const std::string command =
        "bash -c " +
        cambium::shellQuote(std::string(CAMBIUM_EXE) + " bench preview --parameters " +
                            cambium::shellQuote(kPopulus) +
                            " --years 3 --edits 100000 --device cpu --width 16 --height 16 > " +
                            cambium::shellQuote((dir / "out.txt").string()) + " 2> " +
                            cambium::shellQuote((dir / "err.txt").string()) +
                            " & pid=$!; sleep 6; kill -TERM $pid; wait $pid; echo $? > " +
                            cambium::shellQuote((dir / "status.txt").string()));
    ASSERT_EQ(std::system(command.c_str()), 0);
    EXPECT_EQ(fileContents(dir / "status.txt"), "143\n") << fileContents(dir / "err.txt");
    EXPECT_EQ(fileContents(dir / "err.txt").find("terminate called"), std::string::npos)
        << fileContents(dir / "err.txt");
}

TEST(PreviewSession, AGrowthFilesBarkPhotoPaintsThePictureAsABakeDoes)
{
    const fs::path dir = cambium::test::freshDir("cambium_preview_photo");
    // A photo of one colour (linear RGB), written as a PNG.
    auto photo = [&](float r, float g, float b) {
        RenderImage img;
        img.width = img.height = 8;
        for (int i = 0; i < 64; ++i)
            img.rgb.insert(img.rgb.end(), {r, g, b});
        writeImage(img, (dir / "bark.png").string());
    };
    // The picture's pixels (linear RGB) summed, red minus blue.
    auto redness = [&] {
        const Photo p = readPhoto((dir / "preview.png").string());
        double sum = 0.0;
        for (size_t i = 0; i < p.rgb.size(); i += 3)
            sum += p.rgb[i] - p.rgb[i + 2];
        return sum;
    };
    std::string text = fileContents(kPopulus);
    const std::string bark = "\"bark\": {\"color\": [0.36, 0.3, 0.24], ";
    ASSERT_NE(text.find(bark), std::string::npos);
    std::ofstream(dir / "tree.json") << text;
    PreviewSettings settings = settingsFor(dir);
    settings.camera = "look:0.5,0.5,0.5:0,0.4,0";  // close to the trunk
    PreviewSession session(settings);
    using O = PreviewUpdate::Outcome;
    PreviewUpdate u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    const double plain = redness();
    // The file names a red photo: the bark is painted red, as a bake paints it.
    photo(0.8f, 0.02f, 0.02f);
    text.replace(text.find(bark), bark.size(), bark + "\"photo\": \"bark.png\", ");
    std::ofstream(dir / "tree.json") << text;
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    const double red = redness();
    EXPECT_GT(red, plain + 20.0) << plain;
    // The photo made blue under the same text: baked again at the next update.
    photo(0.02f, 0.02f, 0.8f);
    fs::last_write_time(dir / "bark.png",
                        fs::last_write_time(dir / "bark.png") + std::chrono::seconds(2));
    u = session.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_TRUE(u.rebaked);
    EXPECT_LT(redness(), plain - 20.0) << plain;
    const std::string blue = fileContents(dir / "preview.png");
    // The same photo: nothing done.
    EXPECT_EQ(session.update().outcome, O::Unchanged);
    // A damaged photo is named, and the picture kept.
    std::ofstream(dir / "bark.png") << "not a picture";
    u = session.update();
    EXPECT_EQ(u.outcome, O::Failed);
    EXPECT_TRUE(u.inputError);
    EXPECT_NE(u.error.find("bark.png"), std::string::npos) << u.error;
    EXPECT_EQ(fileContents(dir / "preview.png"), blue);
    // With --frames, a frame baked in the background reads a changed photo
    // first: the picture is baked again all the same (it read the new photo
    // and took its stamp, and the update after it saw no change).
    photo(0.8f, 0.02f, 0.02f);
    PreviewSettings framed = settings;
    framed.frames = {4.0};
    PreviewSession background(framed);
    ASSERT_EQ(background.update().outcome, O::Rendered);
    EXPECT_GT(redness(), plain + 20.0) << plain;
    photo(0.02f, 0.02f, 0.8f);
    fs::last_write_time(dir / "bark.png",
                        fs::last_write_time(dir / "bark.png") + std::chrono::seconds(4));
    EXPECT_TRUE(background.prebake());
    u = background.update();
    ASSERT_EQ(u.outcome, O::Rendered) << u.error;
    EXPECT_LT(redness(), plain - 20.0) << plain;
}
