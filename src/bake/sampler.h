// cambium — sampling a FieldProgram on 8^3 leaves of voxels: with OpenCL (the
// kernels of kernels/sample.cl) or on the CPU with the same interpreter.
#pragma once

#include "field/program.h"

#include <cstdint>
#include <memory>
#include <vector>

namespace cambium {

class OpenCLContext;

/// Samples per voxel: value, gradient (3), colour (3).
constexpr int kSampleChannels = 7;
constexpr int kLeafVoxels = 512;

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
    /// Samples every voxel of every leaf: out receives, per leaf, 7 planes of
    /// 512 floats (value, gx, gy, gz, r, g, b), x fastest then y then z.
    virtual void sampleLeaves(const std::vector<Instr>& codePool, const std::vector<LeafJob>& leaves,
                              double voxelSize, float* out) = 0;
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
