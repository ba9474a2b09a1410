// cambium — small math shared by the models and the bake.
#pragma once

#include <glm/glm.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace cambium {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegree = kPi / 180.0;  ///< radians per degree

/// 0 below e0, 1 above e1, the cubic 3u^2 - 2u^3 of u = (x - e0) / (e1 - e0)
/// between (C1, flat at both ends); a step at e1 when e1 <= e0.
inline double smoothstep(double e0, double e1, double x)
{
    if (!(e1 > e0))
        return x >= e1 ? 1.0 : 0.0;
    const double u = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return u * u * (3.0 - 2.0 * u);
}

/// v rotated by `angle` radians about the unit `axis` (Rodrigues).
inline glm::dvec3 rotateAbout(const glm::dvec3& v, const glm::dvec3& axis, double angle)
{
    const double c = std::cos(angle), s = std::sin(angle);
    return v * c + glm::cross(axis, v) * s + axis * glm::dot(axis, v) * (1.0 - c);
}

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
    void mixWord()
    {
        uint64_t w;
        std::memcpy(&w, word_, 8);
        state_ = mix64(state_ ^ w) + 0x9e3779b97f4a7c15ull;
        fill_ = 0;
    }
    uint64_t state_ = 0x243f6a8885a308d3ull, length_ = 0;
    char word_[8] = {};
    size_t fill_ = 0;
};

}  // namespace cambium
