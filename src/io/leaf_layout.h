// cambium — the header of a leaf's bytes in a .vdb grid block, as OpenVDB's
// writeCompressedValues lays it out: one reading for the writer of packed
// leaves (io/vdb.cpp) and the parallel reader (io/vdb_read.cpp).
#pragma once

#include "io/grids.h"

#include <openvdb/io/Compression.h>

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace cambium {

/// A leaf's header: the value mask, the inactive-value code, up to two
/// inactive values and a selection mask, then the values.
struct LeafHeader {
    enum class Fault {
        None,
        Short,        ///< fewer bytes than the mask and the code
        MaskDiffers,  ///< the bytes begin with another value mask than the leaf's
        UnknownCode,  ///< an inactive-value code OpenVDB does not write
    };
    Fault fault = Fault::None;
    int8_t code = 0;    ///< openvdb::io's NO_MASK_OR_INACTIVE_VALS ... NO_MASK_AND_ALL_VALS
    size_t length = 0;  ///< where the values begin (may lie past the bytes given)
};

/// The header of the leaf whose value mask is `mask`, from its `left` bytes at `p`.
template <class ValueT, class MaskT>
LeafHeader readLeafHeader(const char* p, size_t left, const MaskT& mask)
{
    namespace io = openvdb::io;
    using Word = typename MaskT::Word;
    constexpr size_t maskBytes = sizeof(Word) * MaskT::WORD_COUNT;
    LeafHeader h;
    if (left < maskBytes + 1) {
        h.fault = LeafHeader::Fault::Short;
        return h;
    }
    for (openvdb::Index w = 0; w < MaskT::WORD_COUNT; ++w) {
        Word word;
        std::memcpy(&word, p + w * sizeof word, sizeof word);
        if (word != mask.template getWord<Word>(w)) {
            h.fault = LeafHeader::Fault::MaskDiffers;
            return h;
        }
    }
    h.code = int8_t(p[maskBytes]);
    if (h.code < io::NO_MASK_OR_INACTIVE_VALS || h.code > io::NO_MASK_AND_ALL_VALS) {
        h.fault = LeafHeader::Fault::UnknownCode;
        return h;
    }
    h.length = maskBytes + 1;
    if (h.code == io::NO_MASK_AND_ONE_INACTIVE_VAL || h.code == io::MASK_AND_ONE_INACTIVE_VAL)
        h.length += sizeof(ValueT);
    if (h.code == io::MASK_AND_TWO_INACTIVE_VALS)
        h.length += 2 * sizeof(ValueT);
    if (h.code == io::MASK_AND_NO_INACTIVE_VALS || h.code == io::MASK_AND_ONE_INACTIVE_VAL ||
        h.code == io::MASK_AND_TWO_INACTIVE_VALS)
        h.length += maskBytes;  // the selection mask
    return h;
}

}  // namespace cambium
