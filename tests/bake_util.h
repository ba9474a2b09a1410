// cambium tests — baking a BlobTree in one call.
#pragma once

#include "bake/levelset.h"
#include "bake/sampler.h"
#include "field/program.h"

namespace cambium::test {

/// The tree baked with voxel size h and half-width W, by the CPU path or OpenCL.
inline BakedGrids bakeTree(const BlobTree& tree, double h, double W = 3.0, bool cpu = true,
                           bool fog = false, ColourExtent colour = ColourExtent::Shell,
                           bool pack = false)
{
    const FieldProgram prog = FieldProgram::compile(tree);
    auto sampler = cpu ? makeCpuSampler() : makeOpenCLSampler();
    BakeOptions o;
    o.voxelSize = h;
    o.halfWidth = W;
    o.fog = fog;
    o.colour = colour;
    o.pack = pack;
    return bakeLevelSet(prog, *sampler, o);
}

}  // namespace cambium::test
