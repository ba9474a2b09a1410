// cambium — bake stage 5: the grids, from the band's leaves.
#include "bake/stages.h"

#include "core/clock.h"
#include "io/grids.h"

#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <cmath>

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
            ++stats.activeLeaves;
            stats.activeVoxels += leaves.active[l];
        }
    // A field's bake leaves its leaves' inactive voxels at +-background by
    // the field's sign: only the tiles above them need the flood fill
    // (minLevel 1; at the leaf level it would replace those signs by a
    // scan-line guess).  Without leafSigns, the leaves too.
    const auto t = Clock::now();
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
    out.stats.voxelSize = opt.voxelSize;
    return out;
}

}  // namespace cambium
