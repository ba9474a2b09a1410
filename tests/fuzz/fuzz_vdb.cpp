// Fuzzing the .vdb opener of `mesh` and `render` (readLevelSet): the
// structure check, then OpenVDB's reading of what it vouched for.
#include "fuzz_util.h"
#include "use/grid_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    static const bool initialized = [] {
        openvdb::initialize();
        return true;
    }();
    (void)initialized;
    const std::string path = cambium::fuzz::asFile(data, size, ".vdb");
    cambium::fuzz::readOrRefuse([&] { cambium::readLevelSet(path); });
    return 0;
}
