// Frame sequences: `#` runs zero-padded to their length, frame ranges, and
// clear errors for anything else.
#include "core/error.h"
#include "core/frames.h"

#include <gtest/gtest.h>

namespace {

using namespace cambium;

TEST(Frames, PatternsArePaddedToTheirRun)
{
    EXPECT_EQ(framePath("out/tree.####.vdb", 12), "out/tree.0012.vdb");
    EXPECT_EQ(framePath("out/tree.#.vdb", 12), "out/tree.12.vdb");
    EXPECT_EQ(framePath("f##", 7), "f07");
    EXPECT_EQ(framePath("f###", -3), "f-003");
    EXPECT_TRUE(isFramePattern("a.#.vdb"));
    EXPECT_FALSE(isFramePattern("a.vdb"));
    EXPECT_THROW(framePath("a.vdb", 1), InputError);
    EXPECT_THROW(framePath("a.##.b.##.vdb", 1), InputError);
}

TEST(Frames, RangesListTheirFrames)
{
    EXPECT_EQ(parseFrames("5"), (std::vector<long long>{5}));
    EXPECT_EQ(parseFrames("1-4"), (std::vector<long long>{1, 2, 3, 4}));
    EXPECT_EQ(parseFrames("1-10:4"), (std::vector<long long>{1, 5, 9}));
    EXPECT_EQ(parseFrames("-2-1"), (std::vector<long long>{-2, -1, 0, 1}));
    EXPECT_EQ(parseFrames("1-270").size(), 270u);
    for (const char* bad : {"", "a", "4-1", "1-5:0", "1,2", "1-2-3", "1-"}) {
        try {
            parseFrames(bad);
            ADD_FAILURE() << "accepted '" << bad << "'";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("--frames"), std::string::npos) << e.what();
        }
    }
}

}  // namespace
