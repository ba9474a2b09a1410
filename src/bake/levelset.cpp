// cambium — a FieldProgram baked into a narrow-band level set: the stages in
// order (bake/stages.h names the file of each).
#include "bake/levelset.h"
#include "core/system.h"

#include "bake/stages.h"
#include "core/clock.h"

#include "cb_program.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <optional>

namespace cambium {

double autoVoxelSize(const FieldProgram& program, double voxels)
{
    const Box b = program.positiveBounds();
    const glm::dvec3 s = b.size();
    const double extent = std::max({s.x, s.y, s.z});
    return extent > 0.0 ? extent / voxels : 0.0;
}

void sampleLeafValues(FieldSampler& sampler, const std::vector<LeafJob>& leaves, LeafList list,
                      double h, uint16_t* value)
{
    std::vector<LeafJob> batch;
    for (size_t b0 = 0; b0 < list.size; b0 += kBatchLeaves) {
        const size_t b1 = std::min(list.size, b0 + kBatchLeaves);
        batch.clear();
        for (size_t k = b0; k < b1; ++k)
            batch.push_back(leaves[list.index[k]]);
        sampler.sampleValues(batch, 0, batch.size(), h, value + b0 * kLeafVoxels);
    }
}

namespace {

/// The program the bake samples: procedural detail (bark) keeps only the
/// octaves four voxels or more long, what the grid can hold without
/// aliasing.  `limited` holds it where that differs from `given`.
const FieldProgram& detailLimited(const FieldProgram& given, double h,
                                  std::optional<FieldProgram>& limited)
{
    if (given.barkCount() == 0 || given.detailLimit() == 4.0 * h)
        return given;
    limited = given;
    limited->setDetailLimit(4.0 * h);
    return *limited;
}

/// A layer of the stream: one or more consecutive layers (a leaf thick
/// across the slab axis) of one slab.
struct Layer {
    size_t begin, end;  ///< its leaves order[begin, end)
    int lo, hi;         ///< its layers' origin[axis] / 8
};

/// The topology's leaves as the bake streams through them: slab by slab,
/// each slab's leaves by their layer (counting sort); consecutive small
/// layers go together (a sampler call costs about half a millisecond however
/// few its leaves).
struct Layers {
    int axis;
    std::vector<size_t> slab;     ///< slabRuns: where each slab starts, then n
    std::vector<uint32_t> order;  ///< leaf indices, layer by layer
    std::vector<Layer> layer;

    Layers(const BandTopology& topo, size_t groupLeaves)
        : axis(topo.slabAxis), slab(slabRuns(topo.leaves, axis)), order(topo.leaves.size())
    {
        const auto& leaves = topo.leaves;
        for (size_t i = 0; i + 1 < slab.size(); ++i) {
            size_t count[8] = {};
            for (size_t l = slab[i]; l < slab[i + 1]; ++l)
                ++count[(leaves[l].origin[axis] >> 3) & 7];
            size_t at[8], next = slab[i];
            const int base = firstLayer(topo, i);
            for (int k = 0; k < 8; ++k) {
                at[k] = next;
                if (count[k] && !layer.empty() &&
                    layer.back().end - layer.back().begin < groupLeaves)
                    layer.back() = {layer.back().begin, next + count[k], layer.back().lo, base + k};
                else if (count[k])
                    layer.push_back({next, next + count[k], base + k, base + k});
                next += count[k];
            }
            for (size_t l = slab[i]; l < slab[i + 1]; ++l)
                order[at[(leaves[l].origin[axis] >> 3) & 7]++] = uint32_t(l);
        }
    }
    size_t slabs() const { return slab.size() - 1; }
    /// Of slab i: origin[axis] / 8 of its first layer.
    int firstLayer(const BandTopology& topo, size_t i) const
    {
        return (topo.leaves[slab[i]].origin[axis] >> 6) * 8;
    }
    LeafList list(size_t u) const
    {
        return LeafList{order.data() + layer[u].begin, layer[u].end - layer[u].begin};
    }
};

/// The grid leaves are the bake's until the grids take them: a sampler that
/// fails mid-stream must not leave the finished slabs' leaves behind (a
/// long-lived process bakes again).
struct LeafOwner {
    BandLeaves& leaves;
    bool owned = true;
    ~LeafOwner()
    {
        if (owned)
            for (size_t l = 0; l < leaves.surface.size(); ++l) {
                delete leaves.surface[l];
                delete leaves.color[l];
            }
    }
};

/// Stages 2-4, streamed through the topology's slabs: the values of each
/// layer of leaves, the voxels next to a sign change of F - T with their
/// gradients and colours, then each slab's propagation into signed distances
/// and grid leaves.  A layer's surface voxels need the values of the layers
/// next to it, a slab's propagation the surface voxels of the layers next to
/// it: the stages run a layer or two ahead of each other, and a layer's
/// values and surface voxels are freed once the stages of its neighbours are
/// done with them.  The bake holds its output and the state of about a slab
/// and a quarter, not of the band.
struct LayerStream {
    const FieldProgram& program;
    FieldSampler& sampler;
    const BakeOptions& opt;
    const BandTopology& topo;
    const std::vector<LeafNeighbours>& nb;
    const Layers& layers;
    const PropagationInput& propagation;
    LeafState& state;
    BandLeaves& leaves;
    LeafValueCache* next;  ///< the values for a next bake (BakeOptions::reuse)
    const Progress& progress;
    BakeStats& st;

    std::vector<ParallelArray<uint16_t>> values =
        std::vector<ParallelArray<uint16_t>>(layers.layer.size());
    std::vector<SurfaceVoxels> surface = std::vector<SurfaceVoxels>(layers.layer.size());
    size_t sampled = 0, propagated = 0, heldLeaves = 0, heldPoints = 0;

    void sampleLayer(size_t u)
    {
        BakeTimings& tm = st.timings;
        const double h = opt.voxelSize;
        auto t0 = Clock::now();
        const LeafList list = layers.list(u);
        values[u] = parallelArray<uint16_t>(list.size * kLeafVoxels);
        if (u == 0)
            tm.startToSampling = processAgeSeconds();
        if (next)
            sampleWithReuse(program, sampler, topo, list, h, *opt.reuse, *next, values[u].get(),
                            st.reusedLeaves);
        else
            sampleLeafValues(sampler, topo.leaves, list, h, values[u].get());
        for (size_t k = 0; k < list.size; ++k)
            state.value[list.index[k]] = values[u].get() + k * kLeafVoxels;
        tm.values += secondsSince(t0);
        t0 = Clock::now();
        findInsideBits(state, list);
        tm.insideBits += secondsSince(t0);
        sampled += list.size;
        reportProgress();
        heldLeaves += list.size;
        st.heldLeaves = std::max(st.heldLeaves, heldLeaves);
    }

    void surfaceLayer(size_t u)
    {
        BakeTimings& tm = st.timings;
        const LeafList list = layers.list(u);
        SurfaceVoxels& sv = surface[u];
        sv = findSurfaceVoxels(list, nb, state, tm);
        const auto t0 = Clock::now();
        sv.samples = parallelArray<SurfaceSample>(sv.count);
        sampler.sampleSurface(sv.queries.get(), sv.count, opt.voxelSize, sv.samples.get());
        sv.queries.reset();
        tm.surfaceSamples += secondsSince(t0);
        const auto t1 = Clock::now();
        makeSurfacePoints(propagation, list, sv, state);
        tm.surfacePoints += secondsSince(t1);
        st.surfacePoints += sv.count;
        heldPoints += sv.count;
        st.heldSurfacePoints = std::max(st.heldSurfacePoints, heldPoints);
    }

    template <typename Array, typename Pointers>
    void release(Array& array, Pointers& pointers, size_t u)
    {
        array.reset();
        const LeafList list = layers.list(u);
        for (size_t k = 0; k < list.size; ++k)
            pointers[list.index[k]] = nullptr;
    }

    void reportProgress()
    {
        progress("baking", 0.5 * double(sampled + propagated) / double(topo.leaves.size()));
    }

    void run()
    {
        const std::vector<Layer>& layer = layers.layer;
        const size_t count = layer.size(), slabs = layers.slabs();
        const std::vector<size_t>& slab = layers.slab;
        size_t sampledLayers = 0, surfaced = 0, valuesFreed = 0, surfaceFreed = 0;
        for (size_t p = 0; p < slabs; ++p) {
            // Slab p's propagation needs the surface voxels of its layers and
            // of the layers next to it, which need the values of the layers
            // next to them.
            const int first = layers.firstLayer(topo, p);
            while (surfaced < count && layer[surfaced].lo <= first + 8) {
                while (sampledLayers < count && layer[sampledLayers].lo <= layer[surfaced].hi + 1)
                    sampleLayer(sampledLayers++);
                surfaceLayer(surfaced++);
                // Values serve the surface voxels of their own and the
                // neighbouring layers only (propagation reads the inside
                // bits): on the 20k benchmark tree half as many are held.
                const auto t0 = Clock::now();
                while (valuesFreed < sampledLayers &&
                       (surfaced == count || layer[surfaced].lo > layer[valuesFreed].hi + 1)) {
                    release(values[valuesFreed], state.value, valuesFreed);
                    heldLeaves -= layer[valuesFreed].end - layer[valuesFreed].begin;
                    ++valuesFreed;
                }
                st.timings.freeing += secondsSince(t0);
            }
            // (A tile's bake: its halo's slabs only serve its own; slabs are
            // 64 voxels thick, its run a multiple of 128.)
            if (topo.owns(topo.leaves[slab[p]]))
                propagate(propagation, slab[p], slab[p + 1], leaves, st.timings);
            propagated += slab[p + 1] - slab[p];
            reportProgress();
            // Surface voxels serve the propagation of their own and the
            // neighbouring slabs.
            const auto t0 = Clock::now();
            const int needed = p + 1 < slabs ? layers.firstLayer(topo, p + 1) - 1
                                             : std::numeric_limits<int>::max();
            while (surfaceFreed < surfaced && layer[surfaceFreed].hi < needed) {
                release(surface[surfaceFreed].points, state.point, surfaceFreed);
                heldPoints -= surface[surfaceFreed].count;
                ++surfaceFreed;
            }
            st.timings.freeing += secondsSince(t0);
        }
    }
};

}  // namespace

BakedGrids bakeLevelSet(const FieldProgram& given, FieldSampler& sampler, const BakeOptions& opt)
{
    std::optional<FieldProgram> limited;
    const FieldProgram& program = detailLimited(given, opt.voxelSize, limited);
    const auto start = Clock::now();
    const double h = opt.voxelSize, W = opt.halfWidth;
    const float background = bandBackground(h, W);
    BakedGrids out;
    BakeStats& st = out.stats;
    BakeTimings& tm = st.timings;
    st.voxelSize = h;
    const Progress report = [&](const char* stage, double f) {
        if (opt.progress)
            opt.progress(stage, f);
    };
    // Until the leaves are sampled an interrupt stops the bake; after, the
    // bake is as good as done (and its leaves are the reuse cache's).
    const Progress progress = [&](const char* stage, double f) {
        if (opt.interrupt && opt.interrupt->load(std::memory_order_relaxed))
            throw BakeInterrupted();
        report(stage, f);
    };

    // 1. Topology.
    auto t = Clock::now();
    BandTopology topo = findBandLeaves(
        program, h, W, [&](double f) { progress("topology", f); }, opt.tile, opt.source);
    st.topologySeconds = secondsSince(t);
    st.boxesTested = topo.boxesTested;
    const size_t n = topo.leaves.size();
    st.candidateLeaves = n;
    st.meanProgramLength = n ? double(topo.pool.size()) / double(n) : 0.0;
    // The plan's estimate counted the primitives' areas; the leaves found are
    // the band itself, before any is sampled (two coincident spheres of
    // radius 0.01 and support 30 sum to a surface 14 out: estimated at 3,770
    // voxels, they made 463 M).
    // (and the surface's internal nodes: along a needle they cost more
    // than its leaves; three needles 1000 long at 0.001 were estimated at
    // 3.05 GB and ran out of memory under 3.6 GB after 41 s, sweep 23)
    checkMemoryFits(estimateBakeBytesFromLeaves(n) +
                        internalNodeBytes(n, false,
                                          [&](size_t l) {
                                              const int32_t* o = topo.leaves[l].origin;
                                              return openvdb::Coord(o[0], o[1], o[2]);
                                          }),
                    fmt::format("{}: sampling the band's {} leaves (its topology search found "
                                "them)",
                                opt.source, formatCount(double(n))),
                    "use a larger voxel size");

    // 2-4, streamed (LayerStream).
    sampler.setProgram(program);
    sampler.setLeaves(topo.leaves, topo.pool);
    // The device holds the programs now; a cache of leaf values still needs
    // them for its keys.  (On the 20k benchmark tree 23 MB.)
    if (sampler.copiesLeaves() && !opt.reuse)
        std::vector<Instr>().swap(topo.pool);
    t = Clock::now();
    const std::vector<LeafNeighbours> nb = findNeighbours(topo.leaves);
    tm.neighbours = secondsSince(t);
    const Layers layers(topo, opt.layerGroupLeaves);
    LeafState state(n);
    std::optional<LeafValueCache> next;
    if (opt.reuse)
        next = startReuse(topo, h);
    const auto uniform = program.uniformColor();
    BandLeaves leaves;
    leaves.surface.assign(n, nullptr);
    leaves.color.assign(n, nullptr);
    leaves.active.assign(n, 0);
    if (opt.colour == ColourExtent::Shell)
        leaves.colorTile.assign(n, std::nullopt);
    // The grids first: packing serialises leaves against their backgrounds.
    const glm::dvec3 rgb = uniform.value_or(glm::dvec3(0.0));
    createGrids(out, h, background, openvdb::Vec3f(float(rgb.x), float(rgb.y), float(rgb.z)));
    std::shared_ptr<PackedLeaves> surfacePack, colorPack;
    if (opt.pack) {
        if (opt.fog)
            throw std::logic_error("bakeLevelSet: a fog volume needs the values: no packing");
        surfacePack = std::make_shared<PackedLeaves>(*out.surface, opt.half, n);
        if (!uniform && opt.colour != ColourExtent::None)
            colorPack = std::make_shared<PackedLeaves>(*out.color, opt.half, n);
        leaves.surfacePack = surfacePack.get();
        leaves.colorPack = colorPack.get();
        leaves.ends.assign(n, 0);
    }
    LeafOwner owner{leaves};
    const PropagationInput propagation{topo.leaves,
                                       nb,
                                       state,
                                       h,
                                       W,
                                       background,
                                       uniform.has_value() || opt.colour == ColourExtent::None,
                                       program.threshold(),
                                       program.params()[CB_P_XT],
                                       opt.colour};
    {
        LayerStream stream{program,  sampler,     opt,   topo,   nb,
                           layers,   propagation, state, leaves, next ? &*next : nullptr,
                           progress, st};
        stream.run();
    }
    // The layers' scratch pages were recycled from layer to layer; what
    // follows has other uses for them.
    trimScratch();
    if (next)
        finishReuse(topo, *next, *opt.reuse);
    st.samplingSeconds = tm.values + tm.surfaceSamples;
    topo.pool = {};

    // 5. The grids.  A model of one colour has that colour wherever the
    // surface is: its Cd grid is that colour as the background, without
    // voxels (on the 20k benchmark tree the voxels would take 1.1 GB and a
    // sixth of the time).
    t = Clock::now();
    owner.owned = false;
    assembleGrids(out, leaves, st, tm);
    out.surfacePacked = surfacePack;
    out.colorPacked = colorPack;
    if (opt.colour == ColourExtent::None)
        out.color.reset();
    tm.tree = secondsSince(t) - tm.floodFill;
    if (opt.fog)
        addFog(out);
    st.seconds = secondsSince(start);
    st.assemblySeconds = st.seconds - st.topologySeconds - st.samplingSeconds;
    report("assembly", 1.0);
    return out;
}

}  // namespace cambium
