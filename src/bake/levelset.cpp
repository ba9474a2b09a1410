// cambium — a FieldProgram baked into a narrow-band level set: the stages in
// order (bake/stages.h names the file of each).
#include "bake/levelset.h"
#include "core/system.h"

#include "bake/stages.h"
#include "core/clock.h"

#include <algorithm>
#include <optional>

namespace cambium {

double autoVoxelSize(const FieldProgram& program, double voxels)
{
    const Box b = program.positiveBounds();
    const glm::dvec3 s = b.size();
    const double extent = std::max({s.x, s.y, s.z});
    return extent > 0.0 ? extent / voxels : 0.0;
}

void sampleLeafValues(FieldSampler& sampler, const std::vector<LeafJob>& leaves, double h,
                      uint16_t* value, const Progress& progress)
{
    const size_t n = leaves.size();
    for (size_t b0 = 0; b0 < n; b0 += kBatchLeaves) {
        const size_t b1 = std::min(n, b0 + kBatchLeaves);
        sampler.sampleValues(leaves, b0, b1, h, value + b0 * kLeafVoxels);
        progress("sampling", 0.8 * double(b1) / double(n));
    }
}

BakedGrids bakeLevelSet(const FieldProgram& given, FieldSampler& sampler, const BakeOptions& opt)
{
    // Procedural detail (bark) keeps only the octaves four voxels or more
    // long: what the grid can hold without aliasing.
    std::optional<FieldProgram> limited;
    if (given.barkCount() > 0 && given.detailLimit() != 4.0 * opt.voxelSize) {
        limited = given;
        limited->setDetailLimit(4.0 * opt.voxelSize);
    }
    const FieldProgram& program = limited ? *limited : given;
    const auto start = Clock::now();
    const double h = opt.voxelSize, W = opt.halfWidth;
    const float background = bandBackground(h, W);
    BakedGrids out;
    BakeStats& st = out.stats;
    BakeTimings& tm = st.timings;
    st.voxelSize = h;
    const Progress progress = [&](const char* stage, double f) {
        if (opt.progress)
            opt.progress(stage, f);
    };

    // 1. Topology.
    auto t = Clock::now();
    BandTopology topo = findBandLeaves(program, h, W, [&](double f) { progress("topology", f); });
    st.topologySeconds = secondsSince(t);
    st.boxesTested = topo.boxesTested;
    const size_t n = topo.leaves.size();
    st.candidateLeaves = n;
    st.meanProgramLength = n ? double(topo.pool.size()) / double(n) : 0.0;

    // 2. Values of every voxel of those leaves (F - T), in batches.
    t = Clock::now();
    auto value = parallelArray<uint16_t>(n * kLeafVoxels);
    sampler.setProgram(program);
    sampler.setLeafCode(topo.pool);
    tm.startToSampling = processAgeSeconds();
    if (opt.reuse)
        sampleWithReuse(program, sampler, topo, h, *opt.reuse, value.get(), st.reusedLeaves,
                        progress);
    else
        sampleLeafValues(sampler, topo.leaves, h, value.get(), progress);
    tm.values = secondsSince(t);

    // 3. Neighbours, the voxels next to a sign change of F - T, then their
    // gradients and colours.
    t = Clock::now();
    const std::vector<LeafNeighbours> nb = findNeighbours(topo.leaves);
    tm.neighbours = secondsSince(t);
    SurfaceVoxels surface = findSurfaceVoxels(topo.leaves, value.get(), nb, tm);
    const size_t np = surface.count();
    t = Clock::now();
    auto samples = parallelArray<SurfaceSample>(np);
    sampler.sampleSurface(topo.leaves, surface.queries.get(), np, h, samples.get());
    surface.queries.reset();
    tm.surfaceSamples = secondsSince(t);
    st.samplingSeconds = tm.values + tm.surfaceSamples;
    st.surfacePoints = np;
    progress("sampling", 1.0);
    topo.pool = {};

    // 4. Propagation into signed distances and grid leaves, tile by tile.
    const auto uniform = program.uniformColor();
    const BandLeaves leaves = propagate({topo.leaves, value.get(), nb, surface, samples.get(), h, W,
                                         background, uniform.has_value()},
                                        progress, tm);

    // 5. The grids.  A model of one colour has that colour wherever the
    // surface is: its Cd grid is that colour as the background, without
    // voxels (on the 20k benchmark tree the voxels would take 1.1 GB and a
    // sixth of the time).
    t = Clock::now();
    value.reset();
    surface.edges.reset();
    samples.reset();
    tm.freeing = secondsSince(t);
    t = Clock::now();
    const glm::dvec3 rgb = uniform.value_or(glm::dvec3(0.0));
    createGrids(out, h, background, openvdb::Vec3f(float(rgb.x), float(rgb.y), float(rgb.z)));
    assembleGrids(out, leaves, st, tm);
    tm.tree = secondsSince(t) - tm.floodFill;
    if (opt.fog)
        addFog(out);
    st.seconds = secondsSince(start);
    st.assemblySeconds = st.seconds - st.topologySeconds - st.samplingSeconds;
    progress("assembly", 1.0);
    return out;
}

}  // namespace cambium
