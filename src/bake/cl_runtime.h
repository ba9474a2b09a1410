// cambium — a small OpenCL 1.2 runtime wrapper (platform, device, context,
// queue, program builds with readable errors).
#pragma once

#include <CL/cl.h>

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
    cl_platform_id platformId = nullptr;
    cl_device_id deviceId = nullptr;
};

/// Every device of every platform; empty when no OpenCL platform is installed.
std::vector<OpenCLDeviceInfo> listOpenCLDevices();

/// Throws OpenCLError naming `what` and the error code when `status` is not CL_SUCCESS.
void checkCL(cl_int status, const char* what);

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
    cl_program build(const std::string& source, const std::string& options = "") const;

private:
    OpenCLDeviceInfo info_;
    cl_context context_ = nullptr;
    cl_command_queue queue_ = nullptr;
};

}  // namespace cambium
