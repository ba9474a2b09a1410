// cambium — a leaf's values decoded straight from its bytes in a .vdb file,
// for the layout cambium writes and most tools write (full floats or colours,
// Blosc or no compression, active values only): what
// openvdb::io::readCompressedValues does, without its stream, its two
// allocations a leaf and its voxel-by-voxel branches on the masks' bits.
// Other layouts (halves, zip, files older than mask compression) are left to
// OpenVDB's own decoder.
#pragma once

#include "io/leaf_layout.h"

#include <openvdb/util/NodeMasks.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cambium {

/// Whether decodeLeafValues reads the leaves of a grid stored as `s` in a
/// file of format version `fileVersion`.
bool decodesLeafValues(const StoredValues& s, uint32_t fileVersion);

/// The 512 values of the leaf whose value mask is `mask`, from its `n` bytes
/// at `p` (the mask first, then its inactive-value code and what follows, as
/// openvdb::io::writeCompressedValues lays them out and valuesBlock measured
/// them) into `out`; inactive voxels take `background`'s or the stored
/// inactive values, as OpenVDB's reader gives them.  `scratch`: the active
/// values' room, reused.  The empty string, or why the values cannot be
/// decoded (OpenVDB's reader throws there too).
template <class ValueT>
std::string decodeLeafValues(const char* p, size_t n, const openvdb::util::NodeMask<3>& mask,
                             const StoredValues& s, const ValueT& background, ValueT* out,
                             std::vector<ValueT>& scratch);

}  // namespace cambium
