// cambium — trilinear lookups of a grid at world-space points.
#pragma once

#include "io/grids.h"

#include <openvdb/tools/Interpolation.h>

namespace cambium {

/// Trilinear lookups of a grid at world-space points, for one thread: it
/// owns the accessor its sampler refers to, so it is neither copied nor moved.
template <class GridT>
class WorldSampler {
public:
    explicit WorldSampler(const GridT& grid)
        : accessor_(grid.getConstAccessor()), sampler_(accessor_, grid.transform())
    {
    }
    WorldSampler(const WorldSampler&) = delete;
    WorldSampler& operator=(const WorldSampler&) = delete;
    typename GridT::ValueType operator()(const openvdb::Vec3d& world) const
    {
        return sampler_.wsSample(world);
    }
    /// The same lookup at an index-space point of the grid.
    typename GridT::ValueType atIndex(const openvdb::Vec3d& index) const
    {
        return sampler_.isSample(index);
    }

private:
    typename GridT::ConstAccessor accessor_;
    openvdb::tools::GridSampler<typename GridT::ConstAccessor, openvdb::tools::BoxSampler> sampler_;
};

}  // namespace cambium
