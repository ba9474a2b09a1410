// cambium — bake benchmark.
#include "bench/bake_bench.h"

#include "core/files.h"

#include "bake/levelset.h"
#include "bake/topology.h"
#include "bench/median.h"
#include "bench/process_run.h"
#include "bench/ptls_peer.h"
#include "core/error.h"
#include "core/system.h"
#include "io/vdb.h"
#include "model/skeleton.h"

#include "cb_primitives.h"
#include "core/clock.h"

#include <fmt/format.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/Diagnostics.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>
#include <unistd.h>

namespace cambium {

namespace {

double residentBytes()
{
    std::ifstream in("/proc/self/statm");
    double pages = 0, rss = 0;
    in >> pages >> rss;
    return rss * double(::sysconf(_SC_PAGESIZE));
}

/// Runs f while a thread records the peak resident memory.
template <class F>
double timed(F&& f, double& peakBytes)
{
    std::atomic<bool> done{false};
    std::atomic<double> peak{residentBytes()};
    std::thread watch([&] {
        while (!done) {
            const double r = residentBytes();
            if (r > peak)
                peak = r;
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
        }
    });
    // (joined however f ends: a joinable thread destroyed by an exception
    // from f aborted the process, "terminate called without an active
    // exception")
    struct Join {
        std::atomic<bool>& done;
        std::thread& thread;
        ~Join()
        {
            done = true;
            thread.join();
        }
    };
    double s = 0.0;
    {
        const Join join{done, watch};
        const auto t0 = Clock::now();
        f();
        s = secondsSince(t0);
    }
    peakBytes = std::max(peak.load(), residentBytes());
    return s;
}

/// The naive way: every voxel of the box, every primitive, summed.  Times a
/// patch of voxels and extrapolates to the whole box.
double naiveDenseSeconds(const Skeleton& s, const Box& box, double h, double& voxels)
{
    const glm::dvec3 size = box.size() / h;
    voxels = std::ceil(size.x) * std::ceil(size.y) * std::ceil(size.z);
    const double prims = double(s.internodes.size());
    // About 2e8 voxel-primitive evaluations: a second or two.
    const size_t patch = size_t(std::max(64.0, std::min(voxels, 2e8 / prims)));
    const size_t nx = size_t(std::ceil(size.x));
    std::vector<float> out(patch);
    const auto t0 = Clock::now();
    tbb::parallel_for(size_t(0), patch, [&](size_t v) {
        const glm::dvec3 p = box.lo + h * glm::dvec3(double(v % nx), double((v / nx) % 997), 0.0);
        double f = 0.0;
        for (const Internode& n : s.internodes) {
            const glm::dvec3 axis = n.p1 - n.p0;
            const double len = glm::length(axis);
            cb_vec3 g;
            f += cb_cone_field(cb_v3(p.x, p.y, p.z), cb_v3(n.p0.x, n.p0.y, n.p0.z),
                               cb_v3(axis.x / len, axis.y / len, axis.z / len), len, n.r0, n.r1,
                               1.0, 0.5, &g);
        }
        out[v] = float(f);
    });
    const double t = secondsSince(t0);
    return t * voxels / double(patch);
}

/// The writers of BakeBenchResult, in turn, `repeats` rounds, medians.
void benchWriters(const BakedGrids& g, int repeats, BakeBenchResult& result)
{
    const std::string path = ScratchDirectory::temporaryPath("bench") + ".vdb";
    VdbFileInfo info;
    info.scene = "bench";
    std::vector<double> parallel, serial, whole, file;
    for (int rep = 0; rep < repeats; ++rep) {
        auto t = Clock::now();
        result.fileBytes = double(encodeVdb(g, info, true).size());
        parallel.push_back(secondsSince(t));
        t = Clock::now();
        encodeVdb(g, info, false);
        serial.push_back(secondsSince(t));
        t = Clock::now();
        writeVdb(g, path, info);
        whole.push_back(secondsSince(t));
        t = Clock::now();
        {
            openvdb::io::File f(path);
            f.write({g.surface, g.color});
            f.close();
        }
        file.push_back(secondsSince(t));
    }
    std::filesystem::remove(path);
    result.encodeParallel = medianOf(parallel);
    result.encodeSerial = medianOf(serial);
    result.writeVdbSeconds = medianOf(whole);
    result.fileWrite = medianOf(file);
}

/// The whole commands, in turn, `repeats` rounds: `cambium bake` of the
/// case's skeleton file and the peer program (cambium-ptls, built beside
/// cambium) on the same file, voxel size and band.
void benchProcesses(const BakeBenchCase& c, int repeats, BakeBenchResult& result)
{
    const ScratchDirectory scratch(ScratchDirectory::temporaryPath("bench"));
    const std::filesystem::path dir = scratch.path();
    const std::string tree = (dir / "tree.txt").string(), log = (dir / "log.txt").string();
    {
        std::ofstream out(tree);
        out << c.text;
        if (!out.flush())
            throw std::runtime_error("cannot write the benchmark tree to " + tree);
    }
    const std::string exe = executableDirectory();
    const std::vector<std::string> common = {tree, "--voxel-size", fmt::format("{}", c.voxelSize),
                                             "--half-width", fmt::format("{}", c.halfWidth)};
    auto command = [&](std::vector<std::string> head, const std::string& out) {
        head.insert(head.end(), common.begin(), common.end());
        head.insert(head.end(), {"-o", (dir / out).string()});
        return head;
    };
    // (--min-radius 0: cambium's twigs as they are, the field the in-process
    // rows sample; thickened to the bake's smallest radius, 1k internodes at
    // 0.01 would make more voxels than the peer's spheres)
    const std::vector<std::string> ours = command({exe + "/cambium", "bake", "--min-radius", "0"},
                                                  "cambium.vdb"),
                                   peer = command({exe + "/cambium-ptls"}, "peer.vdb");
    std::vector<ProcessRun> a, b;
    for (int rep = 0; rep < repeats; ++rep) {
        a.push_back(runProcess(ours, log));
        b.push_back(runProcess(peer, log));
    }
    result.process = summariseRuns(a);
    result.peerProcess = summariseRuns(b);
    result.process.fileBytes = double(std::filesystem::file_size(dir / "cambium.vdb"));
    result.peerProcess.fileBytes = double(std::filesystem::file_size(dir / "peer.vdb"));
}

}  // namespace

std::vector<BakeBenchResult> runBakeBench(const std::vector<BakeBenchCase>& cases, bool skipCpu,
                                          int repeats,
                                          const std::function<void(const BakeBenchResult&)>& done)
{
    std::vector<BakeBenchResult> all;
    auto opencl = makeOpenCLSampler();  // built once, as across the frames of a sequence
    auto cpu = makeCpuSampler();
    repeats = std::max(1, repeats);
    for (const BakeBenchCase& c : cases) {
        const Skeleton& skeleton = c.skeleton;
        const BlobTree tree = skeletonToBlend(skeleton);
        const FieldProgram program = FieldProgram::compile(tree);
        const double h = c.voxelSize;
        const Box box = program.positiveBounds().padded(c.halfWidth * h);
        BakeOptions opt;
        opt.voxelSize = h;
        opt.halfWidth = c.halfWidth;
        const PeerSpheres sp = internodeSpheres(skeleton);  // (d)'s input, outside its timing
        // The measured methods run in turn, `repeats` rounds (a b d a b d ...),
        // so that a drift of the machine's speed touches all of them alike;
        // each row reports its median.
        std::vector<BakeBenchRow> rows;
        rows.push_back({"(a) cambium, OpenCL on PoCL"});
        if (!skipCpu)
            rows.push_back({"(b) cambium, CPU path (TBB)"});
        rows.push_back(
            {fmt::format("(d) OpenVDB ParticlesToLevelSet ({} spheres)", formatCount(sp.size()))});
        std::vector<std::vector<double>> times(rows.size());
        BakedGrids written;                // (a)'s last grids, for the writers
        openvdb::FloatGrid::Ptr peerGrid;  // (d)'s last
        for (int rep = 0; rep < repeats; ++rep) {
            for (size_t m = 0; m < rows.size(); ++m) {
                BakeBenchRow& r = rows[m];
                double peak = 0.0;
                if (r.method.rfind("(d)", 0) == 0) {
                    times[m].push_back(
                        timed([&] { peerGrid = ptlsLevelSet(sp, h, c.halfWidth); }, peak));
                    r.activeVoxels = double(peerGrid->activeVoxelCount());
                } else {
                    FieldSampler& s = m == 0 ? *opencl : *cpu;
                    BakedGrids g;
                    times[m].push_back(timed([&] { g = bakeLevelSet(program, s, opt); }, peak));
                    r.activeVoxels = double(g.stats.activeVoxels);
                    if (m == 0)
                        written = std::move(g);
                }
                r.peakBytes = std::max(r.peakBytes, peak);
            }
        }
        for (size_t m = 0; m < rows.size(); ++m)
            rows[m].seconds = medianOf(times[m]);
        double boxVoxels = 0.0;
        {
            BakeBenchRow r;
            r.method = "(c) naive dense evaluation";
            r.estimated = true;
            double voxels = 0.0;
            r.seconds = naiveDenseSeconds(skeleton, box, h, voxels);
            r.activeVoxels = boxVoxels = voxels;
            r.peakBytes = voxels * sizeof(float);  // the dense grid it would fill
            rows.insert(rows.end() - 1, r);
        }
        BakeBenchResult result;
        result.label = c.label;
        result.primitives = skeleton.internodes.size();
        result.voxelSize = h;
        result.halfWidth = c.halfWidth;
        result.boxVoxels = boxVoxels;
        result.repeats = repeats;
        result.rows = rows;
        benchWriters(written, repeats, result);
        result.eikonal = eikonalOutliers(*written.surface);
        result.peerEikonal = eikonalOutliers(*peerGrid);
        written = {};
        peerGrid.reset();
        if (!c.text.empty())
            benchProcesses(c, repeats, result);
        if (done)
            done(result);
        all.push_back(std::move(result));
    }
    return all;
}

EikonalCount eikonalOutliers(const openvdb::FloatGrid& grid)
{
    using Check = openvdb::tools::CheckEikonal<openvdb::FloatGrid>;
    std::vector<const openvdb::FloatTree::LeafNodeType*> leaves;
    grid.tree().getNodes(leaves);
    struct Counts {
        size_t crossing = 0, outside = 0;
    };
    const Counts total = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, leaves.size()), Counts{},
        [&](const tbb::blocked_range<size_t>& range, Counts c) {
            Check check(grid, 0.5f, 1.5f);
            for (size_t i = range.begin(); i != range.end(); ++i)
                for (auto it = leaves[i]->cbeginValueOn(); it; ++it) {
                    check.stencil.moveTo(it.getCoord());
                    if (!check.stencil.zeroCrossing())
                        continue;
                    ++c.crossing;
                    if (check(check.stencil.normSqGrad()))
                        ++c.outside;
                }
            return c;
        },
        [](Counts a, const Counts& b) {
            a.crossing += b.crossing;
            a.outside += b.outside;
            return a;
        });
    return {total.crossing, total.outside};
}

}  // namespace cambium
