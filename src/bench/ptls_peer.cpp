// cambium — the ParticlesToLevelSet peer of `cambium bench bake`.
#include "bench/ptls_peer.h"

#include "bench/ptls_passes.h"

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>

namespace cambium {

PeerSpheres internodeSpheres(const Skeleton& skeleton)
{
    PeerSpheres sp;
    for (const Internode& n : skeleton.internodes) {
        const double L = glm::length(n.p1 - n.p0), rmin = std::min(n.r0, n.r1);
        const int steps = std::max(1, int(std::ceil(L / (0.5 * rmin))));
        for (int k = 0; k <= steps; ++k) {
            const double t = double(k) / steps;
            const glm::dvec3 q = n.p0 + t * (n.p1 - n.p0);
            sp.p.emplace_back(q.x, q.y, q.z);
            sp.r.push_back(n.r0 + t * (n.r1 - n.r0));
        }
    }
    return sp;
}

openvdb::FloatGrid::Ptr ptlsLevelSet(const PeerSpheres& spheres, double voxelSize, double halfWidth)
{
    auto grid = openvdb::FloatGrid::create(float(halfWidth * voxelSize));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    PeerRaster raster(*grid);
    raster.setRmin(1.0);
    rasterizePeerSpheres(raster, spheres);
    finalizePeerRaster(raster);
    return grid;
}

}  // namespace cambium
