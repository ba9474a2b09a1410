// The one checked writer: files appear whole or not at all, a failed write
// fails and keeps the old file, non-regular outputs are refused, symlinks are
// written through, stale temporaries are found by their pattern only, and the
// output lock keeps a second writer out; the files' checksum keeps its
// definition.
#include "temp_dir.h"
#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"

#include <gtest/gtest.h>

#include <climits>
#include <cmath>

#include <algorithm>
#include <cstdlib>
#include <cerrno>
#include <filesystem>
#include <fstream>
#include <ostream>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

namespace {

using namespace cambium;
namespace fs = std::filesystem;

using cambium::test::freshDir;

std::string contents(const fs::path& p)
{
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

/// The files in a directory, by name.
std::vector<std::string> listing(const fs::path& dir)
{
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir))
        names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

TEST(Files, WritesWholeFilesWithSeeksAndNoTemporaryLeft)
{
    const fs::path dir = freshDir("cambium_files_write");
    const std::string path = (dir / "a.bin").string();
    writeFile(path, [](std::ostream& out) {
        out << "0123456789";
        EXPECT_EQ(out.tellp(), std::streampos(10));
        out.seekp(2);
        out << "ab";  // overwrite in place, as OpenVDB does with grid offsets
        out.seekp(0, std::ios::end);
        out << std::string(1 << 20, 'x');  // larger than the buffer
    });
    const std::string s = contents(path);
    ASSERT_EQ(s.size(), 10u + (1u << 20));
    EXPECT_EQ(s.substr(0, 10), "01ab456789");
    EXPECT_EQ(listing(dir), std::vector<std::string>{"a.bin"});
}

TEST(Files, AFailureInsideTheWriteKeepsTheOldFileAndRemovesTheTemporary)
{
    const fs::path dir = freshDir("cambium_files_fail");
    const std::string path = (dir / "a.bin").string();
    writeFile(path, "old", 3);
    ::chmod(path.c_str(), 0600);
    EXPECT_THROW(writeFile(path,
                           [](std::ostream& out) {
                               out << std::string(1 << 20, 'n');
                               throw std::runtime_error("injected failure half-way");
                           }),
                 WriteError);
    EXPECT_EQ(contents(path), "old");
    EXPECT_EQ(listing(dir), std::vector<std::string>{"a.bin"});
    // A write that succeeds keeps the file's permissions.
    writeFile(path, "new", 3);
    struct stat st;
    ASSERT_EQ(::stat(path.c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0600u);
    EXPECT_EQ(contents(path), "new");
}

TEST(Files, AFullDeviceFailsTheWriteWithItsReason)
{
    // A small tmpfs, when this process may mount one (the tests run as root).
    const fs::path dir = freshDir("cambium_files_full");
    if (::geteuid() != 0 ||
        std::system(
            ("mount -t tmpfs -o size=64k tmpfs " + dir.string() + " 2>/dev/null").c_str()) != 0)
        GTEST_SKIP() << "cannot mount a tmpfs here (not root, or no mount permission)";
    const std::string path = (dir / "a.bin").string();
    writeFile(path, "old", 3);
    try {
        writeFile(path, [](std::ostream& out) { out << std::string(1 << 20, 'n'); });
        ADD_FAILURE() << "a 1 MB write into 64 KB succeeded";
    } catch (const WriteError& e) {
        EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos)
            << e.what();
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
    }
    EXPECT_EQ(contents(path), "old");
    EXPECT_EQ(listing(dir), std::vector<std::string>{"a.bin"});
    std::system(("umount " + dir.string()).c_str());
}

TEST(Files, OutputsThatAreNotRegularFilesAreRefused)
{
    const fs::path dir = freshDir("cambium_files_kinds");
    EXPECT_THROW(checkOutputPath(""), InputError);
    EXPECT_THROW(checkOutputPath(dir.string()), InputError);
    EXPECT_THROW(checkOutputPath(dir.string() + "/"), InputError);
    EXPECT_THROW(checkOutputPath("/dev/null"), InputError);
    EXPECT_THROW(checkOutputPath("/dev/full"), InputError);
    const std::string fifo = (dir / "fifo.vdb").string();
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0644), 0);
    try {
        checkOutputPath(fifo);
        ADD_FAILURE() << "a FIFO was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("FIFO"), std::string::npos) << e.what();
    }
    EXPECT_THROW(writeFile(fifo, "x", 1), InputError);
    EXPECT_THROW(checkOutputPath((dir / "no/such/dir/a.vdb").string()), InputError);
    // A link to a device is refused like the device.
    fs::create_symlink("/dev/null", dir / "null.vdb");
    EXPECT_THROW(checkOutputPath((dir / "null.vdb").string()), InputError);
    // A dangling link is refused.
    fs::create_symlink(dir / "nowhere.vdb", dir / "dangling.vdb");
    EXPECT_THROW(checkOutputPath((dir / "dangling.vdb").string()), InputError);
}

TEST(Files, ASymlinkIsWrittenThroughAndKept)
{
    const fs::path dir = freshDir("cambium_files_link");
    fs::create_directories(dir / "real");
    const std::string target = (dir / "real" / "a.vdb").string();
    writeFile(target, "old", 3);
    fs::create_symlink(target, dir / "link.vdb");
    EXPECT_EQ(checkOutputPath((dir / "link.vdb").string()), fs::canonical(target).string());
    writeFile((dir / "link.vdb").string(), "new", 3);
    EXPECT_TRUE(fs::is_symlink(dir / "link.vdb"));
    EXPECT_EQ(contents(target), "new");
    EXPECT_EQ(listing(dir / "real"), std::vector<std::string>{"a.vdb"});
}

TEST(Files, APartsLinkMadeDuringTheWorkIsReplacedNotWrittenThrough)
{
    // A frame checked before the work (no link then), then linked to
    // another file while the sequence ran: the frame replaces the link,
    // and the file the link names keeps its bytes (sweep 27: a frame and a
    // mesh written through such links replaced a file outside the pattern
    // and an earlier frame).
    const fs::path dir = freshDir("cambium_files_part_link");
    const std::string victim = (dir / "victim.vdb").string(), frame = (dir / "f.0002.vdb").string(),
                      other = (dir / "f.0001.vdb").string();
    writeFile(victim, "precious", 8);
    writeFile(other, "frame 1", 7);
    checkPartIsNoLink(frame, "frame of a sequence");
    checkPartIsNoLink(other, "frame of a sequence");
    fs::create_symlink(victim, frame);
    errno = 0;  // (as a fresh thread starts: the check read a stale errno)
    writeFile(frame, "frame 2", 7);
    EXPECT_FALSE(fs::is_symlink(frame));
    EXPECT_EQ(contents(frame), "frame 2");
    EXPECT_EQ(contents(victim), "precious");
    // a link to another frame, and a dangling one
    fs::remove(frame);
    fs::create_symlink(other, frame);
    errno = 0;
    writeFile(frame, "frame 2", 7);
    EXPECT_EQ(contents(other), "frame 1");
    EXPECT_EQ(contents(frame), "frame 2");
    fs::remove(frame);
    fs::create_symlink(dir / "nowhere", frame);
    errno = 0;
    writeFile(frame, "frame 2", 7);
    EXPECT_EQ(contents(frame), "frame 2");
    EXPECT_FALSE(fs::exists(dir / "nowhere"));
    EXPECT_EQ(listing(dir), (std::vector<std::string>{"f.0001.vdb", "f.0002.vdb", "victim.vdb"}));
}

TEST(Files, StaleTemporariesAreThoseOfThePatternOnly)
{
    const fs::path dir = freshDir("cambium_files_stale");
    for (const char* name :
         {"tree.0001.vdb.tmp-99999999", "tree.0012.vdb.tmp-4", "tree.12345.vdb.tmp-7",
          // not ours: other patterns, other names, a frame itself
          "tree.0001.vdb", "tree.001.vdb.tmp-5", "tree.0001.vdb.tmp-", "tree.0001.vdb.tmp-5x",
          "bush.0001.vdb.tmp-5", "tree.0001.exr.tmp-5", "tree.00a1.vdb.tmp-5", "notes.txt"})
        std::ofstream(dir / name) << "x";
    const std::vector<std::string> found = staleTemporaries((dir / "tree.####.vdb").string());
    std::vector<std::string> names;
    for (const std::string& f : found)
        names.push_back(fs::path(f).filename().string());
    EXPECT_EQ(names, (std::vector<std::string>{"tree.0001.vdb.tmp-99999999", "tree.0012.vdb.tmp-4",
                                               "tree.12345.vdb.tmp-7"}));
    // A single file's: its own (a bake removes them before it bakes: a
    // killed bake's temporary does not outlive the next bake of the file).
    for (const char* name : {"one.vdb.tmp-99999998", "one.vdb.tmp-3", "xone.vdb.tmp-3",
                             "one.vdb.tmp-3x", "one.vdbx.tmp-3"})
        std::ofstream(dir / name) << "x";
    names.clear();
    for (const std::string& f : staleTemporaries((dir / "one.vdb").string()))
        names.push_back(fs::path(f).filename().string());
    EXPECT_EQ(names, (std::vector<std::string>{"one.vdb.tmp-3", "one.vdb.tmp-99999998"}));
    // Each names the file it stands for, as the writer names its temporary.
    for (const std::string& f : found)
        EXPECT_EQ(temporaryPathFor(temporaryTarget(f)).rfind(temporaryTarget(f) + ".tmp-", 0), 0u);
    EXPECT_EQ(temporaryTarget("/d/tree.0012.vdb.tmp-4"), "/d/tree.0012.vdb");
    EXPECT_EQ(temporaryTarget(temporaryPathFor("/d/a.tmp-1.vdb")), "/d/a.tmp-1.vdb");
}

TEST(Files, TheOutputLockKeepsASecondWriterOutAndNamesTheHolder)
{
    const fs::path dir = freshDir("cambium_files_lock");
    const std::string pattern = (dir / "tree.####.vdb").string();
    {
        const OutputLock first(pattern);
        EXPECT_TRUE(fs::exists(first.path()));
        try {
            const OutputLock second(pattern);
            ADD_FAILURE() << "two locks on one pattern";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("pid " + std::to_string(::getpid())),
                      std::string::npos)
                << e.what();
        }
    }
    EXPECT_TRUE(listing(dir).empty());  // the lock file goes with the lock
    const OutputLock again(pattern);    // and can be taken again
}

TEST(Files, RangeLocksLetDisjointRunsWriteSideBySideAndKeepOverlapsOut)
{
    // The tasks of a farm write disjoint frame ranges of one pattern at once;
    // a run whose frames overlap a live run's, or one of every frame, is
    // refused, naming the holder's frames; a lock a killed run left is taken
    // over.
    const fs::path dir = freshDir("cambium_files_range_lock");
    const std::string pattern = (dir / "tree.####.vdb").string();
    auto refused = [&](long long a, long long b, const std::string& frames) {
        try {
            const OutputLock l = a == LLONG_MIN ? OutputLock(pattern) : OutputLock(pattern, a, b);
            ADD_FAILURE() << "frames " << a << "-" << b << " locked beside " << frames;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(frames), std::string::npos) << e.what();
        }
    };
    {
        const OutputLock first(pattern, 1, 4), second(pattern, 5, 8);
        EXPECT_TRUE(fs::exists(first.path()));
        EXPECT_TRUE(fs::exists(second.path()));
        refused(4, 5, "frames 1 to 4");
        refused(8, 20, "frames 5 to 8");
        refused(LLONG_MIN, LLONG_MAX, "frames 1 to 4");
        const OutputLock third(pattern, 9, 12);
    }
    EXPECT_TRUE(listing(dir).empty());  // every lock file went with its lock
    {
        const OutputLock all(pattern);
        refused(3, 3, "every frame");
    }
    // A killed run's lock: its file is there, nobody holds it.
    std::ofstream(pattern + ".frames-2-6.lock") << "999999999\n";
    {
        const OutputLock over(pattern, 1, 3);
        EXPECT_FALSE(fs::exists(pattern + ".frames-2-6.lock"));
    }
    EXPECT_TRUE(listing(dir).empty());
}

TEST(Files, APlanThatDoesNotFitTheOutputsDiskIsRefusedWithItsNumbers)
{
    const fs::path dir = freshDir("cambium_files_disk");
    const std::string out = (dir / "f.vdb").string();
    const double free = freeDiskBytes(out);
    ASSERT_GT(free, 0.0);
    EXPECT_NO_THROW(checkDiskSpace(out, 1e3, "a small file"));
    try {
        checkDiskSpace(out, 2.0 * free + 1e15, "27 frames of x.####.vdb");
        ADD_FAILURE() << "more than the disk holds";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("27 frames of x.####.vdb would need about "), std::string::npos)
            << what;
        EXPECT_NE(what.find(dir.string() + " has "), std::string::npos) << what;
    }
    // A directory that is not there: the output check names it, not this.
    EXPECT_TRUE(std::isinf(freeDiskBytes((dir / "no" / "f.vdb").string())));
}

TEST(Files, TheChecksumIsItsDefinitionFedInPiecesOfAnySize)
{
    // `cambium_checksum` is stored in every .vdb cambium wrote: its value for
    // given bytes never changes (pinned from its first definition), however
    // the reader splits them.
    std::string bytes;
    for (int i = 0; i < 1000; ++i)
        bytes.push_back(char((i * 131 + 7) & 255));
    Checksum64 whole;
    whole.update(bytes.data(), bytes.size());
    EXPECT_EQ(whole.value(), 0x430cad965974113cull);
    for (size_t first : {size_t(1), size_t(3), size_t(8), size_t(13)}) {
        Checksum64 pieces;
        size_t at = 0;
        for (size_t k = first; at < bytes.size(); k = k * 3 % 17 + 1) {
            const size_t n = std::min(bytes.size() - at, k);
            pieces.update(bytes.data() + at, n);
            at += n;
        }
        EXPECT_EQ(pieces.value(), whole.value()) << first;
    }
    Checksum64 part;
    part.update(bytes.data(), 13);
    EXPECT_EQ(part.value(), 0x29e0ff393672153aull);
}

}  // namespace
