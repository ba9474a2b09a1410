// cambium — ray marching a level set with OpenCL through NanoVDB (kernels/march.cl).
#include "use/render.h"

#include "cl/runtime.h"
#include "cl/kernel_sources.h"
#include "core/error.h"

#include <fmt/format.h>
#include <nanovdb/util/OpenToNanoVDB.h>
#include <tbb/parallel_for.h>

#include <cstring>
#include <functional>

#include <malloc.h>

namespace cambium {

struct OpenCLMarcher::Impl {
    OpenCLContext ctx;
    size_t gridBytes = 0;  ///< of the NanoVDB copies, now on the device only
    bool hasColor = false;
    cl_program program = nullptr;
    cl_kernel kernel = nullptr;
    /// The NanoVDB copies, which the device's buffers use in place (no copy
    /// of them on a CPU device; a GPU's driver keeps its own).
    nanovdb::GridHandle<nanovdb::HostBuffer> nanoSurface, nanoColor;
    DeviceBuffer surfaceBuffer, colorBuffer;
    float skip = 0.0f;  ///< leaves whose values all exceed it hold no crossing
    mutable DeviceBuffer rays, hits;
    ~Impl()
    {
        if (kernel)
            clReleaseKernel(kernel);
        if (program)
            clReleaseProgram(program);
    }
};

OpenCLMarcher::OpenCLMarcher(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color)
    : impl_(std::make_unique<Impl>())
{
    build();
    load(surface, color);
    warmUp();
}

OpenCLMarcher::OpenCLMarcher(LevelSetGrids&& grids) : impl_(std::make_unique<Impl>())
{
    build();
    load(std::move(grids));
    warmUp();
}

void OpenCLMarcher::build()
{
    Impl& m = *impl_;
    m.program =
        m.ctx.build(assembleKernelSource(kernelFile("march.cl")), "-cl-std=CL1.2 -cl-mad-enable");
    cl_int err = CL_SUCCESS;
    m.kernel = clCreateKernel(m.program, "march_rays", &err);
    checkCL(err, "clCreateKernel(march_rays)");
}

void OpenCLMarcher::warmUp()
{
    // PoCL compiles a kernel for its work-group size at the first launch:
    // one group of rays now, so that the first image does not pay for it.
    std::vector<TraceHit> hits;
    trace(std::vector<TraceRay>(64, TraceRay{glm::dvec3(0.0), glm::dvec3(0.0, 0.0, 1.0)}), hits);
}

void OpenCLMarcher::load(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color)
{
    convert(surface, color, {});
}

void OpenCLMarcher::load(LevelSetGrids&& grids)
{
    openvdb::FloatGrid::Ptr surface = std::move(grids.surface);
    openvdb::Vec3fGrid::Ptr color = std::move(grids.color);
    grids = LevelSetGrids();
    // (each grid's values, a gigabyte on a large frame, given back to the
    // system before the next copy is made)
    convert(*surface, color.get(), [&](bool colour) {
        if (colour)
            color.reset();
        else
            surface.reset();
        ::malloc_trim(0);
    });
}

void OpenCLMarcher::convert(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                            const std::function<void(bool colour)>& converted)
{
    Impl& m = *impl_;
    m.surfaceBuffer.release();  // (before the memory they use goes)
    m.colorBuffer.release();
    m.nanoSurface = {};
    m.nanoColor = {};
    // Leaves' extrema let the march step over leaves far from the surface.
    const float skip = float(2.0 * surface.voxelSize()[0]);
    m.nanoSurface =
        nanovdb::openToNanoVDB(surface, nanovdb::StatsMode::MinMax, nanovdb::ChecksumMode::Disable);
    if (converted)
        converted(false);  // (`surface` may be gone now)
    if (color)
        m.nanoColor = nanovdb::openToNanoVDB(*color, nanovdb::StatsMode::BBox,
                                             nanovdb::ChecksumMode::Disable);
    if (converted)
        converted(true);
    for (const auto* h : {&m.nanoSurface, &m.nanoColor})
        if (h->size() >= (uint64_t(1) << 32))  // kernels/cb_pnanovdb.h: 32-bit addresses
            throw InputError(fmt::format(
                "the NanoVDB copy of a grid takes {:.1f} GB; the OpenCL march reads grids "
                "under 4 GB: use --device cpu",
                double(h->size()) * 1e-9));
    m.skip = skip;
    m.hasColor = bool(m.nanoColor);
    m.gridBytes = m.nanoSurface.size() + m.nanoColor.size();
    m.surfaceBuffer.useHost(m.ctx, m.nanoSurface.data(), m.nanoSurface.size(), CL_MEM_READ_ONLY);
    // Without colour the kernel still needs a buffer argument: the surface's.
    if (m.hasColor)
        m.colorBuffer.useHost(m.ctx, m.nanoColor.data(), m.nanoColor.size(), CL_MEM_READ_ONLY);
}

OpenCLMarcher::~OpenCLMarcher() = default;

size_t OpenCLMarcher::gridBytes() const
{
    return impl_->gridBytes;
}

std::string OpenCLMarcher::deviceName() const
{
    return impl_->ctx.info().platform + ": " + impl_->ctx.info().device;
}

void OpenCLMarcher::trace(const std::vector<TraceRay>& rays, std::vector<TraceHit>& hits) const
{
    Impl& m = *impl_;
    const size_t n = rays.size();
    hits.resize(n);
    if (n == 0)
        return;
    const size_t bytes = n * 8 * sizeof(float);
    m.rays.reserve(m.ctx, bytes, CL_MEM_READ_ONLY | CL_MEM_ALLOC_HOST_PTR);
    m.hits.reserve(m.ctx, bytes, CL_MEM_WRITE_ONLY | CL_MEM_ALLOC_HOST_PTR);
    auto* in = static_cast<float*>(m.rays.map(m.ctx, CL_MAP_WRITE_INVALIDATE_REGION, bytes));
    tbb::parallel_for(size_t(0), n, [&](size_t i) {
        const TraceRay& r = rays[i];
        const float v[8] = {float(r.origin.x),    float(r.origin.y),    float(r.origin.z),    0.0f,
                            float(r.direction.x), float(r.direction.y), float(r.direction.z), 0.0f};
        std::memcpy(in + 8 * i, v, sizeof(v));
    });
    m.rays.unmap(m.ctx, in);
    const cl_mem surface = m.surfaceBuffer.get();
    const cl_mem color = m.hasColor ? m.colorBuffer.get() : surface;
    const cl_int hasColor = m.hasColor ? 1 : 0;
    const cl_float4 albedo = {{kBarkAlbedo.x, kBarkAlbedo.y, kBarkAlbedo.z, 0.0f}};
    const cl_mem raysMem = m.rays.get(), hitsMem = m.hits.get();
    const cl_uint count = cl_uint(n);
    setArgs(m.kernel, surface, color, hasColor, albedo, m.skip, raysMem, hitsMem, count);
    const size_t local = 64, global = (n + local - 1) / local * local;
    checkCL(clEnqueueNDRangeKernel(m.ctx.queue(), m.kernel, 1, nullptr, &global, &local, 0, nullptr,
                                   nullptr),
            "clEnqueueNDRangeKernel(march_rays)");

    const auto* out = static_cast<const float*>(m.hits.map(m.ctx, CL_MAP_READ, bytes));
    tbb::parallel_for(size_t(0), n, [&](size_t i) {
        const float* h = out + 8 * i;
        TraceHit& hit = hits[i];
        hit.hit = h[0] >= 0.0f;
        hit.t = h[0];
        hit.normal = glm::vec3(h[1], h[2], h[3]);
        hit.albedo = glm::vec3(h[4], h[5], h[6]);
    });
    m.hits.unmap(m.ctx, const_cast<float*>(out));
    checkCL(clFinish(m.ctx.queue()), "clFinish");
}

RenderImage OpenCLMarcher::render(const Camera& camera, int width, int height, int spp) const
{
    return renderBatches(camera, width, height, spp,
                         [this](const std::vector<TraceRay>& rays, std::vector<TraceHit>& hits) {
                             trace(rays, hits);
                         });
}

RenderImage renderLevelSetOpenCL(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                                 const Camera& camera, int width, int height, int spp)
{
    return OpenCLMarcher(surface, color).render(camera, width, height, spp);
}

}  // namespace cambium
