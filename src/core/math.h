// cambium — small math shared by the models and the bake.
#pragma once

#include <glm/glm.hpp>

#include <algorithm>
#include <string_view>
#include <cmath>
#include <cstdint>
#include <cstring>

namespace cambium {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegree = kPi / 180.0;  ///< radians per degree
/// The farthest any coordinate cambium reads, synthesises or bakes may lie
/// from the origin: beyond it a float keeps no sub-unit detail and bounds,
/// index spaces and Embree's builds overflow.
constexpr double kFarthestCoordinate = 1e15;

/// The farthest a surface may lie from the origin, in voxels: positions
/// there are single-precision floats in meshes, renders and the kernels, and
/// at 2^20 voxels out neighbouring floats are an eighth of a voxel apart (a
/// sphere 5e8 voxels out meshed as two planes of vertices, exit 0).
constexpr double kMaxVoxelsFromOrigin = double(1 << 20);

/// The words that say why (the end of a message naming the distance).
constexpr const char* kFloatPrecisionReason =
    "where single-precision positions (meshes, renders, the kernels) are more than an eighth "
    "of a voxel apart; move the model nearer the origin or use a larger voxel size";

/// A half float's largest value: what `--half` stores, and the largest
/// colour a bake paints (a photo's pixels are at most this).
constexpr double kLargestHalf = 65504.0;

/// The largest seed a file or an option takes (whole numbers from 0: a
/// double holds each exactly).
constexpr long long kMaxSeed = 9000000000000000LL;

/// Whether `t` is 1 to `most` decimal digits (a job id, an exit status, a
/// frame number in a file's name).
inline bool allDigits(std::string_view t, size_t most)
{
    return !t.empty() && t.size() <= most &&
           std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; });
}

/// Whether strtod's number [begin, end) was written in hexadecimal (0x10):
/// the text formats here are decimal, and a hex number in them is a typo
/// or another format's, read as 16 without a word.
inline bool writtenInHex(const char* begin, const char* end)
{
    return std::find_if(begin, end, [](char c) { return c == 'x' || c == 'X'; }) != end;
}

/// 0 below e0, 1 above e1, the cubic 3u^2 - 2u^3 of u = (x - e0) / (e1 - e0)
/// between (C1, flat at both ends); a step at e1 when e1 <= e0.
inline double smoothstep(double e0, double e1, double x)
{
    if (!(e1 > e0))
        return x >= e1 ? 1.0 : 0.0;
    const double u = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return u * u * (3.0 - 2.0 * u);
}

/// The direction of a finite v as a unit vector, (0, 0, 0) for the zero
/// vector: scaled by its largest component first, so that a direction
/// written as [1e300, 1e300, 0] does not overflow its length.
inline glm::dvec3 unitDirection(const glm::dvec3& v)
{
    const double big = std::max({std::fabs(v.x), std::fabs(v.y), std::fabs(v.z)});
    if (!(big > 0.0) || !std::isfinite(big))
        return glm::dvec3(0.0);
    return glm::normalize(v / big);
}

/// v rotated by `angle` radians about the unit `axis` (Rodrigues).
inline glm::dvec3 rotateAbout(const glm::dvec3& v, const glm::dvec3& axis, double angle)
{
    const double c = std::cos(angle), s = std::sin(angle);
    return v * c + glm::cross(axis, v) * s + axis * glm::dot(axis, v) * (1.0 - c);
}

/// The unit vector across `axis` (unit) nearest v: v without its component
/// along the axis, normalised; when v is (nearly) along the axis, x (or y
/// when the axis is near x) made so.
inline glm::dvec3 unitAcross(const glm::dvec3& v, const glm::dvec3& axis)
{
    const glm::dvec3 w = v - glm::dot(v, axis) * axis;
    const double len = glm::length(w);
    if (len > 1e-6)
        return w / len;
    const glm::dvec3 other = std::fabs(axis.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    return glm::normalize(other - glm::dot(other, axis) * axis);
}

}  // namespace cambium
