// cambium — the ParticlesToLevelSet peer's finishing pass (ptls_passes.h).
#include "bench/ptls_passes.h"

namespace cambium {

void finalizePeerRaster(PeerRaster& raster)
{
    raster.finalize(true);
}

}  // namespace cambium
