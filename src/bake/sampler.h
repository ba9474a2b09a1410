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

/// Gradient (IEEE half precision: enough for distances within a voxel and for
/// normals) and colour (8 bits) at a queried voxel.
struct SurfaceSample {
    uint16_t gradient[3];
    uint8_t color[3];
};

/// IEEE half -> float, exactly (every half is a float), by moving the bits:
/// inline, since the assembly converts tens of millions of gradients.
inline float halfToFloat(uint16_t h)
{
    const uint32_t sign = uint32_t(h & 0x8000u) << 16, e = (h >> 10) & 0x1Fu, m = h & 0x3FFu;
    uint32_t bits;
    if (e == 0x1Fu) {
        bits = sign | 0x7F800000u | (m << 13);  // infinities and NaNs
    } else if (e != 0) {
        bits = sign | ((e + 112u) << 23) | (m << 13);  // normal: rebias 15 -> 127
    } else {
        // Zero or subnormal: m * 2^-24, exact in float.
        const float v = float(m) * 5.9604644775390625e-8f;
        std::memcpy(&bits, &v, 4);
        bits |= sign;
    }
    float f;
    std::memcpy(&f, &bits, 4);
    return f;
}
/// float -> IEEE half, rounded to nearest even.
uint16_t floatToHalf(float f);

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
    /// Fixes the pool of leaf programs that LeafJobs refer to.
    virtual void setLeafCode(const std::vector<Instr>& codePool) = 0;
    /// Values of every voxel of leaves[begin, end): 512 floats per leaf into
    /// out, voxel x + 8 y + 64 z.
    virtual void sampleValues(const std::vector<LeafJob>& leaves, size_t begin, size_t end,
                              double voxelSize, float* out) = 0;
    /// Gradient and colour at the queried voxels, `count` queries grouped by
    /// leaf, into out[0, count).
    virtual void sampleSurface(const std::vector<LeafJob>& leaves, const SurfaceQuery* queries, size_t count,
                               double voxelSize, SurfaceSample* out) = 0;
    /// Evaluates `code` at arbitrary points (tests and diagnostics):
    /// out = 7 planes of points.size() floats.
    virtual std::vector<float> samplePoints(Code code, const std::vector<glm::dvec3>& points) = 0;
    virtual const char* name() const = 0;
};

/// The OpenCL path.  Throws OpenCLError (no platform, build failure) from the
/// constructor.  The kernels are built once per sampler and reused across frames.
std::unique_ptr<FieldSampler> makeOpenCLSampler();

/// The CPU path: FieldProgram::evaluate in double precision, TBB over leaves.
std::unique_ptr<FieldSampler> makeCpuSampler();

}  // namespace cambium
