// cambium — sampling a FieldProgram on 8^3 leaves of voxels: with OpenCL (the
// kernels of kernels/sample.cl) or on the CPU with the same interpreter.
#pragma once

#include "field/program.h"

#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

namespace cambium {

class OpenCLContext;

/// Samples per voxel: value, gradient (3), colour (3).
constexpr int kSampleChannels = 7;
constexpr int kLeafVoxels = 512;

/// A voxel of a leaf where gradient and colour are wanted.
struct SurfaceQuery {
    int32_t leaf;    ///< index into the leaf table
    uint16_t voxel;  ///< x + 8 y + 64 z
};

/// How far (voxels) a surface sample's Newton step may go from its voxel:
/// a leaf's program must compute the field over its voxels' box padded by
/// this much (findBandLeaves specialises them so).
constexpr double kSurfaceReach = 1.0;

/// What the sampler answers for a surface voxel (kernels/cb_program.h,
/// cb_surface_step): the Newton step from the voxel toward the surface
/// (voxels, at most kSurfaceReach long) and where it lands F - T, the
/// gradient and the colour.  IEEE halves (enough for distances within a
/// voxel and for normals) and 8-bit colour.
struct SurfaceSample {
    uint16_t step[3];
    uint16_t value;
    uint16_t gradient[3];
    uint8_t color[3];
};

/// IEEE half -> float, exactly (every half is a float), by moving the bits:
/// inline and branch-free, since the assembly converts tens of millions of
/// values and gradients.
inline float halfToFloat(uint16_t h)
{
    const uint32_t sign = uint32_t(h & 0x8000u) << 16, em = h & 0x7FFFu;
    // Exponent and mantissa moved into a float's places read as the value
    // times 2^-112, exactly, for normal and subnormal halves (a subnormal half
    // becomes a subnormal float, scaled back to a normal one); infinities and
    // NaNs take exponent 255.
    uint32_t bits = em << 13;
    float f;
    std::memcpy(&f, &bits, 4);
    f *= 0x1p112f;
    std::memcpy(&bits, &f, 4);
    bits = em >= 0x7C00u ? (0x7F800000u | ((em & 0x3FFu) << 13)) : bits;
    bits |= sign;
    std::memcpy(&f, &bits, 4);
    return f;
}
/// float -> IEEE half, rounded to nearest even (NaN -> a quiet NaN): inline,
/// since a bake converts tens of millions of step, gradient and normal
/// components.
inline uint16_t floatToHalf(float f)
{
    uint32_t x;
    std::memcpy(&x, &f, 4);
    const uint32_t sign = (x >> 16) & 0x8000u;
    x &= 0x7FFFFFFFu;
    uint32_t h;
    if (x >= 0x47800000u) {  // |f| >= 2^16 (past the largest half), infinities, NaNs
        h = x > 0x7F800000u ? 0x7E00u : 0x7C00u;
    } else if (x < 0x38800000u) {
        // |f| < 2^-14: a subnormal half, whose unit is 2^-24, the spacing of
        // floats in [0.5, 1): the addition rounds |f| to it, to nearest even,
        // and leaves the count in the mantissa.
        float a;
        std::memcpy(&a, &x, 4);
        a += 0.5f;
        std::memcpy(&h, &a, 4);
        h -= 0x3F000000u;
    } else {
        // The exponent rebiased (127 -> 15), the 13 bits below the half's
        // mantissa rounded to nearest even (a carry into the exponent is right,
        // up to infinity).
        h = (x - 0x38000000u + 0xFFFu + ((x >> 13) & 1u)) >> 13;
    }
    return uint16_t(h | sign);
}
/// Whether a half is positive and not zero (F - T > 0: inside).
inline bool halfPositive(uint16_t h)
{
    return int16_t(h) > 0;
}

/// A leaf to sample: its origin in voxel index space and its program, a
/// range of a shared code pool.
struct LeafJob {
    int32_t origin[3];
    int32_t codeOffset;
    int32_t codeLength;
};

class FieldSampler {
public:
    virtual ~FieldSampler() = default;
    /// Fixes the program whose parameter table the leaf programs use.
    virtual void setProgram(const FieldProgram& program) = 0;
    /// Fixes the pool of leaf programs that LeafJobs refer to, and the
    /// bake's leaves that sampleSurface's queries name (both kept until the
    /// next call: the leaves are uploaded once, not per query batch).
    virtual void setLeaves(const std::vector<LeafJob>& leaves,
                           const std::vector<Instr>& codePool) = 0;
    /// F - T at every voxel of leaves[begin, end), as IEEE halves (rounded to
    /// nearest even, from F - T in float): 512 per leaf into out, voxel
    /// x + 8 y + 64 z.  Relative precision where it matters, next to the
    /// surface; the sign bit tells the side (inside: positive, not zero).
    virtual void sampleValues(const std::vector<LeafJob>& leaves, size_t begin, size_t end,
                              double voxelSize, uint16_t* out) = 0;
    /// The surface samples of the queried voxels (of setLeaves's leaves),
    /// `count` queries grouped by leaf, into out[0, count).
    virtual void sampleSurface(const SurfaceQuery* queries, size_t count, double voxelSize,
                               SurfaceSample* out) = 0;
    /// Evaluates `code` at arbitrary points (tests and diagnostics):
    /// out = 7 planes of points.size() floats.
    virtual std::vector<float> samplePoints(Code code, const std::vector<glm::dvec3>& points) = 0;
    virtual const char* name() const = 0;
    /// Whether setLeaves copies the leaves and their programs (to a device),
    /// so that the caller's may go once it returns.
    virtual bool copiesLeaves() const { return false; }
};

/// The OpenCL path.  Throws OpenCLError (no platform, build failure) from the
/// constructor.  The kernels are built once per sampler and reused across frames.
std::unique_ptr<FieldSampler> makeOpenCLSampler();

/// The CPU path: FieldProgram::evaluate in double precision, TBB over leaves.
std::unique_ptr<FieldSampler> makeCpuSampler();

}  // namespace cambium
