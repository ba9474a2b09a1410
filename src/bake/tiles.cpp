// cambium — tile files merged into one bake's grids.
#include "bake/tiles.h"

#include "bake/stages.h"
#include "core/clock.h"
#include "core/error.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

namespace cambium {

namespace {

/// A leaf's values freed (a buffer that holds none in their place).
template <class LeafT>
void dropValues(LeafT& leaf)
{
    typename LeafT::Buffer none(openvdb::PartialCreate(), leaf.getValue(0));
    leaf.buffer().swap(none);
}

}  // namespace

BakedGrids mergeTiles(const std::vector<std::string>& files, bool half)
{
    const auto start = Clock::now();
    BakedGrids out;
    BandLeaves leaves;
    std::shared_ptr<PackedLeaves> surfacePack, colorPack;
    double h = 0.0;
    for (const std::string& file : files) {
        // A leaf at a time: each leaf's values read when packed, then
        // dropped (delayed loading), so that the merge holds the packed
        // bytes, not a tile's values.
        const LevelSetGrids g = readLevelSetDelayed(file);
        const double voxel = g.surface->voxelSize()[0];
        const float background = g.surface->background();
        if (!out.surface) {
            h = voxel;
            const openvdb::Vec3f colour = g.color ? g.color->background() : openvdb::Vec3f(0.0f);
            createGrids(out, h, background, colour);
            surfacePack = std::make_shared<PackedLeaves>(*out.surface, half, 0);
            colorPack = std::make_shared<PackedLeaves>(*out.color, half, 0);
            leaves.surfacePack = surfacePack.get();
            leaves.colorPack = colorPack.get();
        } else if (voxel != h || background != out.surface->background()) {
            throw InputError(fmt::format(
                "{}: not a tile of the same bake as {} (voxel size {} and background {}, not {} "
                "and {})",
                file, files.front(), voxel, background, h, out.surface->background()));
        }
        // Its leaves packed in parallel, each into the slot that names it.
        std::vector<openvdb::FloatTree::LeafNodeType*> tileLeaves;
        tileLeaves.reserve(g.surface->tree().leafCount());
        for (auto it = g.surface->tree().beginLeaf(); it; ++it)
            tileLeaves.push_back(it.getLeaf());
        const size_t first = surfacePack->addSlots(tileLeaves.size());
        colorPack->addSlots(tileLeaves.size());
        const size_t n = first + tileLeaves.size();
        leaves.surface.resize(n, nullptr);
        leaves.color.resize(n, nullptr);
        leaves.active.resize(n, 0);
        leaves.ends.resize(n, 0);
        leaves.colorTile.resize(n);
        openvdb::Vec3fTree* colors = g.color ? &g.color->tree() : nullptr;
        tbb::parallel_for(
            tbb::blocked_range<size_t>(0, tileLeaves.size(), 256),
            [&](const tbb::blocked_range<size_t>& r) {
                PackedLeaves::Block surfaceBlock(*surfacePack), colorBlock(*colorPack);
                for (size_t k = r.begin(); k < r.end(); ++k) {
                    auto& leaf = *tileLeaves[k];
                    const uint32_t slot = uint32_t(first + k);
                    surfaceBlock.add(slot, leaf);
                    leaves.surface[slot] = maskLeaf(leaf, leaf.origin(), background, slot);
                    leaves.active[slot] = leaf.onVoxelCount();
                    leaves.ends[slot] =
                        leafEnds(leaf.getValue(0),
                                 leaf.getValue(openvdb::FloatTree::LeafNodeType::SIZE - 1));
                    dropValues(leaf);
                    if (auto* c = colors ? colors->probeLeaf(leaf.origin()) : nullptr) {
                        colorBlock.add(slot, *c);
                        leaves.color[slot] =
                            maskLeaf(*c, c->origin(), out.color->background(), slot);
                        dropValues(*c);
                    } else if (colors && colors->isValueOn(leaf.origin()) &&
                               colors->getValueDepth(leaf.origin()) ==
                                   int(colors->treeDepth()) - 2) {
                        // (a leaf of one colour: a tile, bake/colour_shell.cpp)
                        leaves.colorTile[slot] = colors->getValue(leaf.origin());
                    }
                }
                surfaceBlock.keep();
                colorBlock.keep();
            });
    }
    if (!out.surface)
        throw std::logic_error("mergeTiles: no tile files");
    BakeStats& st = out.stats;
    st.voxelSize = h;
    assembleGrids(out, leaves, st, st.timings);
    out.surfacePacked = surfacePack;
    if (colorPack->size() > 0)
        out.colorPacked = colorPack;
    st.seconds = st.assemblySeconds = secondsSince(start);
    return out;
}

}  // namespace cambium
