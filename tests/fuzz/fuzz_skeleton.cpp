// Fuzzing the skeleton reader and the tree builder on what it reads.
#include "fuzz_util.h"
#include "model/skeleton.h"
#include "model/tree_builder.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    cambium::fuzz::readOrRefuse([&] {
        const cambium::Skeleton sk = cambium::parseSkeleton(cambium::fuzz::text(data, size), "fuzz.txt");
        if (sk.internodes.size() <= 200)
            cambium::buildTree(sk);
    });
    return 0;
}
