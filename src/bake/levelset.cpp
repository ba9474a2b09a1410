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

void sampleLeafValues(FieldSampler& sampler, const std::vector<LeafJob>& leaves, size_t begin,
                      size_t end, double h, uint16_t* value)
{
    for (size_t b0 = begin; b0 < end; b0 += kBatchLeaves) {
        const size_t b1 = std::min(end, b0 + kBatchLeaves);
        sampler.sampleValues(leaves, b0, b1, h, value + (b0 - begin) * kLeafVoxels);
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

    // 2-4, slab by slab (the topology's order): the values of a slab, the
    // voxels next to a sign change of F - T with their gradients and
    // colours, then propagation into signed distances and grid leaves.  Each
    // stage of a slab needs the one before it on the neighbouring slabs too,
    // so the stages run up to a slab ahead of each other, and what a slab's
    // neighbours no longer need is freed: the bake holds its output and the
    // stages' state of about four slabs, not of the whole band.
    sampler.setProgram(program);
    sampler.setLeafCode(topo.pool);
    t = Clock::now();
    const std::vector<LeafNeighbours> nb = findNeighbours(topo.leaves);
    tm.neighbours = secondsSince(t);
    const std::vector<size_t> slab = slabRuns(topo.leaves, topo.slabAxis);
    const size_t slabs = slab.size() - 1;
    std::vector<int> coord(slabs);
    for (size_t i = 0; i < slabs; ++i)
        coord[i] = topo.leaves[slab[i]].origin[topo.slabAxis] >> 6;
    LeafState state(n);
    std::vector<ParallelArray<uint16_t>> values(slabs);
    std::vector<SurfaceVoxels> surface(slabs);
    std::optional<LeafValueCache> next;
    if (opt.reuse)
        next = startReuse(topo, h);
    const auto uniform = program.uniformColor();
    BandLeaves leaves;
    leaves.surface.assign(n, nullptr);
    leaves.color.assign(n, nullptr);
    leaves.active.assign(n, 0);
    const PropagationInput propagation{topo.leaves,        nb, state, h, W, background,
                                       uniform.has_value()};
    size_t sampled = 0, propagated = 0, heldLeaves = 0, heldPoints = 0;
    auto sampleSlab = [&](size_t i) {
        auto t0 = Clock::now();
        const size_t b = slab[i], e = slab[i + 1];
        values[i] = parallelArray<uint16_t>((e - b) * kLeafVoxels);
        if (i == 0)
            tm.startToSampling = processAgeSeconds();
        if (next)
            sampleWithReuse(program, sampler, topo, b, e, h, *opt.reuse, *next, values[i].get(),
                            st.reusedLeaves);
        else
            sampleLeafValues(sampler, topo.leaves, b, e, h, values[i].get());
        for (size_t l = b; l < e; ++l)
            state.value[l] = values[i].get() + (l - b) * kLeafVoxels;
        tm.values += secondsSince(t0);
        t0 = Clock::now();
        findInsideBits(state, b, e);
        tm.insideBits += secondsSince(t0);
        sampled += e - b;
        heldLeaves += e - b;
        st.heldLeaves = std::max(st.heldLeaves, heldLeaves);
        progress("sampling", double(sampled) / double(n));
    };
    auto surfaceSlab = [&](size_t i) {
        const size_t b = slab[i], e = slab[i + 1];
        SurfaceVoxels& sv = surface[i];
        sv = findSurfaceVoxels(b, e, nb, state, tm);
        const auto t0 = Clock::now();
        sv.samples = parallelArray<SurfaceSample>(sv.count);
        sampler.sampleSurface(topo.leaves, sv.queries.get(), sv.count, h, sv.samples.get());
        sv.queries.reset();
        for (size_t l = b; l < e; ++l)
            state.sample[l] = sv.samples.get() + (state.first[l] - state.first[b]);
        tm.surfaceSamples += secondsSince(t0);
        st.surfacePoints += sv.count;
        heldPoints += sv.count;
        st.heldSurfacePoints = std::max(st.heldSurfacePoints, heldPoints);
    };
    auto release = [&](auto& array, auto& pointers, size_t i) {
        array.reset();
        std::fill(pointers.begin() + long(slab[i]), pointers.begin() + long(slab[i + 1]), nullptr);
    };
    size_t sampledSlabs = 0, surfaced = 0, valuesFreed = 0, surfaceFreed = 0;
    for (size_t p = 0; p < slabs; ++p) {
        // Slab p's propagation needs the surface voxels of the slabs next to
        // it, which need the values of the slabs next to them.
        while (surfaced < slabs && coord[surfaced] <= coord[p] + 1) {
            while (sampledSlabs < slabs && coord[sampledSlabs] <= coord[surfaced] + 1)
                sampleSlab(sampledSlabs++);
            surfaceSlab(surfaced++);
        }
        propagate(propagation, slab[p], slab[p + 1], leaves, tm);
        propagated += slab[p + 1] - slab[p];
        progress("assembly", double(propagated) / double(n));
        // Values serve the surface voxels of their own and the neighbouring
        // slabs and their own propagation; surface voxels the propagation of
        // their own and the neighbouring slabs.
        const auto t0 = Clock::now();
        while (valuesFreed <= p &&
               (surfaced == slabs || coord[surfaced] > coord[valuesFreed] + 1)) {
            release(values[valuesFreed], state.value, valuesFreed);
            heldLeaves -= slab[valuesFreed + 1] - slab[valuesFreed];
            ++valuesFreed;
        }
        while (surfaceFreed < surfaced &&
               (p + 1 == slabs || coord[p + 1] > coord[surfaceFreed] + 1)) {
            release(surface[surfaceFreed].edges, state.edge, surfaceFreed);
            release(surface[surfaceFreed].samples, state.sample, surfaceFreed);
            heldPoints -= surface[surfaceFreed].count;
            ++surfaceFreed;
        }
        tm.freeing += secondsSince(t0);
    }
    if (next)
        finishReuse(topo, *next, *opt.reuse);
    st.samplingSeconds = tm.values + tm.surfaceSamples;
    topo.pool = {};

    // 5. The grids.  A model of one colour has that colour wherever the
    // surface is: its Cd grid is that colour as the background, without
    // voxels (on the 20k benchmark tree the voxels would take 1.1 GB and a
    // sixth of the time).
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
