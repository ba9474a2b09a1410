// The libFuzzer entry of every harness, compiled once: each fuzz_<name>
// binary links it with the one line that names its reader (readers.h).
#include "readers.h"

extern "C" const char* const cambiumFuzzHarness;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    cambium::fuzz::readOrRefuse(cambiumFuzzHarness,
                                std::string(reinterpret_cast<const char*>(data), size));
    return 0;
}
