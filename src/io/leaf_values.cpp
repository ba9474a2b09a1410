// cambium — a leaf's values decoded straight from its bytes, and encoded
// as OpenVDB encodes them (see leaf_values.h).
#include "io/leaf_values.h"

#include <blosc.h>
#include <fmt/format.h>
#include <openvdb/math/Math.h>
#include <openvdb/math/Vec3.h>

#include <cstring>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace cambium {

namespace {

using LeafMask = openvdb::util::NodeMask<3>;
constexpr size_t kVoxels = LeafMask::SIZE;                                    // 512
constexpr size_t kMaskBytes = sizeof(LeafMask::Word) * LeafMask::WORD_COUNT;  // 64

/// The leaf's voxels from its active values in order and its two inactive
/// values, chosen by the selection mask: the loop OpenVDB runs a voxel at a
/// time, a word at a time.  `active` holds one value past the last (read,
/// not used, where the last voxels are inactive).
template <class ValueT>
void expandPortable(const ValueT* active, const LeafMask& mask, const LeafMask& selection,
                    const ValueT inactive[2], ValueT* out)
{
    size_t k = 0;
    for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) {
        const uint64_t on = mask.getWord<uint64_t>(w), pick = selection.getWord<uint64_t>(w);
        ValueT* o = out + 64 * w;
        for (int b = 0; b < 64; ++b) {
            const uint64_t a = (on >> b) & 1u;
            o[b] = a ? active[k] : inactive[(pick >> b) & 1u];
            k += a;
        }
    }
}

#if defined(__x86_64__) && !defined(__clang__)
/// The same for floats, sixteen voxels an instruction (AVX-512's expanding
/// load puts the next active values in the active lanes).
__attribute__((target("avx512f,popcnt"))) void expandAvx512(const float* active,
                                                            const LeafMask& mask,
                                                            const LeafMask& selection,
                                                            const float inactive[2], float* out)
{
    const __m512 v0 = _mm512_set1_ps(inactive[0]), v1 = _mm512_set1_ps(inactive[1]);
    size_t k = 0;
    for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w) {
        const uint64_t on = mask.getWord<uint64_t>(w), pick = selection.getWord<uint64_t>(w);
        for (int q = 0; q < 4; ++q) {
            const __mmask16 a = __mmask16(on >> (16 * q)), s = __mmask16(pick >> (16 * q));
            const __m512 idle = _mm512_mask_blend_ps(s, v0, v1);
            _mm512_storeu_ps(out + 64 * w + 16 * q,
                             _mm512_mask_expandloadu_ps(idle, a, active + k));
            k += size_t(__builtin_popcount(unsigned(a)));
        }
    }
}
#endif

void expand(const float* active, const LeafMask& mask, const LeafMask& selection,
            const float inactive[2], float* out)
{
#if defined(__x86_64__) && !defined(__clang__)
    static const bool avx512 = __builtin_cpu_supports("avx512f");
    if (avx512)
        return expandAvx512(active, mask, selection, inactive, out);
#endif
    expandPortable(active, mask, selection, inactive, out);
}

void expand(const openvdb::Vec3f* active, const LeafMask& mask, const LeafMask& selection,
            const openvdb::Vec3f inactive[2], openvdb::Vec3f* out)
{
    expandPortable(active, mask, selection, inactive, out);
}

}  // namespace

bool decodesLeafValues(const StoredValues& s, uint32_t fileVersion)
{
    namespace io = openvdb::io;
    return !s.half && fileVersion >= openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION &&
           !(s.compression & ~uint32_t(io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK));
}

template <class ValueT>
std::string decodeLeafValues(const char* p, size_t n, const LeafMask& mask, const StoredValues& s,
                             const ValueT& background, ValueT* out, std::vector<ValueT>& scratch)
{
    namespace io = openvdb::io;
    const LeafHeader h = readLeafHeader<ValueT>(p, n, mask);
    if (h.fault != LeafHeader::Fault::None || h.length > n)
        return "its header cannot be read";
    // The inactive values and the selection mask, as readCompressedValues
    // reads them.
    const char* q = p + kMaskBytes + 1;
    ValueT inactive[2] = {
        h.code == io::NO_MASK_OR_INACTIVE_VALS ? background : openvdb::math::negative(background),
        background};
    for (int k = 0; k < storedInactiveValues(h.code); ++k, q += sizeof(ValueT))
        std::memcpy(&inactive[k], q, sizeof(ValueT));
    LeafMask selection;  // (all off: every inactive voxel takes inactive[0])
    if (storesSelectionMask(h.code))
        for (openvdb::Index w = 0; w < LeafMask::WORD_COUNT; ++w)
            std::memcpy(&selection.getWord<uint64_t>(w), q + 8 * w, 8);
    const bool onlyActive =
        (s.compression & io::COMPRESS_ACTIVE_MASK) && h.code != io::NO_MASK_AND_ALL_VALS;
    const size_t count = onlyActive ? mask.countOn() : kVoxels;
    // The values block: straight into the leaf where it holds every voxel.
    ValueT* values = out;
    if (count != kVoxels) {
        scratch.resize(count + 1);
        values = scratch.data();
    }
    const size_t bytes = count * sizeof(ValueT);
    const char* block = p + h.length;
    const size_t left = n - h.length;
    if (s.compression & io::COMPRESS_BLOSC) {
        int64_t packed;
        if (left < sizeof packed)
            return "its values run past its bytes";
        std::memcpy(&packed, block, sizeof packed);
        if (packed <= 0) {  // stored raw
            const uint64_t raw = uint64_t(0) - uint64_t(packed);
            if (raw != bytes || left - sizeof packed < bytes)
                return fmt::format("{} raw bytes where its values take {}", raw, bytes);
            std::memcpy(values, block + sizeof packed, bytes);
        } else {
            // (Blosc reads as many bytes as its header claims: its 16-byte
            // header, the block's size in it at byte 12, within the block)
            constexpr size_t kBloscHeader = 16;
            if (uint64_t(packed) > left - sizeof packed || uint64_t(packed) < kBloscHeader)
                return "its values run past its bytes";
            uint32_t claimed;
            std::memcpy(&claimed, block + sizeof packed + 12, 4);
            if (claimed > uint64_t(packed))
                return "its Blosc header claims more bytes than its block holds";
            const int got = blosc_decompress_ctx(block + sizeof packed, values, bytes, 1);
            if (got < 0 || size_t(got) != bytes)
                return fmt::format("Blosc unpacked {} bytes where its values take {}", got, bytes);
        }
    } else {
        if (left < bytes)
            return "its values run past its bytes";
        std::memcpy(values, block, bytes);
    }
    if (count != kVoxels)
        expand(values, mask, selection, inactive, out);
    return {};
}

bool encodesLeafValues(uint32_t compression, bool half)
{
    namespace io = openvdb::io;
    return !half && !(compression & ~uint32_t(io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK));
}

namespace {

/// Each index of the bits set in `words` (eight of a leaf's mask), in order;
/// `f` returns false to stop.
template <class F>
void forEachBit(const uint64_t* words, F&& f)
{
    for (int w = 0; w < 8; ++w)
        for (uint64_t b = words[w]; b; b &= b - 1)
            if (!f(64 * w + __builtin_ctzll(b)))
                return;
}

template <class T>
void append(std::vector<char>& out, const T& v)
{
    const size_t at = out.size();
    out.resize(at + sizeof v);
    std::memcpy(out.data() + at, &v, sizeof v);
}

}  // namespace

template <class ValueT>
void encodeLeafValues(const LeafMask& mask, const ValueT* values, const ValueT& background,
                      uint32_t compression, std::vector<char>& out, std::vector<ValueT>& scratch)
{
    namespace io = openvdb::io;
    auto eq = [](const ValueT& a, const ValueT& b) { return openvdb::math::isExactlyEqual(a, b); };
    uint64_t on[8], off[8];
    for (openvdb::Index w = 0; w < 8; ++w) {
        on[w] = mask.getWord<uint64_t>(w);
        off[w] = ~on[w];
    }
    out.clear();
    for (uint64_t w : on)
        append(out, w);
    const ValueT* data = values;
    size_t count = kVoxels;
    int8_t code = io::NO_MASK_AND_ALL_VALS;
    if (!(compression & io::COMPRESS_ACTIVE_MASK)) {
        append(out, code);
    } else {
        // MaskCompress: the first two distinct inactive values in the
        // voxels' order (a third: every value is kept).
        ValueT inactive[2] = {background, background};
        int unique = 0;
        forEachBit(off, [&](int i) {
            const ValueT& v = values[i];
            if (!((unique > 0 && eq(v, inactive[0])) || (unique > 1 && eq(v, inactive[1])))) {
                if (unique < 2)
                    inactive[unique] = v;
                ++unique;
            }
            return unique < 3;
        });
        const ValueT minus = openvdb::math::negative(background);
        code = io::NO_MASK_OR_INACTIVE_VALS;
        if (unique == 1) {
            if (!eq(inactive[0], background))
                code = eq(inactive[0], minus) ? io::NO_MASK_AND_MINUS_BG
                                              : io::NO_MASK_AND_ONE_INACTIVE_VAL;
        } else if (unique == 2) {
            if (!eq(inactive[0], background) && !eq(inactive[1], background)) {
                code = io::MASK_AND_TWO_INACTIVE_VALS;
            } else if (eq(inactive[1], background)) {
                code = eq(inactive[0], minus) ? io::MASK_AND_NO_INACTIVE_VALS
                                              : io::MASK_AND_ONE_INACTIVE_VAL;
            } else if (eq(inactive[0], background)) {
                code = eq(inactive[1], minus) ? io::MASK_AND_NO_INACTIVE_VALS
                                              : io::MASK_AND_ONE_INACTIVE_VAL;
                std::swap(inactive[0], inactive[1]);
            }
        } else if (unique > 2) {
            code = io::NO_MASK_AND_ALL_VALS;
        }
        append(out, code);
        for (int k = 0; k < storedInactiveValues(code); ++k)
            append(out, inactive[k]);
        if (code != io::NO_MASK_AND_ALL_VALS) {
            // The active values, in order; and where two inactive values
            // are kept, the mask that picks the second.
            scratch.resize(kVoxels);
            count = 0;
            forEachBit(on, [&](int i) {
                scratch[count++] = values[i];
                return true;
            });
            data = scratch.data();
            if (storesSelectionMask(code)) {
                uint64_t pick[8] = {};
                forEachBit(off, [&](int i) {
                    if (eq(values[i], inactive[1]))
                        pick[i >> 6] |= uint64_t(1) << (i & 63);
                    return true;
                });
                for (uint64_t w : pick)
                    append(out, w);
            }
        }
    }
    // The values, as openvdb::io::writeData and bloscToStream write them.
    const size_t bytes = count * sizeof(ValueT);
    if (!(compression & io::COMPRESS_BLOSC)) {
        out.insert(out.end(), reinterpret_cast<const char*>(data),
                   reinterpret_cast<const char*>(data) + bytes);
        return;
    }
    const size_t at = out.size();
    const int room = int(bytes) + BLOSC_MAX_OVERHEAD;
    out.resize(at + sizeof(int64_t) + size_t(room));
    const int packed =
        blosc_compress_ctx(9, 1, sizeof(float), bytes, data, out.data() + at + sizeof(int64_t),
                           size_t(room), BLOSC_LZ4_COMPNAME, bytes, 1);
    if (packed <= 0) {  // (stored raw, its size negated)
        out.resize(at);
        append(out, -int64_t(bytes));
        out.insert(out.end(), reinterpret_cast<const char*>(data),
                   reinterpret_cast<const char*>(data) + bytes);
        return;
    }
    const int64_t size = packed;
    std::memcpy(out.data() + at, &size, sizeof size);
    out.resize(at + sizeof size + size_t(packed));
}

template void encodeLeafValues<float>(const LeafMask&, const float*, const float&, uint32_t,
                                      std::vector<char>&, std::vector<float>&);
template void encodeLeafValues<openvdb::Vec3f>(const LeafMask&, const openvdb::Vec3f*,
                                               const openvdb::Vec3f&, uint32_t, std::vector<char>&,
                                               std::vector<openvdb::Vec3f>&);

template std::string decodeLeafValues<float>(const char*, size_t, const LeafMask&,
                                             const StoredValues&, const float&, float*,
                                             std::vector<float>&);
template std::string decodeLeafValues<openvdb::Vec3f>(const char*, size_t, const LeafMask&,
                                                      const StoredValues&, const openvdb::Vec3f&,
                                                      openvdb::Vec3f*,
                                                      std::vector<openvdb::Vec3f>&);

}  // namespace cambium
