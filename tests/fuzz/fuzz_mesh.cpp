// Fuzzing the OBJ and PLY readers: the first byte picks the format.
#include "fuzz_util.h"
#include "use/mesh.h"

#include <sstream>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    if (size == 0)
        return 0;
    const std::string format = data[0] & 1 ? "ply" : "obj";
    std::istringstream in(cambium::fuzz::text(data + 1, size - 1));
    cambium::fuzz::readOrRefuse([&] { cambium::parseMesh(in, "fuzz." + format, format); });
    return 0;
}
