// cambium — the project's hashes, in one place.  Each is a persisted format
// or a cache key, so each keeps its exact definition: mix64 is SplitMix64's
// finaliser (also the growth model's random stream, core/random.h);
// Checksum64 is the `cambium_checksum` of .vdb files; fnv1a64 keys the
// `cambium_sequence` metadata (--resume compares it with files already
// written); hash128 keys the leaf value cache.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <string>

namespace cambium {

/// SplitMix64's finaliser: a bijective 64-bit mix (seeded streams, hashes).
inline uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

/// A 64-bit checksum of a byte stream, fed in pieces of any size: each
/// 8-byte little-endian word mixed into the state (mix64), the length last.
/// Not cryptographic: it finds damage, not tampering.
class Checksum64 {
public:
    void update(const char* data, size_t n)
    {
        length_ += n;
        while (n > 0) {
            for (; fill_ == 0 && n >= 8; data += 8, n -= 8) {  // (whole words: no copy)
                uint64_t w;
                std::memcpy(&w, data, 8);
                mix(w);
            }
            if (n == 0)
                break;
            const size_t take = std::min(n, size_t(8) - fill_);
            std::memcpy(word_ + fill_, data, take);
            fill_ += take;
            data += take;
            n -= take;
            if (fill_ == 8)
                mixWord();
        }
    }
    uint64_t value() const
    {
        Checksum64 last = *this;
        if (last.fill_ > 0) {
            std::memset(last.word_ + last.fill_, 0, 8 - last.fill_);
            last.mixWord();
        }
        return mix64(last.state_ ^ last.length_);
    }

private:
    void mix(uint64_t w) { state_ = mix64(state_ ^ w) + 0x9e3779b97f4a7c15ull; }
    void mixWord()
    {
        uint64_t w;
        std::memcpy(&w, word_, 8);
        mix(w);
        fill_ = 0;
    }
    uint64_t state_ = 0x243f6a8885a308d3ull, length_ = 0;
    char word_[8] = {};
    size_t fill_ = 0;
};

/// FNV-1a, 64 bits, of a string, continuing from `h` (so that several
/// strings hash as one).
inline uint64_t fnv1a64(const std::string& s, uint64_t h = 0xcbf29ce484222325ull)
{
    for (unsigned char c : s) {
        h ^= c;
        h *= 0x100000001b3ull;
    }
    return h;
}

/// Two independent 64-bit hashes of a sequence of doubles' bits (each word
/// mixed with SplitMix64's finaliser into two differently seeded lanes).
inline std::array<uint64_t, 2> hash128(const double* v, size_t n)
{
    uint64_t a = 0x243f6a8885a308d3ull ^ n, b = 0x13198a2e03707344ull + n;
    for (const double* end = v + n; v != end; ++v) {
        const double d = *v;
        uint64_t x;
        std::memcpy(&x, &d, 8);
        a = mix64(a ^ x) + 0x9e3779b97f4a7c15ull;
        b = mix64(b + x * 0xd6e8feb86659fd93ull) ^ 0xa0761d6478bd642full;
    }
    return {a, b};
}

}  // namespace cambium
