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

/// Whether encodeLeafValues writes the leaves of a grid stored with these
/// compression flags, as full floats or colours (`half` false).
bool encodesLeafValues(uint32_t compression, bool half);

/// A leaf's bytes as openvdb::io's LeafNode::writeBuffers writes them (not
/// as halves) on a stream whose data compression is `compression` and whose
/// grid background is `background`: the value mask, the inactive-value code
/// OpenVDB's MaskCompress chooses and what it keeps, the values (Blosc as
/// OpenVDB calls it, or raw), byte for byte, into `out` (replaced).
/// `scratch`: the active values' room, reused.  OpenVDB's version scans the
/// inactive voxels through a mask iterator and compares each, and allocates
/// twice a leaf: a fifth of a bake's packing.
template <class ValueT>
void encodeLeafValues(const openvdb::util::NodeMask<3>& mask, const ValueT* values,
                      const ValueT& background, uint32_t compression, std::vector<char>& out,
                      std::vector<ValueT>& scratch);

}  // namespace cambium
