// Tests of core/system: sizes read in the units they are printed in.
#include "core/error.h"
#include "core/system.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>

namespace cambium {
namespace {

TEST(System, ByteSizesReadInTheUnitsTheyArePrintedIn)
{
    EXPECT_DOUBLE_EQ(parseByteSize("2000000000", "--max-memory"), 2e9);
    EXPECT_DOUBLE_EQ(parseByteSize("8G", "--max-memory"), 8e9);
    EXPECT_DOUBLE_EQ(parseByteSize("512 MB", "--max-memory"), 512e6);
    EXPECT_DOUBLE_EQ(parseByteSize("1.5t", "--max-memory"), 1.5e12);
    EXPECT_DOUBLE_EQ(parseByteSize("3k", "--max-memory"), 3e3);
    EXPECT_DOUBLE_EQ(parseByteSize("2E", "--max-memory"), 2e18);
    // What a command echoes of a size it was given is that size.
    for (const auto& [given, echoed] : {std::pair{"8G", "8 GB"},
                                        {"512M", "512 MB"},
                                        {"1.5T", "1.5 TB"},
                                        {"750k", "750 KB"},
                                        {"2P", "2 PB"}})
        EXPECT_EQ(formatBytes(parseByteSize(given, "--max-memory")), echoed) << given;
    EXPECT_EQ(formatBytes(parseByteSize("8G", "--max-memory")), "8 GB");
    for (const char* bad : {"", "G", "-8G", "8X", "8 GiB", "0", "0.5", "1e9", "8GG", "nan"})
        EXPECT_THROW(parseByteSize(bad, "--max-memory"), InputError) << bad;
    try {
        parseByteSize("12X", "--max-memory");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("--max-memory"), std::string::npos);
        EXPECT_NE(std::string(e.what()).find("12X"), std::string::npos);
    }
}

TEST(System, WorkThatWouldNotFitIsRefusedWithItsNumbers)
{
    EXPECT_NO_THROW(checkMemoryFits(1.0, "one byte"));
    EXPECT_THROW(checkMemoryFits(std::nan(""), "an estimate that failed"), InputError);
    try {
        checkMemoryFits(2e18, "tree.json: a voxel size of 1e-9", "use a larger --voxel-size");
        FAIL();
    } catch (const InputError& e) {
        const std::string m = e.what();
        EXPECT_EQ(m.rfind("tree.json: a voxel size of 1e-9 needs about 2 EB of memory, and this "
                          "machine has ",
                          0),
                  0u)
            << m;
        EXPECT_NE(m.find(" available: use a larger --voxel-size"), std::string::npos) << m;
    }
}

}  // namespace
}  // namespace cambium
