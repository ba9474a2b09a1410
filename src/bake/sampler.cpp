// cambium — leaf samplers (OpenCL and CPU).
#include "bake/sampler.h"
#include "core/memory.h"

#include "cl/runtime.h"
#include "cl/kernel_sources.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <mutex>

namespace cambium {

namespace {

class CpuSampler final : public FieldSampler {
public:
    void setProgram(const FieldProgram& program) override { program_ = &program; }
    void setLeaves(const std::vector<LeafJob>& leaves, const std::vector<Instr>& pool) override
    {
        leaves_ = &leaves;
        pool_ = &pool;
    }

    /// The world position of voxel i of a leaf, computed as the kernels do (in float).
    static glm::dvec3 voxelPosition(const LeafJob& job, int i, double h)
    {
        return glm::dvec3(float(job.origin[0] + (i & 7)) * float(h),
                          float(job.origin[1] + ((i >> 3) & 7)) * float(h),
                          float(job.origin[2] + (i >> 6)) * float(h));
    }

    void sampleValues(const std::vector<LeafJob>& leaves, size_t begin, size_t end, double h,
                      uint16_t* out) override
    {
        const float T = float(program_->threshold());
        tbb::parallel_for(begin, end, [&](size_t l) {
            const LeafJob& job = leaves[l];
            const Code code(pool_->data() + job.codeOffset, size_t(job.codeLength));
            for (int i = 0; i < kLeafVoxels; ++i)  // F - T in float, as the kernel
                out[(l - begin) * kLeafVoxels + size_t(i)] = floatToHalf(
                    float(program_->evaluate(code, voxelPosition(job, i, h)).value) - T);
        });
    }

    void sampleSurface(const SurfaceQuery* queries, size_t count, double h,
                       SurfaceSample* out) override
    {
        tbb::parallel_for(size_t(0), count, [&](size_t q) {
            const LeafJob& job = (*leaves_)[size_t(queries[q].leaf)];
            const Code code(pool_->data() + job.codeOffset, size_t(job.codeLength));
            glm::dvec3 step;
            const FieldSample s = program_->surfaceStep(
                code, voxelPosition(job, queries[q].voxel, h), kSurfaceReach * h, step);
            out[q].value = floatToHalf(float(s.value - program_->threshold()));
            for (int k = 0; k < 3; ++k) {
                out[q].step[k] = floatToHalf(float(step[k] / h));
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
    const std::vector<LeafJob>* leaves_ = nullptr;
};

class OpenCLSampler final : public FieldSampler {
public:
    OpenCLSampler()
    {
        const std::string source = assembleKernelSource(kernelFile("sample.cl"));
        const std::string options = "-cl-std=CL1.2 -cl-mad-enable";
        program_ = ctx_.build(source, options + " -D CB_LANES=8 -D CB_KERNELS=4");
        // Values 16 points wide: one interpreter dispatch per two rows (0.35 s
        // -> 0.22 s on the 20k-internode tree; one AVX-512 register, two AVX2).
        valuesProgram_ = ctx_.build(
            source, options + " -D CB_LANES=16 -D CB_GRADIENT=0 -D CB_COLOR=0 -D CB_KERNELS=1");
        cl_int err;
        valuesKernel_ = clCreateKernel(valuesProgram_, "sample_values", &err);
        checkCL(err, "clCreateKernel(sample_values)");
        surfaceProgram_ = ctx_.build(source, options + " -D CB_LANES=16 -D CB_KERNELS=2");
        surfaceKernel_ = clCreateKernel(surfaceProgram_, "sample_surface", &err);
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
        clReleaseProgram(surfaceProgram_);
    }

    void setProgram(const FieldProgram& program) override
    {
        const std::vector<float> p = program.paramsFloat();
        params_.upload(ctx_, p.data(), p.size() * sizeof(float), CL_MEM_READ_ONLY);
    }

    void setLeaves(const std::vector<LeafJob>& leaves, const std::vector<Instr>& pool) override
    {
        pool_.upload(ctx_, pool.data(), pool.size() * sizeof(Instr), CL_MEM_READ_ONLY);
        leaves_.upload(ctx_, leaves.data(), leaves.size() * sizeof(LeafJob), CL_MEM_READ_ONLY);
    }

    void sampleValues(const std::vector<LeafJob>& leaves, size_t begin, size_t end, double h,
                      uint16_t* out) override
    {
        if (begin >= end)
            return;
        const size_t n = end - begin;
        cl_mem code = pool_.get(), params = params_.get();
        cl_mem table =
            table_.upload(ctx_, leaves.data() + begin, n * sizeof(LeafJob), CL_MEM_READ_ONLY);
        const size_t bytes = n * kLeafVoxels * sizeof(uint16_t);
        // Aligned output (parallelArray's) is written in place: a CPU device
        // uses it as it is, where a copy would cost a pass over all values.
        const bool inPlace = reinterpret_cast<uintptr_t>(out) % kParallelArrayAlignment == 0;
        cl_mem result;
        if (inPlace) {
            cl_int err;
            result = clCreateBuffer(ctx_.context(), CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR, bytes,
                                    out, &err);
            checkCL(err, "clCreateBuffer(CL_MEM_USE_HOST_PTR)");
        } else {
            result = out_.reserve(ctx_, bytes, CL_MEM_WRITE_ONLY);
        }
        const float hf = float(h);
        setArgs(valuesKernel_, code, params, table, hf, result);
        // An explicit local size: PoCL recompiles for every new global size otherwise.
        const size_t local = 32, global = 32 * n;  // two rows per work-item
        cl_int status = clEnqueueNDRangeKernel(ctx_.queue(), valuesKernel_, 1, nullptr, &global,
                                               &local, 0, nullptr, nullptr);
        if (inPlace) {
            // Mapping makes the host memory hold the results (a no-op where
            // the device works in it); the buffer goes, the memory stays ours.
            void* p = nullptr;
            if (status == CL_SUCCESS)
                p = clEnqueueMapBuffer(ctx_.queue(), result, CL_TRUE, CL_MAP_READ, 0, bytes, 0,
                                       nullptr, nullptr, &status);
            if (p)
                clEnqueueUnmapMemObject(ctx_.queue(), result, p, 0, nullptr, nullptr);
            clFinish(ctx_.queue());
            clReleaseMemObject(result);
            checkCL(status, "sample_values (in place)");
            return;
        }
        checkCL(status, "clEnqueueNDRangeKernel(sample_values)");
        checkCL(
            clEnqueueReadBuffer(ctx_.queue(), result, CL_TRUE, 0, bytes, out, 0, nullptr, nullptr),
            "clEnqueueReadBuffer");
    }

    void sampleSurface(const SurfaceQuery* queries, size_t count, double h,
                       SurfaceSample* out) override
    {
        if (count == 0)
            return;
        constexpr size_t kChunk = 16;  // the surface kernel's width (CB_LANES)
        // Chunks of kChunk voxels of one leaf (a short chunk repeats its last
        // voxel), laid out run by run of the queries' leaves, filled in
        // parallel straight into the device's buffers.
        std::vector<size_t> runStart;  // queries are grouped by leaf
        for (size_t q = 0; q < count; ++q)
            if (q == 0 || queries[q].leaf != queries[q - 1].leaf)
                runStart.push_back(q);
        runStart.push_back(count);
        const size_t runs = runStart.size() - 1;
        std::vector<size_t> firstChunk(runs + 1, 0);
        for (size_t r = 0; r < runs; ++r)
            firstChunk[r + 1] =
                firstChunk[r] + (runStart[r + 1] - runStart[r] + kChunk - 1) / kChunk;
        const size_t local = 8;  // work-items (chunks) per work-group
        const size_t chunks = (firstChunk[runs] + local - 1) / local * local;  // whole work-groups
        const size_t stride = kChunk * chunks;
        chunkLeaf_.reserve(ctx_, chunks * sizeof(int32_t), CL_MEM_READ_ONLY);
        chunkVoxels_.reserve(ctx_, stride * sizeof(uint16_t), CL_MEM_READ_ONLY);
        auto* cLeaf = static_cast<int32_t*>(
            chunkLeaf_.map(ctx_, CL_MAP_WRITE_INVALIDATE_REGION, chunks * sizeof(int32_t)));
        auto* cVox = static_cast<uint16_t*>(
            chunkVoxels_.map(ctx_, CL_MAP_WRITE_INVALIDATE_REGION, stride * sizeof(uint16_t)));
        tbb::parallel_for(size_t(0), runs, [&](size_t r) {
            const size_t q0 = runStart[r], q1 = runStart[r + 1];
            for (size_t c = firstChunk[r]; c < firstChunk[r + 1]; ++c) {
                const size_t q = q0 + kChunk * (c - firstChunk[r]);
                cLeaf[c] = queries[q0].leaf;
                for (size_t k = 0; k < kChunk; ++k)
                    cVox[kChunk * c + k] = queries[std::min(q + k, q1 - 1)].voxel;
            }
        });
        for (size_t c = firstChunk[runs]; c < chunks; ++c) {  // padding: copies of the last chunk
            cLeaf[c] = cLeaf[c - 1];
            for (size_t k = 0; k < kChunk; ++k)
                cVox[kChunk * c + k] = cVox[kChunk * (c - 1) + k];
        }
        chunkLeaf_.unmap(ctx_, cLeaf);
        chunkVoxels_.unmap(ctx_, cVox);
        cl_mem code = pool_.get(), params = params_.get();
        cl_mem table = leaves_.get();
        cl_mem cl = chunkLeaf_.get(), cv = chunkVoxels_.get();
        constexpr size_t kPlanes = 7;  // step (3), F - T, gradient (3)
        cl_mem planes = out_.reserve(ctx_, kPlanes * stride * sizeof(uint16_t), CL_MEM_WRITE_ONLY);
        cl_mem col = out2_.reserve(ctx_, 3 * stride, CL_MEM_WRITE_ONLY);
        const float hf = float(h);
        const int st = int(stride);
        setArgs(surfaceKernel_, code, params, table, hf, cl, cv, st, planes, col);
        checkCL(clEnqueueNDRangeKernel(ctx_.queue(), surfaceKernel_, 1, nullptr, &chunks, &local, 0,
                                       nullptr, nullptr),
                "clEnqueueNDRangeKernel(sample_surface)");
        const auto* g = static_cast<const uint16_t*>(
            out_.map(ctx_, CL_MAP_READ, kPlanes * stride * sizeof(uint16_t)));
        const auto* c = static_cast<const uint8_t*>(out2_.map(ctx_, CL_MAP_READ, 3 * stride));
        tbb::parallel_for(size_t(0), runs, [&](size_t r) {
            for (size_t q = runStart[r]; q < runStart[r + 1]; ++q) {
                const size_t at = kChunk * firstChunk[r] + (q - runStart[r]);
                out[q].value = g[3 * stride + at];
                for (int k = 0; k < 3; ++k) {
                    out[q].step[k] = g[size_t(k) * stride + at];
                    out[q].gradient[k] = g[size_t(4 + k) * stride + at];
                    out[q].color[k] = c[size_t(k) * stride + at];
                }
            }
        });
        out_.unmap(ctx_, const_cast<uint16_t*>(g));
        out2_.unmap(ctx_, const_cast<uint8_t*>(c));
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
        cl_mem result =
            out_.reserve(ctx_, kSampleChannels * stride * sizeof(float), CL_MEM_WRITE_ONLY);
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
    bool copiesLeaves() const override { return true; }

private:
    OpenCLContext ctx_;
    cl_program program_ = nullptr, valuesProgram_ = nullptr, surfaceProgram_ = nullptr;
    cl_kernel valuesKernel_ = nullptr, surfaceKernel_ = nullptr, pointsKernel_ = nullptr;
    DeviceBuffer params_, pool_, leaves_, code_, table_, out_, out2_, chunkLeaf_, chunkVoxels_;
};

}  // namespace

std::unique_ptr<FieldSampler> makeOpenCLSampler()
{
    return std::make_unique<OpenCLSampler>();
}
std::unique_ptr<FieldSampler> makeCpuSampler()
{
    return std::make_unique<CpuSampler>();
}

}  // namespace cambium
