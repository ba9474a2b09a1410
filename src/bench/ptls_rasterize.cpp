// cambium — the ParticlesToLevelSet peer's rasterisation (ptls_passes.h).
#include "bench/ptls_passes.h"

namespace cambium {

void rasterizePeerSpheres(PeerRaster& raster, const PeerSpheres& spheres)
{
    raster.rasterizeSpheres(spheres);
}

}  // namespace cambium
