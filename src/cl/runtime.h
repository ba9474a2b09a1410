// cambium — a small OpenCL 1.2 runtime wrapper (platform, device, context,
// queue, program builds with readable errors).
#pragma once

#include <CL/cl.h>

#include <algorithm>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace cambium {

/// An OpenCL failure: no platform, a failed build (with its log), a failed call.
class OpenCLError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
};

struct OpenCLDeviceInfo {
    std::string platform;  ///< platform name, e.g. "Portable Computing Language"
    std::string device;    ///< device name
    std::string version;   ///< device OpenCL version string
    std::string platformVersion, driverVersion;  ///< (they key cambium's program cache)
    cl_platform_id platformId = nullptr;
    cl_device_id deviceId = nullptr;
};

/// Every device of every platform; empty when no OpenCL platform is installed.
std::vector<OpenCLDeviceInfo> listOpenCLDevices();

[[noreturn]] void throwOpenCLHint(const OpenCLError& e, const char* action);

/// Runs f; an OpenCLError from it becomes an InputError that says how to do
/// without OpenCL (`action`: "bake", "render").
template <class F>
auto withOpenCLHint(const char* action, F&& f) -> decltype(f());

/// Throws OpenCLError naming `what` and the error code when `status` is not CL_SUCCESS.
void checkCL(cl_int status, const char* what);

/// Where OpenCLContext::build keeps built programs: $CAMBIUM_CACHE_DIR/opencl
/// (an empty value: nowhere, an empty result), else
/// $XDG_CACHE_HOME/cambium/opencl, else ~/.cache/cambium/opencl.
std::string programCacheDirectory();

/// A context and in-order queue on one device (the first device found unless
/// CAMBIUM_OPENCL_DEVICE names a substring of the wanted device's name).
class OpenCLContext {
public:
    OpenCLContext();
    ~OpenCLContext();
    OpenCLContext(const OpenCLContext&) = delete;
    OpenCLContext& operator=(const OpenCLContext&) = delete;

    cl_context context() const { return context_; }
    cl_command_queue queue() const { return queue_; }
    cl_device_id device() const { return info_.deviceId; }
    const OpenCLDeviceInfo& info() const { return info_; }

    /// Builds a program from one source string (see assembleKernelSource).
    /// Throws OpenCLError with the build log on failure.  The caller releases it.
    /// The device's binary is kept in a cache on disk ($CAMBIUM_CACHE_DIR,
    /// else ~/.cache/cambium; docs/baking.md) keyed by the driver, the device,
    /// the options and the whole source, and loaded from there next time.
    cl_program build(const std::string& source, const std::string& options = "") const;

private:
    cl_program buildFromSource(const std::string& source, const std::string& options) const;

    OpenCLDeviceInfo info_;
    cl_context context_ = nullptr;
    cl_command_queue queue_ = nullptr;
};

/// A device buffer that grows as needed.
class DeviceBuffer {
public:
    DeviceBuffer() = default;
    DeviceBuffer(const DeviceBuffer&) = delete;
    DeviceBuffer& operator=(const DeviceBuffer&) = delete;
    ~DeviceBuffer()
    {
        if (mem_)
            clReleaseMemObject(mem_);
    }
    cl_mem upload(const OpenCLContext& ctx, const void* data, size_t bytes, cl_mem_flags flags)
    {
        reserve(ctx, bytes, flags);
        if (bytes)
            checkCL(clEnqueueWriteBuffer(ctx.queue(), mem_, CL_TRUE, 0, bytes, data, 0, nullptr,
                                         nullptr),
                    "clEnqueueWriteBuffer");
        return mem_;
    }
    /// A buffer of host memory the caller keeps alive and unchanged while
    /// the buffer lives (CL_MEM_USE_HOST_PTR: on a CPU device no copy of it).
    cl_mem useHost(const OpenCLContext& ctx, const void* data, size_t bytes, cl_mem_flags flags)
    {
        release();
        cl_int err;
        mem_ = clCreateBuffer(ctx.context(), flags | CL_MEM_USE_HOST_PTR, bytes,
                              const_cast<void*>(data), &err);
        checkCL(err, "clCreateBuffer(CL_MEM_USE_HOST_PTR)");
        return mem_;  // (size_ 0: a later reserve makes a buffer of its own)
    }
    void release()
    {
        if (mem_)
            clReleaseMemObject(mem_);
        mem_ = nullptr;
        size_ = 0;
    }
    cl_mem get() const { return mem_; }
    /// The first `bytes` mapped into host memory (no copy on a CPU device):
    /// CL_MAP_READ, or CL_MAP_WRITE_INVALIDATE_REGION to fill it.
    void* map(const OpenCLContext& ctx, cl_map_flags flags, size_t bytes)
    {
        cl_int err;
        void* p = clEnqueueMapBuffer(ctx.queue(), mem_, CL_TRUE, flags, 0, bytes, 0, nullptr,
                                     nullptr, &err);
        checkCL(err, "clEnqueueMapBuffer");
        return p;
    }
    void unmap(const OpenCLContext& ctx, void* p)
    {
        checkCL(clEnqueueUnmapMemObject(ctx.queue(), mem_, p, 0, nullptr, nullptr),
                "clEnqueueUnmapMemObject");
    }
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

template <class F>
auto withOpenCLHint(const char* action, F&& f) -> decltype(f())
{
    try {
        return f();
    } catch (const OpenCLError& e) {
        throwOpenCLHint(e, action);
    }
}

}  // namespace cambium
