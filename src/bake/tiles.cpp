// cambium — tile files merged into one bake's grids.
#include "bake/tiles.h"

#include "bake/stages.h"
#include "core/clock.h"
#include "core/error.h"

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <optional>
#include <utility>
#include <vector>

namespace cambium {

BakedGrids mergeTiles(const std::vector<std::string>& files, bool half)
{
    const auto start = Clock::now();
    BakedGrids out;
    BandLeaves leaves;
    std::shared_ptr<PackedLeaves> surfacePack, colorPack;
    double h = 0.0;
    for (const std::string& file : files) {
        // A piece of the file at a time: each leaf's values decoded, packed,
        // then dropped (decodeLeaves), so that the merge holds the packed
        // bytes, not a tile's values.
        VdbSummary summary;
        const LevelSetGrids g = readLevelSetDelayed(file, summary);
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
        // Its leaves get the next slots, in the tree's order; a colour leaf
        // the slot of the surface leaf at its origin (a leaf of one colour
        // is a tile of its tree, bake/colour_shell.cpp: its topology holds
        // it).
        const size_t count = g.surface->tree().leafCount();
        const size_t first = surfacePack->addSlots(count);
        colorPack->addSlots(count);
        const size_t n = first + count;
        leaves.surface.resize(n, nullptr);
        leaves.color.resize(n, nullptr);
        leaves.active.resize(n, 0);
        leaves.ends.resize(n, 0);
        leaves.colorTile.resize(n);
        openvdb::Vec3fTree* colors = g.color ? &g.color->tree() : nullptr;
        std::vector<std::pair<openvdb::Coord, uint32_t>> colourSlots;
        size_t k = 0;
        for (auto it = g.surface->tree().cbeginLeaf(); it; ++it, ++k) {
            const openvdb::Coord o = it->origin();
            if (!colors)
                continue;
            if (colors->probeConstLeaf(o))
                colourSlots.emplace_back(o, uint32_t(first + k));
            else if (colors->isValueOn(o) &&
                     colors->getValueDepth(o) == int(colors->treeDepth()) - 2)
                leaves.colorTile[first + k] = colors->getValue(o);
        }
        std::sort(colourSlots.begin(), colourSlots.end());
        auto slotOf = [&](const openvdb::Coord& o) -> const std::pair<openvdb::Coord, uint32_t>* {
            const auto at = std::lower_bound(colourSlots.begin(), colourSlots.end(),
                                             std::make_pair(o, uint32_t(0)));
            return at != colourSlots.end() && at->first == o ? &*at : nullptr;
        };
        // Each leaf decoded, packed and its values dropped, on all cores.
        tbb::enumerable_thread_specific<std::optional<PackedLeaves::Block>> surfaceBlocks,
            colourBlocks;
        decodeLeaves(
            file, summary, *g.surface, {}, [&](size_t i, openvdb::FloatTree::LeafNodeType& leaf) {
                std::optional<PackedLeaves::Block>& block = surfaceBlocks.local();
                if (!block)
                    block.emplace(*surfacePack);
                const uint32_t slot = uint32_t(first + i);
                block->add(slot, leaf);
                leaves.surface[slot] = maskLeaf(leaf, leaf.origin(), background, slot);
                leaves.active[slot] = leaf.onVoxelCount();
                leaves.ends[slot] = leafEnds(
                    leaf.getValue(0), leaf.getValue(openvdb::FloatTree::LeafNodeType::SIZE - 1));
                dropLeafValues(leaf);
            });
        if (g.color)
            decodeLeaves(
                file, summary, *g.color,
                [&](const openvdb::Coord& o) { return slotOf(o) != nullptr; },
                [&](size_t, openvdb::Vec3fTree::LeafNodeType& c) {
                    std::optional<PackedLeaves::Block>& block = colourBlocks.local();
                    if (!block)
                        block.emplace(*colorPack);
                    const uint32_t slot = slotOf(c.origin())->second;
                    block->add(slot, c);
                    leaves.color[slot] = maskLeaf(c, c.origin(), out.color->background(), slot);
                    dropLeafValues(c);
                });
        for (auto* blocks : {&surfaceBlocks, &colourBlocks})
            for (std::optional<PackedLeaves::Block>& block : *blocks)
                if (block)
                    block->keep();
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
