// cambium — dependency versions.  This file only includes the libraries'
// version headers, so it stays quick to compile.
#include "core/versions.h"

#include <OpenImageIO/oiioversion.h>
#include <embree3/rtcore_config.h>
#include <nanovdb/NanoVDB.h>
#include <oneapi/tbb/version.h>
#include <openvdb/version.h>

#include <fmt/format.h>

namespace cambium {

const char* version()
{
    return CAMBIUM_VERSION;
}

std::vector<std::pair<std::string, std::string>> dependencyVersions()
{
    return {
        {"OpenVDB", OPENVDB_LIBRARY_VERSION_STRING},
        {"NanoVDB", fmt::format("{}.{}.{}", NANOVDB_MAJOR_VERSION_NUMBER,
                                NANOVDB_MINOR_VERSION_NUMBER, NANOVDB_PATCH_VERSION_NUMBER)},
        {"OpenImageIO", OIIO_VERSION_STRING},
        {"Embree", RTC_VERSION_STRING},
        {"TBB", fmt::format("{} (runtime {})", TBB_VERSION_STRING, TBB_runtime_version())},
    };
}

}  // namespace cambium
