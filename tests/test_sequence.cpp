// Growth sequences: one .vdb per frame with consistent names, transforms and
// metadata; --resume; dormant frames reused and identical to a full bake;
// determinism; a volume that changes smoothly from frame to frame; bark
// ridges that form continuously with a junction's age.
#include "bake/sequence.h"
#include "io/vdb.h"
#include "blobtree/evaluator.h"
#include "blobtree/stats.h"
#include "core/error.h"
#include "model/growth.h"
#include "test_util.h"
#include "use/mesh.h"

#include <gtest/gtest.h>
#include <openvdb/io/File.h>

#include <algorithm>
#include <tuple>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

namespace {

using namespace cambium;
using cambium::test::expectIdentical;
using cambium::test::expectInputError;
using cambium::test::report;
namespace fs = std::filesystem;

const std::string kPopulus = CAMBIUM_SOURCE_DIR "/examples/populus/populus.json";

struct TempDir {
    fs::path path;
    TempDir()
    {
        char tmpl[] = "/tmp/cambium-seq-XXXXXX";
        path = ::mkdtemp(tmpl);
    }
    ~TempDir() { fs::remove_all(path); }
    std::string operator/(const std::string& name) const { return (path / name).string(); }
};

SequenceRequest sequence(const std::string& out, const std::string& frames, double fps,
                         double h = 0.04)
{
    openvdb::initialize();
    SequenceRequest r;
    r.bake.input = kPopulus;
    r.bake.output = out;
    r.frames = frames;
    r.fpsPerYear = fps;
    r.bake.voxelSize = h;
    r.bake.device = Device::Cpu;
    return r;
}

openvdb::GridPtrVecPtr readGrids(const std::string& path)
{
    openvdb::io::File f(path);
    f.open();
    openvdb::GridPtrVecPtr g = f.getGrids();
    f.close();
    return g;
}

openvdb::FloatGrid::Ptr surface(const std::string& path)
{
    if (!fs::exists(path))
        ADD_FAILURE() << path << " is missing";
    const openvdb::GridPtrVecPtr grids = readGrids(path);  // (held: the loop must not outlive it)
    for (const auto& g : *grids)
        if (g->getName() == "surface")
            return openvdb::gridPtrCast<openvdb::FloatGrid>(g);
    return nullptr;
}

openvdb::Vec3fGrid::Ptr colour(const std::string& path)
{
    const openvdb::GridPtrVecPtr grids = readGrids(path);
    for (const auto& g : *grids)
        if (g->getName() == "Cd")
            return openvdb::gridPtrCast<openvdb::Vec3fGrid>(g);
    return nullptr;
}

TEST(Sequence, FilesAreNamedPaddedAndConsistent)
{
    TempDir dir;
    const SequenceReport r = bakeSequence(sequence(dir / "tree.####.vdb", "8-12:2", 1.0));
    ASSERT_EQ(r.frames.size(), 3u);
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir.path))
        names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    EXPECT_EQ(names, (std::vector<std::string>{"tree.0008.vdb", "tree.0010.vdb",
                                               "tree.0012.vdb"}));  // no temporaries
    for (const FrameReport& f : r.frames) {
        EXPECT_EQ(f.outcome, FrameReport::Outcome::Baked);
        const openvdb::GridPtrVecPtr grids = readGrids(f.path);
        std::vector<std::string> gridNames;
        for (const auto& g : *grids) {
            gridNames.push_back(g->getName());
            EXPECT_TRUE(g->transform() == *openvdb::math::Transform::createLinearTransform(0.04))
                << f.path;
            EXPECT_EQ(g->metaValue<int64_t>("cambium_frame"), f.frame);
            EXPECT_DOUBLE_EQ(g->metaValue<double>("cambium_time"), double(f.frame));
        }
        std::sort(gridNames.begin(), gridNames.end());
        EXPECT_EQ(gridNames, (std::vector<std::string>{"Cd", "surface"}));
        EXPECT_EQ(readFileStamp(f.path).key,
                  sequenceKey(sequence("", "", 1.0), readTextFile(kPopulus, "t"), 0.04));
    }
    // The tree grows: more voxels every frame.
    EXPECT_LT(r.frames[0].stats.activeVoxels, r.frames[1].stats.activeVoxels);
    EXPECT_LT(r.frames[1].stats.activeVoxels, r.frames[2].stats.activeVoxels);
}

TEST(Sequence, ResumeKeepsFinishedFramesAndRefusesOthers)
{
    TempDir dir;
    const std::string pattern = dir / "p.##.vdb";
    bakeSequence(sequence(pattern, "4-7", 1.0));
    fs::remove(dir / "p.06.vdb");
    const auto stamp = fs::last_write_time(dir / "p.05.vdb");
    SequenceRequest again = sequence(pattern, "4-7", 1.0);
    again.resume = true;
    const SequenceReport r = bakeSequence(again);
    ASSERT_EQ(r.frames.size(), 4u);
    for (const FrameReport& f : r.frames)
        EXPECT_EQ(f.outcome,
                  f.frame == 6 ? FrameReport::Outcome::Baked : FrameReport::Outcome::Skipped)
            << f.frame;
    EXPECT_EQ(fs::last_write_time(dir / "p.05.vdb"), stamp);
    EXPECT_TRUE(fs::exists(dir / "p.06.vdb"));
    EXPECT_EQ(readFileStamp(dir / "p.06.vdb").part, "frame 6");
    // Resumed again: frame `baked` baked again with one note that says
    // `why`, the rest kept.
    auto resumeBakes = [&](long long baked, const std::string& why) {
        std::vector<std::string> notes;
        SequenceCallbacks callbacks;
        callbacks.notice = [&](const std::string& line) { notes.push_back(line); };
        const SequenceReport resumed = bakeSequence(again, callbacks);
        for (const FrameReport& f : resumed.frames)
            EXPECT_EQ(f.outcome, f.frame == baked ? FrameReport::Outcome::Baked
                                                  : FrameReport::Outcome::Skipped)
                << f.frame;
        ASSERT_EQ(notes.size(), 1u);
        EXPECT_NE(notes[0].find(why), std::string::npos) << notes[0];
    };
    // A frame copied over another of the sequence.
    fs::copy_file(dir / "p.04.vdb", dir / "p.07.vdb", fs::copy_options::overwrite_existing);
    resumeBakes(7, "p.07.vdb holds frame 4 of this sequence, not frame 7");
    EXPECT_EQ(readFileStamp(dir / "p.07.vdb").part, "frame 7");
    // A frame with one byte changed near its end (its header, key and part
    // as written: kept through every retry of a farm, sweep 20).
    {
        std::ifstream in(dir / "p.05.vdb", std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(in)), {});
        bytes[bytes.size() - 100] ^= 0x5a;
        std::ofstream(dir / "p.05.vdb", std::ios::binary) << bytes;
    }
    resumeBakes(5, "p.05.vdb: a damaged .vdb file: its bytes do not match the checksum");
    EXPECT_NO_THROW(readFileStamp(dir / "p.05.vdb", /*verify=*/true));
    // Files from another bake (here another voxel size) are not taken for finished.
    SequenceRequest other = sequence(pattern, "4-7", 1.0, 0.05);
    other.resume = true;
    expectInputError([&] { bakeSequence(other); }, "p.04.vdb exists from another bake",
                     "other key");
}

TEST(Sequence, DormantFramesReuseGridsIdenticalToAFullBake)
{
    TempDir dir;
    // Year 4 at 10 frames a year: growth until 3.6, dormant after.
    SequenceRequest req = sequence(dir / "d.####.vdb", "35-40", 10.0);
    req.bake.model.leaves = false;
    const SequenceReport r = bakeSequence(req);
    size_t reused = 0;
    for (const FrameReport& f : r.frames) {
        reused += f.outcome == FrameReport::Outcome::Reused;
        if (f.frame >= 38) {
            EXPECT_EQ(f.outcome, FrameReport::Outcome::Reused) << f.frame;
        }
    }
    EXPECT_GE(reused, 3u);
    // The reused frame against a bake of that frame alone.
    TempDir single;
    SequenceRequest one = sequence(single / "s.####.vdb", "39", 10.0);
    one.bake.model.leaves = false;
    bakeSequence(one);
    const auto reusedGrid = surface(dir / "d.0039.vdb"), fullGrid = surface(single / "s.0039.vdb");
    ASSERT_TRUE(reusedGrid && fullGrid);
    expectIdentical(*reusedGrid, *fullGrid, "reused vs full bake");
}

TEST(Sequence, UnchangedLeavesAreReusedAndTheFrameIsAFullBakes)
{
    // Around a year's end with leaves: the leaves fall (frames 89, 90), the
    // next year begins (91); a worker reuses the values of the 8^3 leaves
    // whose specialised program did not change since its last baked frame.
    TempDir dir;
    SequenceRequest req = sequence(dir / "r.####.vdb", "86-91", 10.0, 0.03);
    req.jobs = 1;
    const SequenceReport r = bakeSequence(req);
    size_t reusedLeaves = 0;
    for (const FrameReport& f : r.frames)
        if (f.outcome == FrameReport::Outcome::Baked && f.frame > 86) {
            EXPECT_GT(f.stats.reusedLeaves, 0u) << f.frame;
            EXPECT_LT(f.stats.reusedLeaves, f.stats.candidateLeaves) << f.frame;
            reusedLeaves += f.stats.reusedLeaves;
        }
    EXPECT_GT(reusedLeaves, 1000u);
    for (const char* frame : {"89", "90", "91"}) {
        TempDir single;
        bakeSequence(sequence(single / "s.####.vdb", frame, 10.0, 0.03));
        const std::string name = std::string("00") + frame + ".vdb";
        expectIdentical(*surface(dir / ("r." + name)), *surface(single / ("s." + name)),
                        std::string("frame ") + frame + " with reuse vs alone");
        expectIdentical(*colour(dir / ("r." + name)), *colour(single / ("s." + name)),
                        std::string("Cd of frame ") + frame);
    }
}

TEST(Sequence, RangesOfOnePlanWriteTheFramesOfOneRun)
{
    // The voxel size comes from the plan's last frame, not the range's: two
    // runs of parts of a plan (as two processes would) write the frames that
    // one run of the whole plan writes, bit for bit, also where a part
    // splits a year's reuse group.
    TempDir a, b;
    SequenceRequest whole = sequence(a / "w.#.vdb", "7-12", 2.0);
    whole.bake.voxelSize.reset();  // automatic: 512 voxels across year 6
    const SequenceReport one = bakeSequence(whole);
    SequenceRequest parts = whole;
    parts.bake.output = b / "w.#.vdb";
    const SequencePlan plan = planSequence(parts);
    ASSERT_EQ(plan.frames.size(), 6u);
    EXPECT_EQ(plan.voxelSize, one.voxelSize);
    bool split = false;  // some reuse group has frames on both sides of index 3
    for (const std::vector<size_t>& g : plan.groups)
        split = split || (g.front() < 3 && g.back() >= 3);
    EXPECT_TRUE(split) << "the test should split a reuse group";
    // A temporary of a frame outside a run's range is another run's: kept.
    const std::string other = b / "w.7.vdb.tmp-99999999", mine = b / "w.12.vdb.tmp-99999999";
    std::ofstream(other) << "x";
    std::ofstream(mine) << "x";
    const SequenceReport second = runSequence(plan, 3, 6);
    EXPECT_TRUE(fs::exists(other));
    EXPECT_FALSE(fs::exists(mine));
    const SequenceReport first = runSequence(plan, 0, 3);
    ASSERT_EQ(first.frames.size(), 3u);
    ASSERT_EQ(second.frames.size(), 3u);
    EXPECT_EQ(first.frames[0].frame, 7);
    EXPECT_EQ(second.frames[2].frame, 12);
    for (int f = 7; f <= 12; ++f) {
        const std::string name = "w." + std::to_string(f) + ".vdb";
        expectIdentical(*surface(a / name), *surface(b / name), "surface of " + name);
        expectIdentical(*colour(a / name), *colour(b / name), "Cd of " + name);
        EXPECT_EQ(surface(b / name)->voxelSize()[0], one.voxelSize) << name;
        EXPECT_EQ(readFileStamp(a / name).key, readFileStamp(b / name).key) << name;
    }
    expectInputError([&] { runSequence(plan, 2, 2); }, "not a range", "empty range");
    expectInputError([&] { runSequence(plan, 3, 7); }, "not a range", "past the end");
}

TEST(Sequence, FramesSmallerThanTheSequencesVoxelStillBake)
{
    // A voxel size given for the whole sequence (or a farm chunk's, the
    // plan's) may be larger than an early frame's seedling: the frames
    // bake as before, while a single bake of such a model with that voxel
    // size is refused (review of the refusal: a chunk of a sequence's first
    // frames, and a sequence ending in its first year, whose frames are
    // sampled for their memory, were refused).
    TempDir a;
    const SequenceReport r = bakeSequence(sequence(a / "s.#.vdb", "1-3", 100.0, 0.2));
    EXPECT_EQ(r.frames.size(), 3u);
    BakeRequest single;
    single.input = kPopulus;
    single.model.time = 0.02;
    single.output = a / "single.vdb";
    single.voxelSize = 0.2;
    single.device = Device::Cpu;
    expectInputError([&] { runBake(single); },
                     "--voxel-size 0.2 is larger than the whole model, whose field reaches",
                     "a single bake of the seedling");
    EXPECT_FALSE(fs::exists(a / "single.vdb"));
}

TEST(Sequence, SameSeedSameGridsOtherSeedOtherGrids)
{
    TempDir a, b;
    bakeSequence(sequence(a / "t.#.vdb", "6", 1.0));
    bakeSequence(sequence(b / "t.#.vdb", "6", 1.0));
    expectIdentical(*surface(a / "t.6.vdb"), *surface(b / "t.6.vdb"), "same seed");
    // Another seed: the same parameters otherwise.
    std::string text = readTextFile(kPopulus, "test");
    text.replace(text.find("\"seed\": 1"), 9, "\"seed\": 7");
    const std::string other = a / "other.json";
    {
        std::ofstream(other) << text;
    }
    SequenceRequest req = sequence(b / "u.#.vdb", "6", 1.0);
    req.bake.input = other;
    bakeSequence(req);
    const auto s1 = surface(a / "t.6.vdb"), s2 = surface(b / "u.6.vdb");
    size_t differ = 0;
    for (auto it = s1->cbeginValueOn(); it; ++it)
        differ += s2->tree().getValue(it.getCoord()) != *it;
    EXPECT_GT(differ, s1->activeVoxelCount() / 10);
}

TEST(Sequence, VolumeChangesSmoothlyFromFrameToFrame)
{
    // Years 9-13 at ten frames a year: branches appear by growing from their
    // buds and are shed by dying back, so that no frame's change of volume
    // exceeds four times the median change of the growing frames.  (Without
    // leaves: they fall within a tenth of a year, one frame at this rate.)
    TempDir dir;
    SequenceRequest req = sequence(dir / "v.####.vdb", "81-130", 10.0, 0.03);
    req.bake.model.leaves = false;
    // Nor bark: its furrows change no volume, and were half of the time.
    std::string text = readTextFile(kPopulus, "test");
    text.replace(text.find("\"depth\": 0.12"), 13, "\"depth\": 0.0");
    req.bake.input = dir / "smooth.json";
    std::ofstream(req.bake.input) << text;
    const SequenceReport r = bakeSequence(req);
    // Volumes of the level sets' meshes (OpenVDB's levelSetVolume, a band
    // integral, jumps by several times the change between frames here, on
    // twigs thinner than the band).
    std::vector<double> volume;
    for (const FrameReport& f : r.frames)
        volume.push_back(meshVolume(meshLevelSet(*surface(f.path))));
    std::vector<double> change;
    for (size_t i = 1; i < volume.size(); ++i) {
        change.push_back(std::abs(volume[i] - volume[i - 1]));
        if (std::getenv("CAMBIUM_VERBOSE"))
            report("frame {} volume {:.4f} change {:+.4f}", r.frames[i].frame, volume[i],
                   volume[i] - volume[i - 1]);
    }
    std::vector<double> growing;
    for (double c : change)
        if (c > 0.0)
            growing.push_back(c);
    ASSERT_GT(growing.size(), 20u);
    std::nth_element(growing.begin(), growing.begin() + long(growing.size() / 2), growing.end());
    const double median = growing[growing.size() / 2];
    const double largest = *std::max_element(change.begin(), change.end());
    report("largest change of volume {:.2f} times the median of {} growing frames",
           largest / median, growing.size());
    EXPECT_LT(largest, 4.0 * median)
        << "largest change " << largest << ", median " << median;  // measured 3.5
    // And it grows overall.
    EXPECT_GT(volume.back(), 1.3 * volume.front());
}

TEST(Sequence, ThePlansDiskEstimateIsTheSumOfItsFramesEstimates)
{
    // 100 frames over ten years (more than the 64 the plan estimates, linear
    // between them): within 10 % of the sum of every frame's estimate (the
    // leaves' seasons fall between samples); 40 frames (all estimated):
    // equal.  (Ten years, not 27: the trees of the last years are the largest,
    // and the property the same.)
    TempDir dir;
    for (const auto& [frames, fps, tolerance] :
         {std::tuple{"1-100", 10.0, 0.1}, std::tuple{"1-40", 4.0, 1e-12}}) {
        const SequencePlan plan = planSequence(sequence(dir / "a.####.vdb", frames, fps));
        const BakeRequest& req = plan.request.bake;
        double sum = 0.0;
        for (double t : plan.times) {
            const Skeleton sk = plan.model->skeleton(t, req.model.leaves);
            if (sk.internodes.empty()) {
                sum += 4096.0;
                continue;
            }
            // (each frame's tree as its bake makes it: thin parts thickened)
            const BlobTree tree = frameTree(*plan.model, sk, req.minRadius, plan.voxelSize);
            sum += estimateFileBytes(FieldProgram::compile(tree), plan.voxelSize, req.halfWidth,
                                     req.colour, req.half, req.fog);
        }
        EXPECT_NEAR(plan.fileBytes, sum, tolerance * sum) << frames;
        report("{} frames: the plan's estimate is {:+.2f} % of the frames' sum", frames,
               100.0 * (plan.fileBytes / sum - 1.0));
        EXPECT_GT(plan.bandVoxels, 0.0);
    }
    EXPECT_TRUE(fs::is_empty(dir.path));
}

TEST(Sequence, BadRequestsAreRefusedBeforeAnyOutput)
{
    TempDir dir;
    expectInputError([&] { bakeSequence(sequence(dir / "a.####.vdb", "1-300", 10.0)); },
                     "frame 271 is year 27.1 at 10 frames a year", "past the last year");
    expectInputError([&] { bakeSequence(sequence(dir / "a.vdb", "1-3", 1.0)); }, "a run of '#'",
                     "no #");
    expectInputError([&] { bakeSequence(sequence(dir / "a.#.vdb", "1-3", 0.0)); }, "--fps-per-year",
                     "fps");
    SequenceRequest scene = sequence(dir / "a.#.vdb", "1-3", 1.0);
    scene.bake.input = CAMBIUM_SOURCE_DIR "/examples/lsystems/sympodial.l";
    expectInputError([&] { bakeSequence(scene); }, "--frames needs a growth parameter file",
                     "not growth");
    SequenceRequest junctions = sequence(dir / "a.#.vdb", "1-3", 1.0);
    junctions.bake.model.junctions = ModelOptions::Junctions::Blend;
    expectInputError([&] { bakeSequence(junctions); }, "a growth parameter file sets its own",
                     "junctions");
    expectInputError([&] { bakeSequence(sequence(dir / "a.#.vdb", "20-27", 1.0, 2e-4)); },
                     "of memory, and this machine has", "a voxel size needing terabytes");
    EXPECT_TRUE(fs::is_empty(dir.path));
}

// ---- Bark ridges over time: generalized bounded blending by junction age.

/// A trunk internode with a continuation and a lateral at its tip, all of
/// the given age.
Skeleton junction(double age)
{
    using test::internode;
    Skeleton sk;
    sk.internodes = {
        internode(0, -1, {0, 0, 0}, {0, 2, 0}, 0.3, 0.28, age),
        internode(1, 0, {0, 2, 0}, {0, 4, 0}, 0.28, 0.25, age),
        internode(2, 0, {0, 2, 0}, glm::dvec3(0, 2, 0) + 2.0 * glm::normalize(glm::dvec3(1, 1, 0)),
                  0.15, 0.12, age)};
    return sk;
}

/// Where the surface crosses the line from inside the upper crotch outwards
/// (between the continuation and the lateral).
double crotchSurface(const BlobTree& tree)
{
    const ReferenceEvaluator e(tree);
    const glm::dvec3 from(0.1, 2.2, 0.0), dir = glm::normalize(glm::dvec3(0.52, 0.855, 0.0));
    return cambium::test::bisect([&](double s) { return e.sample(from + s * dir).value - 0.5; },
                                 0.0, 0.8);
}

size_t gbbNodes(const BlobTree& tree)
{
    const TreeStats s = computeStats(tree);
    const auto it = s.countByType.find(NodeType::GBB);
    return it == s.countByType.end() ? 0 : it->second;
}

TEST(Ridges, TheCrotchMovesContinuouslyFromBlendToPcmAsTheJunctionAges)
{
    TreeBuildOptions o;
    o.ridgeYears = 8.0;
    o.ridgeRadius = 4.0;
    TreeBuildOptions pcm = o;
    pcm.ridgeYears = 0.0;  // PCM at once: the ridge
    const double young = crotchSurface(buildTree(junction(0.0), o));
    // At age 0 the junction is the summation.
    const BlobTree summed = buildTree(junction(0.0), o);
    EXPECT_EQ(gbbNodes(summed), 0u);
    const double ridge = crotchSurface(buildTree(junction(-1.0), pcm));  // unknown age: PCM
    ASSERT_GT(std::abs(young - ridge), 0.01)
        << "the blend and PCM crotches must differ for the test to mean anything";
    double last = young, largestStep = 0.0;
    for (double age = 0.25; age <= 12.0; age += 0.25) {
        const BlobTree tree = buildTree(junction(age), o);
        EXPECT_EQ(gbbNodes(tree), 1u);
        const double s = crotchSurface(tree);
        // Monotone from the blend's surface towards the ridge's.
        EXPECT_GE((s - last) * (ridge - young), -1e-12) << "age " << age;
        largestStep = std::max(largestStep, std::abs(s - last));
        last = s;
    }
    EXPECT_LT(largestStep, 0.15 * std::abs(ridge - young));  // no jump
    // Fully formed, the crotch is most of the way to PCM's (the bounding
    // field is 1 on the lateral's axis, about 0.8 at the crotch: measured 76 %).
    EXPECT_GT((last - young) / (ridge - young), 0.7);
    // Nothing changes once formed.
    EXPECT_EQ(crotchSurface(buildTree(junction(20.0), o)), last);
    // The ridge darkens the bark where it forms (PCM's darkening, weighted by
    // the bounding field), not elsewhere.
    auto colourAt = [&](double age, const glm::dvec3& p) {
        const BlobTree tree = buildTree(junction(age), o);
        return ReferenceEvaluator(tree).sample(p).color;
    };
    const glm::dvec3 crotch =
        glm::dvec3(0.1, 2.2, 0.0) + last * glm::normalize(glm::dvec3(0.52, 0.855, 0.0));
    const glm::dvec3 youngColour = colourAt(0.0, crotch), oldColour = colourAt(12.0, crotch);
    EXPECT_LT(oldColour.r, 0.9 * youngColour.r);
    const glm::dvec3 far(0.3, 0.8, 0.0);  // the trunk's side, far below the junction
    EXPECT_EQ(colourAt(0.0, far), colourAt(12.0, far));
}

}  // namespace
