// Fuzzing the growth parameter reader (and the growth model's first years).
#include "fuzz_util.h"
#include "model/growth.h"
#include "model/growth_params.h"

#include <algorithm>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    cambium::fuzz::readOrRefuse([&] {
        const cambium::GrowthParameters p = cambium::parseGrowthParameters(cambium::fuzz::text(data, size), "fuzz.json");
        const cambium::GrowthModel model(p);
        model.skeleton(std::min(2.0, double(p.years)), true);
    });
    return 0;
}
