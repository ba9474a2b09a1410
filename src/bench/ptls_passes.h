// cambium — the ParticlesToLevelSet peer's two passes, each a translation
// unit of its own.  OpenVDB instantiates the rasteriser's attribute grid even
// without attributes: its construction (ptls_peer.cpp), the rasterisation and
// the finishing pass compile in 16, 19 and 18 s apart, 39 s in one file, past
// the incremental build's 30 s.
#pragma once

#include "bench/ptls_peer.h"

#include <openvdb/tools/ParticlesToLevelSet.h>

namespace cambium {

using PeerRaster = openvdb::tools::ParticlesToLevelSet<openvdb::FloatGrid>;

/// raster.rasterizeSpheres(spheres) (ptls_rasterize.cpp).
void rasterizePeerSpheres(PeerRaster& raster, const PeerSpheres& spheres);
/// raster.finalize(true): the rasterised spheres as a pruned level set
/// (ptls_finalize.cpp).
void finalizePeerRaster(PeerRaster& raster);

}  // namespace cambium
