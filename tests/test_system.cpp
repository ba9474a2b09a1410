// Tests of core/system (sizes read in the units they are printed in),
// core/process (a command run, its status, output and own peak memory) and
// core/memory (scratch blocks recycled).
#include "bench/process_run.h"
#include "core/error.h"
#include "core/files.h"
#include "core/memory.h"
#include "core/process.h"
#include "core/system.h"
#include "test_util.h"

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>
#include <unistd.h>
#include <sys/wait.h>
#include <sys/resource.h>
#include <sys/mman.h>
#include <tbb/parallel_for.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace cambium {
namespace {

/// How many of the pages of [p, p + bytes) are resident (mincore).
size_t residentPages(const void* p, size_t bytes)
{
    const size_t page = 4096, n = (bytes + page - 1) / page;
    std::vector<unsigned char> in(n);
    EXPECT_EQ(mincore(const_cast<void*>(p), n * page, in.data()), 0);
    size_t count = 0;
    for (unsigned char c : in)
        count += c & 1u;
    return count;
}

TEST(Scratch, ABlockGivenBackIsHandedOutAgainWithItsPages)
{
    if (!scratchUse().inRegion)
        GTEST_SKIP() << "blocks come from the allocator here (AddressSanitizer)";
    constexpr size_t mb = size_t(1) << 20;
    trimScratch();
    // (Free pages are kept up to the most in use.)
    auto held = parallelArray<char>(16 * mb);
    auto a = parallelArray<char>(8 * mb);
    char* at = a.get();
    EXPECT_EQ(residentPages(at, 8 * mb), 8 * mb / 4096);  // faulted in when made
    const size_t fresh = scratchUse().fresh;
    a.reset();
    EXPECT_EQ(residentPages(at, 8 * mb), 8 * mb / 4096);  // kept
    // A block of the same size, and two that together fill it: the same
    // pages, no new ones.
    auto b = parallelArray<char>(8 * mb);
    EXPECT_EQ(b.get(), at);
    b.reset();
    auto c = parallelArray<char>(3 * mb), d = parallelArray<char>(5 * mb);
    EXPECT_EQ(c.get(), at);
    EXPECT_EQ(d.get(), at + 3 * mb);
    EXPECT_EQ(scratchUse().fresh, fresh);
    // Given back, the two merge again into one run that holds 8 MB.
    c.reset();
    d.reset();
    auto e = parallelArray<char>(8 * mb);
    EXPECT_EQ(e.get(), at);
    EXPECT_EQ(scratchUse().fresh, fresh);
    e.reset();
    held.reset();
    // 24 MB free: as much is kept as the budget allows, the lowest pages.
    const size_t budget = std::min(32 * mb, scratchUse().highWater);
    EXPECT_GE(budget, 24 * mb);
    EXPECT_EQ(scratchUse().keptFree, std::min(budget, 24 * mb));
    trimScratch();
    EXPECT_EQ(scratchUse().keptFree, 0u);
    EXPECT_EQ(residentPages(at, 8 * mb), 0u);
}

TEST(Scratch, ASmallBlockComesFromTheAllocator)
{
    // (Its pages stay in the allocator's heap for the next.)
    const ScratchUse before = scratchUse();
    auto a = parallelArray<char>(512 * 1024);
    EXPECT_EQ(scratchUse().inUse, before.inUse);
    EXPECT_EQ(scratchUse().fresh, before.fresh);
}

TEST(Scratch, AtMost32MBOfFreePagesAreKept)
{
    if (!scratchUse().inRegion)
        GTEST_SKIP() << "blocks come from the allocator here (AddressSanitizer)";
    constexpr size_t mb = size_t(1) << 20;
    trimScratch();
    std::vector<ParallelArray<char>> blocks;  // 96 MB in use
    for (int k = 0; k < 6; ++k)
        blocks.push_back(parallelArray<char>(16 * mb));
    std::vector<char*> at;
    for (const auto& b : blocks)
        at.push_back(b.get());
    blocks.clear();
    size_t resident = 0;
    for (char* p : at)
        resident += residentPages(p, 16 * mb);
    EXPECT_EQ(scratchUse().keptFree, 32 * mb);
    EXPECT_EQ(resident * 4096, 32 * mb);
    // The lowest are kept: a block as large comes from them without faults.
    const size_t fresh = scratchUse().fresh;
    auto again = parallelArray<char>(32 * mb);
    EXPECT_EQ(again.get(), *std::min_element(at.begin(), at.end()));
    EXPECT_EQ(scratchUse().fresh, fresh);
    // One larger than what is kept comes from dropped pages, faulted in.
    auto more = parallelArray<char>(48 * mb);
    EXPECT_EQ(scratchUse().fresh, fresh + 48 * mb);
    EXPECT_EQ(residentPages(more.get(), 48 * mb), 48 * mb / 4096);
    again.reset();
    more.reset();
    trimScratch();
    EXPECT_EQ(scratchUse().keptFree, 0u);
    EXPECT_EQ(scratchUse().inUse, 0u);
}

TEST(Scratch, BlocksTakenAndGivenBackOnAllThreadsNeverOverlap)
{
    // Each block holds its owner's stamp from when it is made until it is
    // given back; another block sharing its pages would overwrite it.
    std::atomic<int> damaged{0};
    tbb::parallel_for(0, 400, [&](int i) {
        const size_t n = size_t(1 + (i * 7919) % 97) * 37 * 1024;  // 37 kB to 3.6 MB
        auto b = parallelArray<uint32_t>(n / 4);
        for (size_t k = 0; k < n / 4; k += 512)
            b[k] = uint32_t(i);
        for (int round = 0; round < 3; ++round)
            for (size_t k = 0; k < n / 4; k += 512)
                damaged += b[k] != uint32_t(i);
    });
    EXPECT_EQ(damaged.load(), 0);
    EXPECT_EQ(scratchUse().inUse, 0u);
}

TEST(Scratch, ALimitOnAddressSpaceIsNotSpentOnTheRegion)
{
    // The region reserves address space as large as the machine's memory. A
    // process under a limit on address space (ulimit -v) makes none, and one
    // whose limit came after it does not count the reservation as used.
    const int before = cambium::test::statusUnderAddressSpaceLimit(64e6 + 1e9, [] {
        auto a = parallelArray<char>(16 << 20);  // (the region's first block, where there is one)
        a.reset();
        const double room = availableMemoryBytes();
        return room > 0.7e9 && room < 1.3e9 ? 0 : 1;
    });
    if (before == -1)
        GTEST_SKIP() << "no address-space limit to try (ASan, or a limit set already)";
    EXPECT_EQ(before, 0);
    {
        auto made = parallelArray<char>(16 << 20);
        if (!scratchUse().inRegion)
            return;  // (made by a test before, under a limit)
    }
    const int after = cambium::test::statusUnderAddressSpaceLimit(64e6 + 1e9, [] {
        const double room = availableMemoryBytes();
        return room > 0.7e9 && room < 1.3e9 ? 0 : 1;
    });
    EXPECT_EQ(after, 0);
}

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

TEST(System, TheRoomLeftIsTheLeastOfTheMachineUlimitAndCgroup)
{
    MemoryLimits m;
    m.available = 8e9;
    EXPECT_EQ(m.room(), 8e9);  // no limits set
    m.addressSpaceLimit = 6e9;
    m.addressSpaceUsed = 1e9;
    EXPECT_EQ(m.room(), 5e9);  // ulimit -v 6 GB, 1 GB mapped
    m.cgroupMax = 4e9;
    m.cgroupCurrent = 3e9;
    EXPECT_EQ(m.room(), 1e9);  // a job's allocation of 4 GB, 3 GB in use
    m.cgroupCurrent = 5e9;
    EXPECT_EQ(m.room(), 0.0);
    // This process under an address-space limit 1 GB above what it maps:
    // about 1 GB of room, whatever the machine has (a shape past `ulimit -v`
    // was accepted, then ran out of memory after 27 s).
    const int status = cambium::test::statusUnderAddressSpaceLimit(64e6 + 1e9, [] {
        const double room = availableMemoryBytes();
        return room > 0.7e9 && room < 1.3e9 ? 0 : 1;
    });
    if (status == -1)
        GTEST_SKIP() << "no address-space limit to try (ASan, or a limit set already)";
    EXPECT_EQ(status, 0);
}

TEST(System, RunningOutOfMemoryWithATreeHeldEndsInBadAllocNotTerminate)
{
    // A tree grown until memory runs out, then freed by the unwinding:
    // OpenVDB's Tree::clear lists the nodes before it frees them, which
    // threw again inside the destructor ("terminate called", SIGABRT: mesh
    // of a long needle, sweep 23).  The reserve released by the first
    // failure leaves that list room.
    const int status = cambium::test::statusUnderAddressSpaceLimit(3e8, [] {
        installMemoryReserve();
        try {
            openvdb::FloatTree tree(1.0f);
            for (int i = 0;; ++i)
                tree.touchLeaf(openvdb::Coord(i * 128, 0, 0));
        } catch (const std::bad_alloc&) {
            return 0;
        }
    });
    if (status == -1)
        GTEST_SKIP() << "no address-space limit to try (ASan, or a limit set already)";
    EXPECT_EQ(status, 0) << "128: a signal (terminate)";
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

std::string readAll(const std::string& path)
{
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

TEST(Process, ACommandsStatusAndOutput)
{
    const ScratchDirectory scratch(ScratchDirectory::temporaryPath("test_process"));
    const std::string dir = scratch.path();
    const std::string log = dir + "/log.txt", peak = dir + "/peak";
    const ChildRun run = runChild({"/bin/sh", "-c", "echo out; echo err >&2; exit 3"}, {log, peak});
    EXPECT_EQ(run.status, 3);
    EXPECT_EQ(readAll(log), "out\nerr\n");  // (GNU time's own line goes to its file)
    EXPECT_FALSE(std::filesystem::exists(peak));
    EXPECT_GT(run.seconds, 0.0);
    // Ended by a signal: 128 + the signal.
    EXPECT_EQ(runChild({"/bin/sh", "-c", "kill -9 $$"}, {log, peak}).status, 128 + 9);
    // No log: its output discarded (this process's own is untouched).
    EXPECT_EQ(runChild({"/bin/sh", "-c", "echo lost"}, {"", peak}).status, 0);
    EXPECT_THROW(runChild({dir + "/no-such-program"}, {"", ""}), std::runtime_error);
}

TEST(Process, ABenchmarkedCommandsFailureSaysItsLastWords)
{
    // (the benchmark's scratch directory, where its log was, is gone when
    // the message is read: the message carries the output's end)
    ASSERT_TRUE(measuresOwnPeak());
    const ScratchDirectory scratch(ScratchDirectory::temporaryPath("test_process_fail"));
    const std::string log = scratch.path() + "/log.txt";
    try {
        runProcess({"/bin/sh", "-c", "echo early; echo 'the reason\n' >&2; exit 3"}, log);
        ADD_FAILURE() << "no error";
    } catch (const std::runtime_error& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("/bin/sh failed (exit 3); it said: early the reason"), std::string::npos)
            << m;
        EXPECT_EQ(m.find(log), std::string::npos) << m;
    }
    try {
        runProcess({"/bin/sh", "-c", "exit 4"}, log + ".2");
        ADD_FAILURE() << "no error";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("(exit 4); it printed nothing"), std::string::npos)
            << e.what();
    }
}

TEST(Process, APeakIsTheCommandsOwnNotThisProcesss)
{
    ASSERT_TRUE(measuresOwnPeak())
        << "GNU time is missing: bash tools/setup.sh packages installs it";
    // This process reaches 600 MB (touched); the command, dd with a 96 MB
    // buffer, stays near 100 MB.  A child of this process would start
    // from 600 MB.
    std::vector<char> big(size_t(600) << 20);
    volatile char* touch = big.data();
    for (size_t i = 0; i < big.size(); i += 4096)
        touch[i] = 1;
    const ScratchDirectory scratch(ScratchDirectory::temporaryPath("test_process_peak"));
    const ChildRun run = runChild({"/bin/dd", "if=/dev/zero", "of=/dev/null", "bs=96M", "count=2"},
                                  {"", scratch.path() + "/peak"});
    EXPECT_EQ(run.status, 0);
    EXPECT_TRUE(run.peakExact);
    EXPECT_GT(run.peakBytes, 96e6);
    EXPECT_LT(run.peakBytes, 200e6) << "not the command's own peak";
    EXPECT_GT(peakMemoryBytes(), 600e6);
}

}  // namespace
}  // namespace cambium

TEST(Messages, PrintableEscapesControlsAndBidiOverridesAndShortenedKeepsBothEnds)
{
    using cambium::printable;
    using cambium::shortened;
    EXPECT_EQ(printable("a\nb\x1b[31m"), "a\\x0ab\\x1b[31m");
    // U+202E (right-to-left override) and U+2066 (left-to-right isolate)
    // escaped; other multi-byte characters (an e acute, U+2014) kept.
    EXPECT_EQ(printable("x\xe2\x80\xaey\xe2\x81\xa6z"), "x\\u{202e}y\\u{2066}z");
    EXPECT_EQ(printable("caf\xc3\xa9 \xe2\x80\x94 ok"), "caf\xc3\xa9 \xe2\x80\x94 ok");
    // Invalid UTF-8 (a lone continuation byte, a cut sequence, an overlong
    // slash, a surrogate, past U+10FFFF) byte by byte; a C1 control (U+009B,
    // a terminal's CSI) as \u; a 4-byte character kept.
    EXPECT_EQ(printable("a\x80"
                        "b\xc3"),
              "a\\x80b\\xc3");
    EXPECT_EQ(printable("\xc0\xaf\xed\xa0\x80\xf4\x90\x80\x80"),
              "\\xc0\\xaf\\xed\\xa0\\x80\\xf4\\x90\\x80\\x80");
    EXPECT_EQ(printable("\xc2\x9b"
                        "31m \xf0\x9f\x8c\xb3"),
              "\\u{009b}31m \xf0\x9f\x8c\xb3");
    EXPECT_EQ(shortened("short", 10), "short");
    const std::string key = "file.json: root." + std::string(100000, 'k') + ": unknown field";
    const std::string s = shortened(key, 300);
    EXPECT_LE(s.size(), 300u);  // (its marker counted)
    EXPECT_EQ(s.rfind("file.json: root.kkk", 0), 0u) << s;
    EXPECT_NE(s.find("characters left out"), std::string::npos) << s;
    EXPECT_EQ(s.substr(s.size() - 15), ": unknown field") << s;
    // A cut never splits a UTF-8 character.
    const std::string accents = std::string(50, 'a') + [] {
        std::string e;
        for (int i = 0; i < 200; ++i)
            e += "\xc3\xa9";
        return e;
    }();
    const std::string t = shortened(accents, 101);
    for (size_t i = 0; i + 1 < t.size(); ++i) {
        if (static_cast<unsigned char>(t[i]) == 0xc3) {
            EXPECT_EQ(static_cast<unsigned char>(t[i + 1]), 0xa9) << i;
        }
    }
    EXPECT_NE(static_cast<unsigned char>(t.back()), 0xc3);
}

TEST(Messages, ATextFilesByteOrderMarkIsReadPast)
{
    // (an L-system's first line read as "unknown line 'Axiom: F'", with the
    // invisible U+FEFF in the message)
    const std::string path =
        (std::filesystem::temp_directory_path() / ("cambium_bom_" + std::to_string(::getpid())))
            .string();
    std::ofstream(path, std::ios::binary) << "\xEF\xBB\xBF"
                                             "Axiom: F\n";
    EXPECT_EQ(cambium::readTextFile(path, "L-system file"), "Axiom: F\n");
    std::ofstream(path, std::ios::binary) << "Axiom: \xEF\xBB\xBF"
                                             "F\n";  // (only at the start)
    EXPECT_EQ(cambium::readTextFile(path, "L-system file"),
              "Axiom: \xEF\xBB\xBF"
              "F\n");
    std::filesystem::remove(path);
}
