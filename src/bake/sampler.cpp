// cambium — leaf samplers (OpenCL and CPU).
#include "bake/sampler.h"

#include "bake/cl_runtime.h"
#include "bake/kernel_sources.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <mutex>

namespace cambium {

namespace {

class CpuSampler final : public FieldSampler {
public:
    void setProgram(const FieldProgram& program) override { program_ = &program; }

    void sampleLeaves(const std::vector<Instr>& pool, const std::vector<LeafJob>& leaves,
                      double h, float* out) override
    {
        tbb::parallel_for(size_t(0), leaves.size(), [&](size_t l) {
            const LeafJob& job = leaves[l];
            const Code code(pool.data() + job.codeOffset, size_t(job.codeLength));
            float* o = out + l * kSampleChannels * kLeafVoxels;
            for (int i = 0; i < kLeafVoxels; ++i) {
                const glm::dvec3 p(job.origin[0] + (i & 7), job.origin[1] + ((i >> 3) & 7),
                                   job.origin[2] + (i >> 6));
                // The same float positions as the kernel computes them.
                const glm::dvec3 w(float(p.x) * float(h), float(p.y) * float(h), float(p.z) * float(h));
                const FieldSample s = program_->evaluate(code, w);
                const float v[kSampleChannels] = {float(s.value),      float(s.gradient.x),
                                                  float(s.gradient.y), float(s.gradient.z),
                                                  float(s.color.x),    float(s.color.y),
                                                  float(s.color.z)};
                for (int c = 0; c < kSampleChannels; ++c)
                    o[c * kLeafVoxels + i] = v[c];
            }
        });
    }

    std::vector<float> samplePoints(Code code, const std::vector<glm::dvec3>& points) override
    {
        const size_t n = points.size();
        std::vector<float> out(kSampleChannels * n);
        tbb::parallel_for(size_t(0), n, [&](size_t i) {
            const FieldSample s = program_->evaluate(code, points[i]);
            const double v[kSampleChannels] = {s.value,   s.gradient.x, s.gradient.y, s.gradient.z,
                                               s.color.x, s.color.y,    s.color.z};
            for (int c = 0; c < kSampleChannels; ++c)
                out[c * n + i] = float(v[c]);
        });
        return out;
    }

    const char* name() const override { return "cpu"; }

private:
    const FieldProgram* program_ = nullptr;
};

/// A device buffer that grows as needed.
class DeviceBuffer {
public:
    ~DeviceBuffer()
    {
        if (mem_)
            clReleaseMemObject(mem_);
    }
    cl_mem upload(const OpenCLContext& ctx, const void* data, size_t bytes, cl_mem_flags flags)
    {
        reserve(ctx, bytes, flags);
        if (bytes)
            checkCL(clEnqueueWriteBuffer(ctx.queue(), mem_, CL_TRUE, 0, bytes, data, 0, nullptr, nullptr),
                    "clEnqueueWriteBuffer");
        return mem_;
    }
    cl_mem get() const { return mem_; }
    cl_mem reserve(const OpenCLContext& ctx, size_t bytes, cl_mem_flags flags)
    {
        bytes = std::max<size_t>(bytes, 64);
        if (bytes > size_) {
            if (mem_)
                clReleaseMemObject(mem_);
            cl_int err;
            size_ = std::max(bytes, size_ + size_ / 2);
            mem_ = clCreateBuffer(ctx.context(), flags, size_, nullptr, &err);
            checkCL(err, "clCreateBuffer");
        }
        return mem_;
    }

private:
    cl_mem mem_ = nullptr;
    size_t size_ = 0;
};

class OpenCLSampler final : public FieldSampler {
public:
    OpenCLSampler()
    {
        program_ = ctx_.build(assembleKernelSource(kernelFile("sample.cl")),
                              "-cl-std=CL1.2 -cl-mad-enable -D CB_LANES=8");
        cl_int err;
        leavesKernel_ = clCreateKernel(program_, "sample_leaves", &err);
        checkCL(err, "clCreateKernel(sample_leaves)");
        pointsKernel_ = clCreateKernel(program_, "sample_points", &err);
        checkCL(err, "clCreateKernel(sample_points)");
    }
    ~OpenCLSampler() override
    {
        clReleaseKernel(leavesKernel_);
        clReleaseKernel(pointsKernel_);
        clReleaseProgram(program_);
    }

    void setProgram(const FieldProgram& program) override
    {
        const std::vector<float> p = program.paramsFloat();
        params_.upload(ctx_, p.data(), p.size() * sizeof(float), CL_MEM_READ_ONLY);
    }

    void sampleLeaves(const std::vector<Instr>& pool, const std::vector<LeafJob>& leaves,
                      double h, float* out) override
    {
        if (leaves.empty())
            return;
        cl_mem code = code_.upload(ctx_, pool.data(), pool.size() * sizeof(Instr), CL_MEM_READ_ONLY);
        cl_mem table = table_.upload(ctx_, leaves.data(), leaves.size() * sizeof(LeafJob), CL_MEM_READ_ONLY);
        const size_t bytes = leaves.size() * kSampleChannels * kLeafVoxels * sizeof(float);
        cl_mem result = out_.reserve(ctx_, bytes, CL_MEM_WRITE_ONLY);
        const float hf = float(h);
        cl_mem params = params_.get();
        clSetKernelArg(leavesKernel_, 0, sizeof(cl_mem), &code);
        clSetKernelArg(leavesKernel_, 1, sizeof(cl_mem), &params);
        clSetKernelArg(leavesKernel_, 2, sizeof(cl_mem), &table);
        clSetKernelArg(leavesKernel_, 3, sizeof(float), &hf);
        clSetKernelArg(leavesKernel_, 4, sizeof(cl_mem), &result);
        // An explicit local size: PoCL recompiles for every new global size otherwise.
        const size_t local = 64, global = 64 * leaves.size();
        checkCL(clEnqueueNDRangeKernel(ctx_.queue(), leavesKernel_, 1, nullptr, &global, &local, 0,
                                       nullptr, nullptr),
                "clEnqueueNDRangeKernel(sample_leaves)");
        checkCL(clEnqueueReadBuffer(ctx_.queue(), result, CL_TRUE, 0, bytes, out, 0, nullptr, nullptr),
                "clEnqueueReadBuffer");
    }

    std::vector<float> samplePoints(Code code, const std::vector<glm::dvec3>& points) override
    {
        const size_t n = points.size(), stride = (n + 63) / 64 * 64;
        std::vector<float> in(3 * stride, 0.0f);
        for (size_t i = 0; i < n; ++i)
            for (int c = 0; c < 3; ++c)
                in[c * stride + i] = float(points[i][c]);
        cl_mem codeMem = code_.upload(ctx_, code.data, code.size * sizeof(Instr), CL_MEM_READ_ONLY);
        cl_mem pts = table_.upload(ctx_, in.data(), in.size() * sizeof(float), CL_MEM_READ_ONLY);
        cl_mem result = out_.reserve(ctx_, kSampleChannels * stride * sizeof(float), CL_MEM_WRITE_ONLY);
        cl_mem params = params_.get();
        const int length = int(code.size), st = int(stride);
        clSetKernelArg(pointsKernel_, 0, sizeof(cl_mem), &codeMem);
        clSetKernelArg(pointsKernel_, 1, sizeof(int), &length);
        clSetKernelArg(pointsKernel_, 2, sizeof(cl_mem), &params);
        clSetKernelArg(pointsKernel_, 3, sizeof(cl_mem), &pts);
        clSetKernelArg(pointsKernel_, 4, sizeof(int), &st);
        clSetKernelArg(pointsKernel_, 5, sizeof(cl_mem), &result);
        const size_t local = 8, global = stride / 8;
        checkCL(clEnqueueNDRangeKernel(ctx_.queue(), pointsKernel_, 1, nullptr, &global, &local, 0,
                                       nullptr, nullptr),
                "clEnqueueNDRangeKernel(sample_points)");
        std::vector<float> raw(kSampleChannels * stride);
        checkCL(clEnqueueReadBuffer(ctx_.queue(), result, CL_TRUE, 0, raw.size() * sizeof(float),
                                    raw.data(), 0, nullptr, nullptr),
                "clEnqueueReadBuffer");
        std::vector<float> out(kSampleChannels * n);
        for (int c = 0; c < kSampleChannels; ++c)
            std::copy(raw.begin() + long(c * stride), raw.begin() + long(c * stride + n),
                      out.begin() + long(c * n));
        return out;
    }

    const char* name() const override { return "opencl"; }

private:
    OpenCLContext ctx_;
    cl_program program_ = nullptr;
    cl_kernel leavesKernel_ = nullptr, pointsKernel_ = nullptr;
    DeviceBuffer params_, code_, table_, out_;
};

}  // namespace

std::unique_ptr<FieldSampler> makeOpenCLSampler() { return std::make_unique<OpenCLSampler>(); }
std::unique_ptr<FieldSampler> makeCpuSampler() { return std::make_unique<CpuSampler>(); }

}  // namespace cambium
