// cambium — the random numbers: a Mersenne Twister that can follow Python's
// random module draw for draw, and uniform reals from std::mt19937_64 that do
// not depend on which standard library built the binary.
#pragma once

#include "core/hash.h"

#include <cmath>
#include <cstdint>
#include <random>

namespace cambium {

/// The 32-bit Mersenne Twister MT19937 (Matsumoto and Nishimura's mt19937ar),
/// written out rather than taken from <random> because Python seeds it through
/// init_by_array, which std::mt19937 does not offer (its seed_seq scrambles the
/// key differently).  Owning the state lets a generator here repeat, to the
/// bit, a workload first written with Python's random.Random.
class Mt19937 {
public:
    Mt19937() { seed(5489u); }

    /// The stream of std::mt19937(s): the state filled by init_genrand.
    void seed(uint32_t s)
    {
        state_[0] = s;
        for (int i = 1; i < kN; ++i)
            state_[i] = 1812433253u * (state_[i - 1] ^ (state_[i - 1] >> 30)) + uint32_t(i);
        index_ = kN;
    }

    /// The stream of Python's random.Random(s) for 0 <= s < 2^32: Python keys
    /// init_by_array with the 32-bit words of abs(seed), here the single word s.
    void seedPython(uint32_t s) { seedByArray(&s, 1); }

    /// mt19937ar's init_by_array: a fixed init_genrand, then the key mixed in.
    void seedByArray(const uint32_t* key, int length)
    {
        seed(19650218u);
        int i = 1, j = 0;
        for (int k = kN > length ? kN : length; k > 0; --k) {
            state_[i] = (state_[i] ^ ((state_[i - 1] ^ (state_[i - 1] >> 30)) * 1664525u)) +
                        key[j] + uint32_t(j);
            if (++i >= kN) {
                state_[0] = state_[kN - 1];
                i = 1;
            }
            if (++j >= length)
                j = 0;
        }
        for (int k = kN - 1; k > 0; --k) {
            state_[i] =
                (state_[i] ^ ((state_[i - 1] ^ (state_[i - 1] >> 30)) * 1566083941u)) - uint32_t(i);
            if (++i >= kN) {
                state_[0] = state_[kN - 1];
                i = 1;
            }
        }
        state_[0] = 0x80000000u;  // the state is never all zero
        index_ = kN;
    }

    /// The next 32-bit output (genrand_int32, tempered).
    uint32_t next()
    {
        if (index_ >= kN)
            twist();
        uint32_t y = state_[index_++];
        y ^= y >> 11;
        y ^= (y << 7) & 0x9d2c5680u;
        y ^= (y << 15) & 0xefc60000u;
        y ^= y >> 18;
        return y;
    }

    /// A double in [0, 1) with 53 random bits from two outputs (genrand_res53),
    /// the value Python's random.random() returns from the same state.
    double random01()
    {
        const uint32_t a = next() >> 5, b = next() >> 6;
        return (a * 67108864.0 + b) * (1.0 / 9007199254740992.0);
    }

    /// Python's random.uniform(a, b), including its order of operations.
    double uniform(double a, double b) { return a + (b - a) * random01(); }

private:
    static constexpr int kN = 624, kM = 397;

    void twist()
    {
        for (int k = 0; k < kN; ++k) {
            const uint32_t y = (state_[k] & 0x80000000u) | (state_[(k + 1) % kN] & 0x7fffffffu);
            state_[k] = state_[(k + kM) % kN] ^ (y >> 1) ^ ((y & 1u) ? 0x9908b0dfu : 0u);
        }
        index_ = 0;
    }

    uint32_t state_[kN];
    int index_ = kN;
};

/// A double in [0, 1) from one draw of g: what libstdc++'s
/// std::uniform_real_distribution<double>(0, 1)(g) returns (its
/// generate_canonical<double, 53>: the 64-bit draw rounded to a double and
/// scaled by 2^-64, a draw that rounds up to 1 taken as the largest double
/// below 1).  The standard fixes the engines' outputs but not how the
/// distributions use them, so libc++ and MSVC give other numbers from the same
/// engine; this is for seeded models that must grow the same tree everywhere.
inline double uniformCanonical(std::mt19937_64& g)
{
    static_assert(std::mt19937_64::min() == 0 && std::mt19937_64::max() == ~uint64_t(0),
                  "a full 64-bit engine");
    // libstdc++ scales by a long double 2^64 stored into a double: a power of
    // two either way, so the division is exact and long double plays no part.
    const double ret = double(g()) / 18446744073709551616.0;
    return ret >= 1.0 ? std::nextafter(1.0, 0.0) : ret;
}

/// A double in [a, b) (b itself possible through rounding) from one draw of g:
/// libstdc++'s std::uniform_real_distribution<double>(a, b)(g), in its order
/// of operations.
inline double uniformReal(std::mt19937_64& g, double a, double b)
{
    return uniformCanonical(g) * (b - a) + a;
}

/// A double in [0, 1) with 53 bits from a SplitMix64 step of `state`: the
/// growth model's stream, one state per branch, cheap to seed per use.
inline double splitMix01(uint64_t& state)
{
    return double(mix64(state += 0x9e3779b97f4a7c15ull) >> 11) * 0x1.0p-53;
}

}  // namespace cambium
