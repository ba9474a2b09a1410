// cambium — reading baked level sets back, one file or a frame sequence.
#pragma once

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>

#include <functional>
#include <string>

namespace cambium {

/// A level-set grid and, when the file has one, its `Cd` colour grid.
struct LevelSetFile {
    openvdb::FloatGrid::Ptr surface;
    openvdb::Vec3fGrid::Ptr color;
};

/// Reads grid `grid` (a float level set) and `Cd` from a .vdb file.
/// InputError for an unreadable file, a missing grid (the message lists the
/// file's grids) or one that is not a float level set.
LevelSetFile readLevelSet(const std::string& path, const std::string& grid = "surface");

/// Trilinear lookups of a grid at world-space points, for one thread: it
/// owns the accessor its sampler refers to, so it is neither copied nor moved.
template <class GridT>
class WorldSampler {
public:
    explicit WorldSampler(const GridT& grid) : accessor_(grid.getConstAccessor()), sampler_(accessor_, grid.transform())
    {
    }
    WorldSampler(const WorldSampler&) = delete;
    WorldSampler& operator=(const WorldSampler&) = delete;
    typename GridT::ValueType operator()(const openvdb::Vec3d& world) const { return sampler_.wsSample(world); }

private:
    typename GridT::ConstAccessor accessor_;
    openvdb::tools::GridSampler<typename GridT::ConstAccessor, openvdb::tools::BoxSampler> sampler_;
};

/// Runs one(input, output) for a single file, or, when input or output holds
/// a run of `#` or `frames` is given, for every frame of `frames` with the
/// frame number in both names; first checks every input exists and calls
/// checkOutput on the first output, so that bad input fails before any work.
void forEachFile(const std::string& input, const std::string& output, const std::string& frames,
                 const std::function<void(const std::string&)>& checkOutput,
                 const std::function<void(const std::string&, const std::string&)>& one);

}  // namespace cambium
