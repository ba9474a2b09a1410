// cambium — OpenCL runtime wrapper.
#include "cl/runtime.h"

#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"

#include <fmt/format.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

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

/// A cached program's file: the key's length (8 bytes), the key (what
/// identifies the build: the driver, the device, the options and the whole
/// source), the binary's length and checksum (8 bytes each), then the
/// device's binary.  The file is named by a hash of the key and used only
/// when the key stored in it is the same, byte for byte, and the binary is
/// whole: PoCL asserts or crashes on a binary cut short or altered (sweep
/// 18: every OpenCL command aborted on every run until the file was
/// deleted by hand).
std::string readCachedBinary(const std::string& path, const std::string& key)
{
    std::ifstream in(path, std::ios::binary);
    uint64_t n = 0;
    if (!in.read(reinterpret_cast<char*>(&n), sizeof n) || n != key.size())
        return {};
    std::string stored(n, '\0');
    if (!in.read(stored.data(), std::streamsize(n)) || stored != key)
        return {};
    uint64_t size = 0, sum = 0;
    if (!in.read(reinterpret_cast<char*>(&size), sizeof size) ||
        !in.read(reinterpret_cast<char*>(&sum), sizeof sum) || size > (uint64_t(1) << 32))
        return {};
    std::string binary(std::istreambuf_iterator<char>(in), {});
    Checksum64 check;
    check.update(binary.data(), binary.size());
    return binary.size() == size && check.value() == sum ? binary : std::string();
}

/// The file readCachedBinary reads.
std::string cachedBinaryFile(const std::string& key, const std::string& binary)
{
    Checksum64 check;
    check.update(binary.data(), binary.size());
    const uint64_t header[] = {key.size()}, tail[] = {binary.size(), check.value()};
    std::string out(reinterpret_cast<const char*>(header), sizeof header);
    out += key;
    out.append(reinterpret_cast<const char*>(tail), sizeof tail);
    return out + binary;
}

}  // namespace

std::string programCacheDirectory()
{
    if (const char* d = std::getenv("CAMBIUM_CACHE_DIR"))
        return *d ? std::string(d) + "/opencl" : std::string();
    if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x)
        return std::string(x) + "/cambium/opencl";
    if (const char* h = std::getenv("HOME"); h && *h)
        return std::string(h) + "/.cache/cambium/opencl";
    return {};
}

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
                           infoString(clGetDeviceInfo, d, CL_DEVICE_VERSION),
                           infoString(clGetPlatformInfo, p, CL_PLATFORM_VERSION),
                           infoString(clGetDeviceInfo, d, CL_DRIVER_VERSION), p, d});
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

cl_program OpenCLContext::buildFromSource(const std::string& source,
                                          const std::string& options) const
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

cl_program OpenCLContext::build(const std::string& source, const std::string& options) const
{
    // A driver compiles from source every time (PoCL preprocesses the whole
    // of OpenCL C's headers first, about 0.1 s a program even when its own
    // cache holds the result); a program built before is loaded from its
    // binary instead.
    const std::string dir = programCacheDirectory();
    if (dir.empty())
        return buildFromSource(source, options);
    const std::string key = fmt::format("cambium OpenCL program 2\n{}\n{}\n{}\n{}\n{}\n{}\n",
                                        info_.platform, info_.platformVersion, info_.device,
                                        info_.version, info_.driverVersion, options) +
                            source;
    const std::string path = fmt::format("{}/{:016x}.bin", dir, fnv1a64(key));
    const std::string binary = readCachedBinary(path, key);
    if (!binary.empty()) {
        const auto* bytes = reinterpret_cast<const unsigned char*>(binary.data());
        const size_t size = binary.size();
        cl_int status = CL_SUCCESS, err = CL_SUCCESS;
        cl_program program =
            clCreateProgramWithBinary(context_, 1, &info_.deviceId, &size, &bytes, &status, &err);
        if (err == CL_SUCCESS && status == CL_SUCCESS &&
            clBuildProgram(program, 1, &info_.deviceId, options.c_str(), nullptr, nullptr) ==
                CL_SUCCESS)
            return program;
        if (program)
            clReleaseProgram(program);  // (a damaged file: rebuilt and replaced below)
    }
    cl_program program = buildFromSource(source, options);
    size_t size = 0;
    if (clGetProgramInfo(program, CL_PROGRAM_BINARY_SIZES, sizeof size, &size, nullptr) ==
            CL_SUCCESS &&
        size > 0) {
        std::string built(size, '\0');
        unsigned char* at = reinterpret_cast<unsigned char*>(built.data());
        if (clGetProgramInfo(program, CL_PROGRAM_BINARIES, sizeof at, &at, nullptr) == CL_SUCCESS) {
            try {  // a cache that cannot be written costs the next run time, nothing else
                std::filesystem::create_directories(dir);
                const std::string out = cachedBinaryFile(key, built);
                writeFile(path, out.data(), out.size());
            } catch (const std::exception&) {
            }
        }
    }
    return program;
}

}  // namespace cambium
