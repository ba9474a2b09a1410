// A libFuzzer harness for one input reader, CAMBIUM_FUZZ_HARNESS (readers.h).
#include "readers.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    cambium::fuzz::readOrRefuse(CAMBIUM_FUZZ_HARNESS,
                                std::string(reinterpret_cast<const char*>(data), size));
    return 0;
}
