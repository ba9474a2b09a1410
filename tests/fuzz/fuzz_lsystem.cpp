// Fuzzing the L-system reader, the deriver and the turtle, with the
// derivation bounded so that an input's run stays short.
#include "fuzz_util.h"
#include "model/lsystem.h"
#include "model/turtle.h"

#include <algorithm>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    cambium::fuzz::readOrRefuse([&] {
        const cambium::LSystem sys = cambium::parseLSystem(cambium::fuzz::text(data, size), "fuzz.l");
        const cambium::ModuleString s =
            cambium::derive(sys, std::min(sys.derivationLength, 8), sys.seed, 20000);
        cambium::interpretTurtle(sys, s);
    });
    return 0;
}
