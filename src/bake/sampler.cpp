// cambium — leaf samplers (OpenCL and CPU).
#include "bake/sampler.h"

#include "bake/cl_runtime.h"
#include "bake/kernel_sources.h"

#include <fmt/format.h>
#include <openvdb/math/Half.h>
#include <tbb/parallel_for.h>

#include <mutex>

namespace cambium {

uint16_t floatToHalf(float f) { return openvdb::math::internal::half(f).bits(); }

namespace {

class CpuSampler final : public FieldSampler {
public:
    void setProgram(const FieldProgram& program) override { program_ = &program; }
    void setLeafCode(const std::vector<Instr>& pool) override { pool_ = &pool; }

    /// The world position of voxel i of a leaf, computed as the kernels do (in float).
    static glm::dvec3 voxelPosition(const LeafJob& job, int i, double h)
    {
        return glm::dvec3(float(job.origin[0] + (i & 7)) * float(h),
                          float(job.origin[1] + ((i >> 3) & 7)) * float(h),
                          float(job.origin[2] + (i >> 6)) * float(h));
    }

    void sampleValues(const std::vector<LeafJob>& leaves, size_t begin, size_t end, double h,
                      float* out) override
    {
        tbb::parallel_for(begin, end, [&](size_t l) {
            const LeafJob& job = leaves[l];
            const Code code(pool_->data() + job.codeOffset, size_t(job.codeLength));
            for (int i = 0; i < kLeafVoxels; ++i)
                out[(l - begin) * kLeafVoxels + size_t(i)] =
                    float(program_->evaluate(code, voxelPosition(job, i, h)).value);
        });
    }

    void sampleSurface(const std::vector<LeafJob>& leaves, const std::vector<SurfaceQuery>& queries,
                       double h, SurfaceSample* out) override
    {
        tbb::parallel_for(size_t(0), queries.size(), [&](size_t q) {
            const LeafJob& job = leaves[size_t(queries[q].leaf)];
            const Code code(pool_->data() + job.codeOffset, size_t(job.codeLength));
            const FieldSample s = program_->evaluate(code, voxelPosition(job, queries[q].voxel, h));
            for (int k = 0; k < 3; ++k) {
                out[q].gradient[k] = floatToHalf(float(s.gradient[k]));
                out[q].color[k] = uint8_t(std::lround(255.0 * std::clamp(s.color[k], 0.0, 1.0)));
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
    const std::vector<Instr>* pool_ = nullptr;
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

/// Sets a kernel's arguments in order.
template <class... Args>
void setArgs(cl_kernel k, const Args&... args)
{
    cl_uint i = 0;
    (checkCL(clSetKernelArg(k, i++, sizeof(Args), &args), "clSetKernelArg"), ...);
}

class OpenCLSampler final : public FieldSampler {
public:
    OpenCLSampler()
    {
        const std::string source = assembleKernelSource(kernelFile("sample.cl"));
        const std::string options = "-cl-std=CL1.2 -cl-mad-enable -D CB_LANES=8";
        program_ = ctx_.build(source, options);
        valuesProgram_ = ctx_.build(source, options + " -D CB_GRADIENT=0 -D CB_COLOR=0");
        cl_int err;
        valuesKernel_ = clCreateKernel(valuesProgram_, "sample_values", &err);
        checkCL(err, "clCreateKernel(sample_values)");
        surfaceKernel_ = clCreateKernel(program_, "sample_surface", &err);
        checkCL(err, "clCreateKernel(sample_surface)");
        pointsKernel_ = clCreateKernel(program_, "sample_points", &err);
        checkCL(err, "clCreateKernel(sample_points)");
    }
    ~OpenCLSampler() override
    {
        clReleaseKernel(valuesKernel_);
        clReleaseKernel(surfaceKernel_);
        clReleaseKernel(pointsKernel_);
        clReleaseProgram(program_);
        clReleaseProgram(valuesProgram_);
    }

    void setProgram(const FieldProgram& program) override
    {
        const std::vector<float> p = program.paramsFloat();
        params_.upload(ctx_, p.data(), p.size() * sizeof(float), CL_MEM_READ_ONLY);
    }

    void setLeafCode(const std::vector<Instr>& pool) override
    {
        pool_.upload(ctx_, pool.data(), pool.size() * sizeof(Instr), CL_MEM_READ_ONLY);
    }

    void sampleValues(const std::vector<LeafJob>& leaves, size_t begin, size_t end, double h,
                      float* out) override
    {
        if (begin >= end)
            return;
        const size_t n = end - begin;
        cl_mem code = pool_.get(), params = params_.get();
        cl_mem table = table_.upload(ctx_, leaves.data() + begin, n * sizeof(LeafJob), CL_MEM_READ_ONLY);
        const size_t bytes = n * kLeafVoxels * sizeof(float);
        cl_mem result = out_.reserve(ctx_, bytes, CL_MEM_WRITE_ONLY);
        const float hf = float(h);
        setArgs(valuesKernel_, code, params, table, hf, result);
        // An explicit local size: PoCL recompiles for every new global size otherwise.
        const size_t local = 64, global = 64 * n;
        checkCL(clEnqueueNDRangeKernel(ctx_.queue(), valuesKernel_, 1, nullptr, &global, &local, 0,
                                       nullptr, nullptr),
                "clEnqueueNDRangeKernel(sample_values)");
        checkCL(clEnqueueReadBuffer(ctx_.queue(), result, CL_TRUE, 0, bytes, out, 0, nullptr, nullptr),
                "clEnqueueReadBuffer");
    }

    void sampleSurface(const std::vector<LeafJob>& leaves, const std::vector<SurfaceQuery>& queries,
                       double h, SurfaceSample* out) override
    {
        if (queries.empty())
            return;
        // Chunks of eight voxels of one leaf; a short chunk repeats its last voxel.
        std::vector<int32_t> chunkLeaf;
        std::vector<uint16_t> chunkVoxels;
        std::vector<size_t> slot(queries.size());  // where each query's result lands
        for (size_t q = 0; q < queries.size();) {
            size_t e = q;
            while (e < queries.size() && e - q < 8 && queries[e].leaf == queries[q].leaf)
                ++e;
            const size_t chunk = chunkLeaf.size();
            chunkLeaf.push_back(queries[q].leaf);
            for (size_t k = 0; k < 8; ++k)
                chunkVoxels.push_back(queries[q + std::min(k, e - q - 1)].voxel);
            for (size_t k = q; k < e; ++k)
                slot[k] = 8 * chunk + (k - q);
            q = e;
        }
        const size_t local = 8;
        while (chunkLeaf.size() % local) {  // pad to the work-group size
            chunkLeaf.push_back(chunkLeaf.back());
            for (int k = 0; k < 8; ++k)
                chunkVoxels.push_back(chunkVoxels[chunkVoxels.size() - 8]);
        }
        const size_t chunks = chunkLeaf.size(), stride = 8 * chunks;
        cl_mem code = pool_.get(), params = params_.get();
        cl_mem table = table_.upload(ctx_, leaves.data(), leaves.size() * sizeof(LeafJob), CL_MEM_READ_ONLY);
        cl_mem cl = chunkLeaf_.upload(ctx_, chunkLeaf.data(), chunks * sizeof(int32_t), CL_MEM_READ_ONLY);
        cl_mem cv = chunkVoxels_.upload(ctx_, chunkVoxels.data(), stride * sizeof(uint16_t), CL_MEM_READ_ONLY);
        cl_mem grad = out_.reserve(ctx_, 3 * stride * sizeof(uint16_t), CL_MEM_WRITE_ONLY);
        cl_mem col = out2_.reserve(ctx_, 3 * stride, CL_MEM_WRITE_ONLY);
        const float hf = float(h);
        const int st = int(stride);
        setArgs(surfaceKernel_, code, params, table, hf, cl, cv, st, grad, col);
        checkCL(clEnqueueNDRangeKernel(ctx_.queue(), surfaceKernel_, 1, nullptr, &chunks, &local, 0,
                                       nullptr, nullptr),
                "clEnqueueNDRangeKernel(sample_surface)");
        std::vector<uint16_t> g(3 * stride);
        std::vector<uint8_t> c(3 * stride);
        checkCL(clEnqueueReadBuffer(ctx_.queue(), grad, CL_TRUE, 0, g.size() * 2, g.data(), 0, nullptr, nullptr),
                "clEnqueueReadBuffer");
        checkCL(clEnqueueReadBuffer(ctx_.queue(), col, CL_TRUE, 0, c.size(), c.data(), 0, nullptr, nullptr),
                "clEnqueueReadBuffer");
        tbb::parallel_for(size_t(0), queries.size(), [&](size_t q) {
            for (int k = 0; k < 3; ++k) {
                out[q].gradient[k] = g[size_t(k) * stride + slot[q]];
                out[q].color[k] = c[size_t(k) * stride + slot[q]];
            }
        });
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
        setArgs(pointsKernel_, codeMem, length, params, pts, st, result);
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
    cl_program program_ = nullptr, valuesProgram_ = nullptr;
    cl_kernel valuesKernel_ = nullptr, surfaceKernel_ = nullptr, pointsKernel_ = nullptr;
    DeviceBuffer params_, pool_, code_, table_, out_, out2_, chunkLeaf_, chunkVoxels_;
};

}  // namespace

std::unique_ptr<FieldSampler> makeOpenCLSampler() { return std::make_unique<OpenCLSampler>(); }
std::unique_ptr<FieldSampler> makeCpuSampler() { return std::make_unique<CpuSampler>(); }

}  // namespace cambium
