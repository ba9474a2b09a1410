// Every input that once made a reader fail (tests/fuzz/regressions/<harness>/,
// kept from the fuzzers' findings) and every seed is read or refused with an
// InputError by the reader its fuzzer drives (tests/fuzz/readers.h).
#include "fuzz/readers.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>

namespace {

namespace fs = std::filesystem;

TEST(FuzzRegressions, EveryKeptInputIsReadOrRefused)
{
    const fs::path root = CAMBIUM_SOURCE_DIR "/tests/fuzz";
    size_t inputs = 0;
    for (const auto& [name, reader] : cambium::fuzz::readers())
        for (const char* kind : {"regressions", "seeds"}) {
            if (!fs::exists(root / kind / name))
                continue;
            for (const auto& e : fs::directory_iterator(root / kind / name)) {
                if (!e.is_regular_file() || e.path().filename().string()[0] == '.')
                    continue;
                std::ifstream in(e.path(), std::ios::binary);
                const std::string bytes(std::istreambuf_iterator<char>(in), {});
                EXPECT_NO_THROW(cambium::fuzz::readOrRefuse(name, bytes)) << e.path();
                ++inputs;
            }
        }
    EXPECT_GE(inputs, 2u);  // the seeds at least
}

}  // namespace
