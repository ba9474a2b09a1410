// Fuzzing the JSON scene reader (and the BlobTree it builds).
#include "blobtree/scene_io.h"
#include "blobtree/stats.h"
#include "fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    cambium::fuzz::readOrRefuse([&] {
        const cambium::BlobTree tree = cambium::parseScene(cambium::fuzz::text(data, size), "fuzz.json");
        cambium::computeStats(tree);
    });
    return 0;
}
