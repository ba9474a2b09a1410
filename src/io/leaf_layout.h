// cambium — a node's values in a .vdb grid, as OpenVDB's
// writeCompressedValues lays them out: one reading for the writer of packed
// leaves (io/vdb.cpp), the parallel reader (io/vdb_read.cpp) and the check of
// a tree's structure (io/vdb_tree.cpp).
#pragma once

#include "io/grids.h"

#include <openvdb/io/Compression.h>

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

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

/// How many inactive values a node's inactive-value code stores after it
/// (0, 1 or 2), and whether a selection mask follows them: what
/// openvdb::io::writeCompressedValues writes for each code.
inline int storedInactiveValues(int8_t code)
{
    namespace io = openvdb::io;
    return code == io::MASK_AND_TWO_INACTIVE_VALS                                              ? 2
           : code == io::NO_MASK_AND_ONE_INACTIVE_VAL || code == io::MASK_AND_ONE_INACTIVE_VAL ? 1
                                                                                               : 0;
}
inline bool storesSelectionMask(int8_t code)
{
    namespace io = openvdb::io;
    return code == io::MASK_AND_NO_INACTIVE_VALS || code == io::MASK_AND_ONE_INACTIVE_VAL ||
           code == io::MASK_AND_TWO_INACTIVE_VALS;
}

/// The bytes after a node's inactive-value code: its inactive values (each
/// `valueBytes`, as the tree holds them even where it stores halves) and
/// selection mask (`maskBytes`); SIZE_MAX for a code OpenVDB does not write.
inline size_t valuesHeaderBytes(int8_t code, size_t valueBytes, size_t maskBytes)
{
    namespace io = openvdb::io;
    if (code < io::NO_MASK_OR_INACTIVE_VALS || code > io::NO_MASK_AND_ALL_VALS)
        return std::numeric_limits<size_t>::max();
    return size_t(storedInactiveValues(code)) * valueBytes +
           (storesSelectionMask(code) ? maskBytes : 0);
}

/// The header of the leaf whose value mask is `mask`, from its `left` bytes at `p`.
template <class ValueT, class MaskT>
LeafHeader readLeafHeader(const char* p, size_t left, const MaskT& mask)
{
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
    const size_t rest = valuesHeaderBytes(h.code, sizeof(ValueT), maskBytes);
    if (rest == std::numeric_limits<size_t>::max()) {
        h.fault = LeafHeader::Fault::UnknownCode;
        return h;
    }
    h.length = maskBytes + 1 + rest;
    return h;
}

/// How a grid stores a node's values after their header (what
/// openvdb::io::readData reads).
struct StoredValues {
    uint32_t compression = 0;  ///< the grid's openvdb::io::COMPRESS_* flags
    size_t storedBytes = 0;    ///< a value as stored (a half's where the grid holds halves)
    bool half = false;         ///< halves: nothing at all is written for no values
};

enum class BlockFault {
    None,
    Short,  ///< it runs past the bytes given
    Size,   ///< its size cannot be that of its values
};

/// The block of `count` values at `p` (of `left` bytes) as a grid stored as
/// `s` holds them: its length into `length` (where its size could be read,
/// also when it runs past `left`).  Size where OpenVDB's reader would read
/// past a buffer: a raw block of another length than its values' (OpenVDB
/// reads the length a block claims into a buffer of `count` values before
/// it compares the two), or a blosc block whose header claims more bytes
/// than the block holds (blosc reads as many as its header claims).  Other
/// lies (a compressed block that unpacks to another size) OpenVDB's
/// decoders find themselves.
inline BlockFault valuesBlock(const char* p, size_t left, const StoredValues& s, uint64_t count,
                              size_t& length)
{
    namespace io = openvdb::io;
    const uint64_t raw = count * s.storedBytes;
    length = 0;
    if (s.half && count == 0)
        return BlockFault::None;
    if (!(s.compression & (io::COMPRESS_BLOSC | io::COMPRESS_ZIP))) {
        length = raw;
        return left >= length ? BlockFault::None : BlockFault::Short;
    }
    int64_t n;
    if (left < sizeof n)
        return BlockFault::Short;
    std::memcpy(&n, p, sizeof n);
    if (n <= 0) {  // stored raw, -n bytes
        if (n != -int64_t(raw))
            return BlockFault::Size;
        length = sizeof n + raw;
    } else {
        if (uint64_t(n) > (uint64_t(1) << 40))
            return BlockFault::Size;
        length = sizeof n + uint64_t(n);
        if (s.compression & io::COMPRESS_BLOSC) {
            // Blosc's header: versions, flags and type size, then the sizes
            // unpacked, of a block and packed.
            constexpr size_t kHeader = 16;
            if (uint64_t(n) < kHeader)
                return BlockFault::Size;
            if (left < sizeof n + kHeader)
                return BlockFault::Short;
            uint32_t packed;
            std::memcpy(&packed, p + sizeof n + 12, 4);
            if (packed < kHeader || packed > uint64_t(n))
                return BlockFault::Size;
        }
    }
    return left >= length ? BlockFault::None : BlockFault::Short;
}

}  // namespace cambium
