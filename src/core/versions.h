// cambium — versions of cambium and the libraries it was built with.
#pragma once

#include <string>
#include <utility>
#include <vector>

namespace cambium {

const char* version();

/// (library, version) pairs: compile-time versions of OpenVDB, NanoVDB,
/// OpenImageIO, Embree and TBB (the OpenCL devices: listOpenCLDevices).
std::vector<std::pair<std::string, std::string>> dependencyVersions();

}  // namespace cambium
