// cambium — OpenCL runtime wrapper.
#include "cl/runtime.h"

#include "core/error.h"

#include <fmt/format.h>

#include <cstdlib>

namespace cambium {

namespace {

/// A string property through one of OpenCL's two-call query functions.
template <class Handle, class Param, class Query>
std::string infoString(Query query, Handle h, Param what)
{
    size_t n = 0;
    if (query(h, what, 0, nullptr, &n) != CL_SUCCESS || n == 0)
        return {};
    std::string s(n, '\0');
    query(h, what, n, s.data(), nullptr);
    s.resize(n - 1);
    return s;
}

}  // namespace

void throwOpenCLHint(const OpenCLError& e, const char* action)
{
    throw InputError(
        fmt::format("{}\n(use --device cpu to {} on the CPU without OpenCL)", e.what(), action));
}

void checkCL(cl_int status, const char* what)
{
    if (status != CL_SUCCESS)
        throw OpenCLError(fmt::format("OpenCL: {} failed (error {})", what, status));
}

std::vector<OpenCLDeviceInfo> listOpenCLDevices()
{
    std::vector<OpenCLDeviceInfo> out;
    cl_uint np = 0;
    if (clGetPlatformIDs(0, nullptr, &np) != CL_SUCCESS || np == 0)
        return out;
    std::vector<cl_platform_id> platforms(np);
    clGetPlatformIDs(np, platforms.data(), nullptr);
    for (cl_platform_id p : platforms) {
        cl_uint nd = 0;
        if (clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, 0, nullptr, &nd) != CL_SUCCESS || nd == 0)
            continue;
        std::vector<cl_device_id> devices(nd);
        clGetDeviceIDs(p, CL_DEVICE_TYPE_ALL, nd, devices.data(), nullptr);
        for (cl_device_id d : devices)
            out.push_back({infoString(clGetPlatformInfo, p, CL_PLATFORM_NAME),
                           infoString(clGetDeviceInfo, d, CL_DEVICE_NAME),
                           infoString(clGetDeviceInfo, d, CL_DEVICE_VERSION), p, d});
    }
    return out;
}

OpenCLContext::OpenCLContext()
{
    const auto devices = listOpenCLDevices();
    if (devices.empty())
        throw OpenCLError(
            "no OpenCL platform found: install one (on Debian: apt-get install pocl-opencl-icd "
            "ocl-icd-libopencl1), or use --device cpu");
    info_ = devices.front();
    if (const char* want = std::getenv("CAMBIUM_OPENCL_DEVICE"); want && *want) {
        bool found = false;
        for (const auto& d : devices)
            if ((d.device + " " + d.platform).find(want) != std::string::npos) {
                info_ = d;
                found = true;
                break;
            }
        if (!found)
            throw OpenCLError(
                fmt::format("CAMBIUM_OPENCL_DEVICE='{}' matches no OpenCL device", want));
    }
    cl_int err = CL_SUCCESS;
    context_ = clCreateContext(nullptr, 1, &info_.deviceId, nullptr, nullptr, &err);
    checkCL(err, "clCreateContext");
    queue_ = clCreateCommandQueue(context_, info_.deviceId, 0, &err);
    if (err != CL_SUCCESS) {
        clReleaseContext(context_);
        checkCL(err, "clCreateCommandQueue");
    }
}

OpenCLContext::~OpenCLContext()
{
    if (queue_)
        clReleaseCommandQueue(queue_);
    if (context_)
        clReleaseContext(context_);
}

cl_program OpenCLContext::build(const std::string& source, const std::string& options) const
{
    const char* text = source.c_str();
    const size_t length = source.size();
    cl_int err = CL_SUCCESS;
    cl_program program = clCreateProgramWithSource(context_, 1, &text, &length, &err);
    checkCL(err, "clCreateProgramWithSource");
    err = clBuildProgram(program, 1, &info_.deviceId, options.c_str(), nullptr, nullptr);
    if (err != CL_SUCCESS) {
        size_t n = 0;
        clGetProgramBuildInfo(program, info_.deviceId, CL_PROGRAM_BUILD_LOG, 0, nullptr, &n);
        std::string log(n, '\0');
        if (n)
            clGetProgramBuildInfo(program, info_.deviceId, CL_PROGRAM_BUILD_LOG, n, log.data(),
                                  nullptr);
        clReleaseProgram(program);
        throw OpenCLError(fmt::format("OpenCL kernel build failed on {} (error {}):\n{}",
                                      info_.device, err, log));
    }
    return program;
}

}  // namespace cambium
