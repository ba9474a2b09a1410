// cambium — the peer of `cambium bench bake`: a level set of the benchmark
// tree made the way a user of OpenVDB makes one today, with
// ParticlesToLevelSet over spheres along every internode.  Used in process
// (bake_bench.cpp's row (d)) and as a whole program (tools/ptls_bake.cpp,
// the binary `cambium-ptls`, timed beside `cambium bake`).
#pragma once

#include "io/grids.h"
#include "model/skeleton.h"

#include <vector>

namespace cambium {

/// Spheres along every internode, spaced half the thinner end's radius
/// apart, radii interpolated along the internode: the tapered cones as a
/// particle rasteriser can take them.
struct PeerSpheres {
    std::vector<openvdb::Vec3R> p;
    std::vector<openvdb::Real> r;
    using PosType = openvdb::Vec3R;
    size_t size() const { return p.size(); }
    void getPos(size_t n, openvdb::Vec3R& xyz) const { xyz = p[n]; }
    void getPosRad(size_t n, openvdb::Vec3R& xyz, openvdb::Real& rad) const
    {
        xyz = p[n];
        rad = r[n];
    }
};

PeerSpheres internodeSpheres(const Skeleton& skeleton);

/// The spheres' level set: voxel size `voxelSize`, narrow band `halfWidth`
/// voxels each side, minimum radius lowered to 1 voxel (the default 1.5
/// would drop thin twigs).
openvdb::FloatGrid::Ptr ptlsLevelSet(const PeerSpheres& spheres, double voxelSize,
                                     double halfWidth);

}  // namespace cambium
