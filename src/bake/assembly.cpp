// cambium — bake stage 5: the grids, from the band's leaves.
#include "bake/stages.h"

#include "core/clock.h"
#include "io/grids.h"

#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <tbb/parallel_for.h>

#include <cmath>
#include <map>

namespace cambium {

float bandBackground(double h, double W)
{
    float background = float(W * h);
    while (double(background) / h < W)
        background = std::nextafter(background, INFINITY);
    return background;
}

void createGrids(BakedGrids& out, double h, float background,
                 const openvdb::Vec3f& colourBackground)
{
    out.surface = openvdb::FloatGrid::create(background);
    out.color = openvdb::Vec3fGrid::create(colourBackground);
    const auto xform = openvdb::math::Transform::createLinearTransform(h);
    out.surface->setTransform(xform);
    out.color->setTransform(xform->copy());
    out.surface->setGridClass(openvdb::GRID_LEVEL_SET);
    out.surface->setName(kSurfaceGrid);
    out.color->setName(kColorGrid);
    out.color->setVectorType(openvdb::VEC_INVARIANT);
}

void addFog(BakedGrids& out)
{
    out.density = out.surface->deepCopy();
    openvdb::tools::sdfToFogVolume(*out.density);
    out.density->setName(kDensityGrid);
}

namespace {

/// OpenVDB's signedFloodFill above the leaves (tools/SignedFloodFill.h,
/// minLevel 1: the same scan lines, in the same order) for a tree whose
/// leaves hold no values (packed): a leaf's first and last values' signs
/// come from ends[its transient data] (bits 0 and 1).
class PackedFloodFill {
public:
    using Tree = openvdb::FloatTree;
    using Root = Tree::RootNodeType;
    using Upper = Root::ChildNodeType;
    using Lower = Upper::ChildNodeType;
    using Leaf = Lower::ChildNodeType;

    PackedFloodFill(Tree& tree, const std::vector<uint8_t>& ends)
        : ends_(ends), outside_(std::abs(tree.background())), inside_(-outside_)
    {
        fillLevel<Lower>(tree);
        fillLevel<Upper>(tree);
        fillRoot(tree.root());
    }

private:
    bool inside(const Leaf& leaf, bool last) const
    {
        return (ends_[leaf.transientData()] >> (last ? 1 : 0)) & 1;
    }
    template <class NodeT>
    bool inside(const NodeT& node, bool last) const
    {
        const openvdb::Index i = last ? NodeT::NUM_VALUES - 1 : 0;
        return node.getChildMask().isOn(i) ? inside(*node.getTable()[i].getChild(), last)
                                           : node.getTable()[i].getValue() < 0.0f;
    }
    template <class NodeT>
    void fillLevel(Tree& tree) const
    {
        std::vector<NodeT*> nodes;
        tree.getNodes(nodes);
        tbb::parallel_for(size_t(0), nodes.size(), [&](size_t k) { fill(*nodes[k]); });
    }
    template <class NodeT>
    void fill(NodeT& node) const
    {
        const auto& childMask = node.getChildMask();
        auto* table = const_cast<typename NodeT::UnionType*>(node.getTable());
        const openvdb::Index first = childMask.findFirstOn();
        if (first >= NodeT::NUM_VALUES) {
            const float v = table[0].getValue() < 0.0f ? inside_ : outside_;
            for (openvdb::Index i = 0; i < NodeT::NUM_VALUES; ++i)
                table[i].setValue(v);
            return;
        }
        constexpr openvdb::Index D = 1 << NodeT::LOG2DIM;
        bool xIn = inside(*table[first].getChild(), false);
        for (openvdb::Index x = 0; x != D; ++x) {
            const openvdb::Index x00 = x << (2 * NodeT::LOG2DIM);
            if (childMask.isOn(x00))
                xIn = inside(*table[x00].getChild(), true);
            bool yIn = xIn;
            for (openvdb::Index y = 0; y != D; ++y) {
                const openvdb::Index xy0 = x00 + (y << NodeT::LOG2DIM);
                if (childMask.isOn(xy0))
                    yIn = inside(*table[xy0].getChild(), true);
                bool zIn = yIn;
                for (openvdb::Index z = 0; z != D; ++z) {
                    const openvdb::Index xyz = xy0 + z;
                    if (childMask.isOn(xyz))
                        zIn = inside(*table[xyz].getChild(), true);
                    else
                        table[xyz].setValue(zIn ? inside_ : outside_);
                }
            }
        }
    }
    void fillRoot(Root& root) const
    {
        std::map<openvdb::Coord, const Upper*> nodes;
        for (auto it = root.cbeginChildOn(); it; ++it)
            nodes.emplace(it.getCoord(), &*it);
        constexpr int D = int(Upper::DIM);
        if (!nodes.empty())
            for (auto a = nodes.begin(), b = std::next(a); b != nodes.end(); ++a, ++b) {
                const openvdb::Coord d = b->first - a->first;
                if (d[0] != 0 || d[1] != 0 || d[2] == D)
                    continue;
                if (!inside(*a->second, true) || !inside(*b->second, false))
                    continue;
                for (openvdb::Coord c = a->first + openvdb::Coord(0, 0, D); c[2] != b->first[2];
                     c[2] += D)
                    root.addTile(c, inside_, false);
            }
        root.setBackground(outside_, /*updateChildNodes=*/false);
    }

    const std::vector<uint8_t>& ends_;
    const float outside_, inside_;
};

void floodFillAboveLeaves(openvdb::FloatTree& tree, const std::vector<uint8_t>& ends)
{
    PackedFloodFill(tree, ends);
}

}  // namespace

void assembleGrids(BakedGrids& out, const BandLeaves& leaves, BakeStats& stats,
                   BakeTimings& timings, bool leafSigns)
{
    // Through accessors: consecutive leaves mostly share their internal
    // nodes (depth-first order), which the accessors keep at hand.
    openvdb::FloatGrid::Accessor sAcc = out.surface->getAccessor();
    openvdb::Vec3fGrid::Accessor cAcc = out.color->getAccessor();
    for (size_t l = 0; l < leaves.surface.size(); ++l)
        if (leaves.surface[l]) {
            sAcc.addLeaf(leaves.surface[l]);
            if (leaves.color[l])
                cAcc.addLeaf(leaves.color[l]);
            else if (l < leaves.colorTile.size() && leaves.colorTile[l])
                cAcc.addTile(1, leaves.surface[l]->origin(), *leaves.colorTile[l], true);
            ++stats.activeLeaves;
            stats.activeVoxels += leaves.active[l];
        }
    // A field's bake leaves its leaves' inactive voxels at +-background by
    // the field's sign: only the tiles above them need the flood fill
    // (minLevel 1; at the leaf level it would replace those signs by a
    // scan-line guess).  Without leafSigns, the leaves too.
    const auto t = Clock::now();
    if (leaves.surfacePack)
        floodFillAboveLeaves(out.surface->tree(), leaves.ends);
    else
        openvdb::tools::signedFloodFill(out.surface->tree(), true, 1, leafSigns ? 1 : 0);
    timings.floodFill = secondsSince(t);
}

BakedGrids emptyLevelSet(const BakeOptions& opt)
{
    BakedGrids out;
    createGrids(out, opt.voxelSize, bandBackground(opt.voxelSize, opt.halfWidth),
                openvdb::Vec3f(0.0f));
    if (opt.fog)
        addFog(out);
    if (opt.colour == ColourExtent::None)
        out.color.reset();
    out.stats.voxelSize = opt.voxelSize;
    return out;
}

}  // namespace cambium
