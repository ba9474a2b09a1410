// cambium — the structure check of .vdb input, and the metadata cambium
// writes: plain reads of the file's framing, no OpenVDB.
#include "io/vdb_header.h"

#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"
#include "io/read_file.h"

#include <fmt/format.h>

#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <vector>

namespace cambium {

namespace {

/// The first eight bytes of every .vdb file.
constexpr int64_t kMagic = 0x56444220;

/// Bounded reads of a .vdb's framing: every length is checked against what
/// is left of the file before anything is read or allocated.
class VdbReader {
public:
    VdbReader(const std::string& path, uint64_t size)
        : path_(path), size_(size), in_(path, std::ios::binary)
    {
        if (!in_)
            throw InputError(
                fmt::format("{}: cannot read the .vdb file: {}", path, std::strerror(errno)));
    }
    uint64_t at() const { return at_; }
    uint64_t left() const { return size_ - at_; }

    template <class T>
    T value(const char* what)
    {
        T v;
        bytes(reinterpret_cast<char*>(&v), sizeof v, what);
        return v;
    }
    void bytes(char* out, uint64_t n, const char* what)
    {
        need(n, what);
        in_.read(out, std::streamsize(n));
        if (!in_)
            throw InputError(
                fmt::format("{}: cannot read the .vdb file at byte {} ({})", path_, at_, what));
        at_ += n;
    }
    /// A length-prefixed string of at most `limit` bytes.
    std::string string(const char* what, uint32_t limit)
    {
        const uint32_t n = value<uint32_t>(what);
        if (n > limit)
            damaged(fmt::format("{} of {} bytes at byte {}", what, n, at_ - 4));
        std::string s(n, '\0');
        bytes(s.data(), n, what);
        return s;
    }
    void skip(uint64_t n, const char* what)
    {
        need(n, what);
        seek(at_ + n);
    }
    void seek(uint64_t to)
    {
        in_.seekg(std::streamoff(to));
        at_ = to;
    }
    [[noreturn]] void damaged(const std::string& why) const
    {
        throw InputError(fmt::format("{}: a damaged .vdb file: {}", path_, why));
    }

private:
    void need(uint64_t n, const char* what) const
    {
        if (n > left())
            throw InputError(fmt::format(
                "{}: a truncated .vdb file: {} at byte {} needs {} bytes, the file has {} "
                "in all",
                path_, what, at_, n, size_));
    }

    std::string path_;
    uint64_t size_, at_ = 0;
    std::ifstream in_;
};

/// The longest name or type string read from a .vdb's framing, and the
/// longest string metadata value kept.
constexpr uint32_t kNameLimit = 1 << 12, kValueLimit = 1 << 16;

/// Moves past a transform's values, after its map's type; false where the
/// map's size is unknown (OpenVDB refuses a map it has not registered).
bool skipMap(VdbReader& r, const std::string& map, uint64_t block, const std::string& grid)
{
    static const std::map<std::string, uint64_t> mapBytes = {
        {"UniformScaleMap", 120},   {"ScaleMap", 120},      {"UniformScaleTranslateMap", 144},
        {"ScaleTranslateMap", 144}, {"TranslationMap", 24}, {"AffineMap", 128},
        {"UnitaryMap", 128}};
    uint64_t bytes = 0;
    if (map == "NonlinearFrustumMap") {
        // Its box (two vec3d), taper and depth, then the linear map it
        // composes with, by type.
        if (r.at() + 64 + 4 > block)
            r.damaged(fmt::format("grid '{}' has no room for its transform", grid));
        r.skip(64, "frustum");
        const std::string inner = r.string("frustum's map type", kNameLimit);
        const auto m = mapBytes.find(inner);
        if (m == mapBytes.end())
            return false;
        bytes = m->second;
    } else if (const auto m = mapBytes.find(map); m != mapBytes.end()) {
        bytes = m->second;
    } else {
        return false;
    }
    if (r.at() + bytes > block)
        r.damaged(fmt::format("grid '{}' has no room for its transform", grid));
    r.skip(bytes, "transform");
    return true;
}

/// The counts of a grid's root node, from the start of its transform's
/// values (after the map's type): OpenVDB makes a node for each it claims
/// before it reads the node, whatever is left of the file (a changed byte of
/// a 1.2 MB file's root claimed 58,000 children: 16 GB made before the read
/// failed, and the unwinding aborted).  Each tile and child must fit in what
/// is left of the grid's topology, before `block`.  Checked for every map
/// OpenVDB registers and every tree type it reads (the others it refuses).
void checkRootCounts(VdbReader& r, VdbSummary::Grid& g, const std::string& map, uint64_t block)
{
    // A value's bytes, and its real numbers (0: integers, bool, masks and
    // points, whose leaves checkTreeStructure does not walk).
    struct Value {
        uint32_t bytes, reals;
        bool walked;
    };
    static const std::map<std::string, Value> values = {
        {"float", {4, 1, true}},    {"double", {8, 1, true}},      {"int32", {4, 0, true}},
        {"int64", {8, 0, true}},    {"bool", {1, 0, false}},       {"mask", {1, 0, false}},
        {"vec3s", {12, 3, true}},   {"vec3d", {24, 3, true}},      {"vec3i", {12, 0, true}},
        {"ptidx32", {4, 0, false}}, {"ptdataidx32", {4, 0, false}}};
    const std::string prefix = "Tree_", suffix = "_5_4_3";
    const size_t at = g.type.find(suffix);
    if (g.type.rfind(prefix, 0) != 0 || at == std::string::npos)
        return;
    const auto v = values.find(g.type.substr(prefix.size(), at - prefix.size()));
    if (v == values.end() || !skipMap(r, map, block, g.name))
        return;
    if (v->second.walked) {
        g.tree = int64_t(r.at());
        g.valueBytes = v->second.bytes;
        g.reals = v->second.reals;
    }
    // The tree's buffer count, the root's background.
    const uint64_t header = 4 + v->second.bytes;
    if (r.at() + header + 8 > block)
        r.damaged(fmt::format("grid '{}' has no room for its tree", g.name));
    r.skip(header, "buffer count and background");
    const uint64_t tiles = r.value<uint32_t>("root tile count");
    const uint64_t children = r.value<uint32_t>("root child count");
    // A tile: its origin, value and active flag; a child: its origin and at
    // least its two masks of 32^3 bits.
    const uint64_t least = tiles * (12 + v->second.bytes + 1) + children * (12 + 2 * 4096);
    if (least > block - r.at())
        r.damaged(fmt::format(
            "grid '{}' claims {} tiles and {} nodes at its root, at least {} bytes, and its "
            "tree has {} bytes",
            g.name, tiles, children, least, block - r.at()));
}

}  // namespace

VdbSummary inspectVdb(const std::string& path)
{
    VdbSummary s;
    s.bytes = checkInputFile(path, ".vdb file");
    VdbReader r(path, s.bytes);
    if (s.bytes < 8 || r.value<int64_t>("magic number") != kMagic)
        throw InputError(fmt::format(
            "{}: not a .vdb file (it does not begin with OpenVDB's magic number)", path));
    s.fileVersion = r.value<uint32_t>("file version");
    if (s.fileVersion < 222 || s.fileVersion > 1000)
        r.damaged(
            fmt::format("file format version {} (cambium reads 222 and later)", s.fileVersion));
    r.skip(8, "library version");
    if (r.value<char>("grid offsets flag") != 1)
        throw InputError(
            fmt::format("{}: a .vdb stream without grid offsets: cambium reads .vdb files written "
                        "to disk (with io::File)",
                        path));
    r.skip(36, "UUID");

    // A metadata block (the file's, or a grid's ending by `end`): every
    // entry's name, type and value within it; string values kept.
    auto metadata = [&](uint64_t end, std::map<std::string, std::string>* strings,
                        int64_t* leaves) {
        if (r.at() + 4 > end)
            r.damaged(fmt::format("no room for metadata at byte {}", r.at()));
        const int32_t metas = r.value<int32_t>("metadata count");
        if (metas < 0 || uint64_t(metas) > (end - r.at()) / 12)
            r.damaged(fmt::format("{} metadata entries at byte {}", metas, r.at() - 4));
        for (int32_t i = 0; i < metas; ++i) {
            const std::string name = r.string("metadata name", kNameLimit);
            const std::string type = r.string("metadata type", kNameLimit);
            const uint32_t n = r.value<uint32_t>("metadata size");
            if (r.at() + n > end && end == s.bytes)
                throw InputError(fmt::format(
                    "{}: a truncated .vdb file: metadata '{}' at byte {} needs {} bytes, the "
                    "file has {} in all",
                    path, name, r.at(), n, s.bytes));
            if (r.at() + n > end)
                r.damaged(fmt::format("metadata '{}' of {} bytes at byte {} runs past its block",
                                      name, n, r.at()));
            // OpenVDB reads a value of a fixed-size type by its type, not by
            // the size written before it: the two must agree.
            static const std::map<std::string, uint32_t> fixed = {
                {"bool", 1},   {"int32", 4},  {"int64", 8},  {"float", 4},
                {"double", 8}, {"vec2i", 8},  {"vec2s", 8},  {"vec2d", 16},
                {"vec3i", 12}, {"vec3s", 12}, {"vec3d", 24}, {"vec4i", 16},
                {"vec4s", 16}, {"vec4d", 32}, {"mat4s", 64}, {"mat4d", 128}};
            if (const auto f = fixed.find(type); f != fixed.end() && f->second != n)
                r.damaged(fmt::format("metadata '{}' of type {} has {} bytes, not {}", name, type,
                                      n, f->second));
            if (type == "__delayedload" && n > 0) {
                // OpenVDB sizes per-leaf arrays by the count it holds.
                if (n < 8)
                    r.damaged(fmt::format("metadata '{}' of {} bytes", name, n));
                // What OpenVDB reads of it is its own count of bytes, not n:
                // the leaves' masks (a byte each) and compressed sizes (8
                // bytes each), each a blosc block after its byte count, or
                // raw after a count of 0 (the sizes absent after 2^32 - 1).
                // Read past n, OpenVDB took the next name's length from the
                // wrong place (2 GB from a 161 KB file); a blosc block's
                // header sizes what OpenVDB reserves.
                const uint64_t start = r.at();
                const uint32_t count = r.value<uint32_t>("delayed-load count");
                if (count > s.bytes)
                    r.damaged(fmt::format("metadata '{}' counts {} leaves", name, count));
                auto block = [&](uint64_t itemBytes, bool optional) {
                    const uint32_t b = r.value<uint32_t>("delayed-load block size");
                    if (optional && b == std::numeric_limits<uint32_t>::max())
                        return;
                    const uint64_t bytes = b > 0 ? b : count * itemBytes;
                    if (r.at() + bytes > start + n)
                        r.damaged(
                            fmt::format("metadata '{}' of {} bytes holds a block of {} "
                                        "bytes at byte {}",
                                        name, n, bytes, r.at()));
                    if (b > 0) {
                        char header[16];
                        if (b < sizeof header)
                            r.damaged(
                                fmt::format("metadata '{}' has a block of {} bytes", name, b));
                        r.bytes(header, sizeof header, "blosc header");
                        uint32_t nbytes;
                        std::memcpy(&nbytes, header + 4, 4);
                        if (nbytes > 2 * count * itemBytes + 1024)  // (writers pad a little)
                            r.damaged(fmt::format("metadata '{}' unpacks {} bytes for {} leaves",
                                                  name, nbytes, count));
                        r.skip(b - sizeof header, "delayed-load block");
                    } else {
                        r.skip(bytes, "delayed-load block");
                    }
                };
                if (n < 12)
                    r.damaged(fmt::format("metadata '{}' of {} bytes", name, n));
                block(1, false);
                block(8, true);
                if (leaves)
                    *leaves = count;
                r.skip(start + n - r.at(), "metadata value");
                continue;
            }
            if (strings && type == "string" && n <= kValueLimit) {
                std::string v(n, '\0');
                r.bytes(v.data(), n, "metadata value");
                (*strings)[name] = v;
                if (name == kChecksumKey)
                    s.checksumEnd = r.at();
            } else {
                r.skip(n, "metadata value");
            }
        }
    };
    metadata(s.bytes, &s.strings, nullptr);
    const int32_t grids = r.value<int32_t>("grid count");
    if (grids < 0 || uint64_t(grids) > r.left() / 36)
        r.damaged(fmt::format("{} grids", grids));
    for (int32_t i = 0; i < grids; ++i) {
        VdbSummary::Grid g;
        g.name = r.string("grid name", kNameLimit);
        g.type = r.string("grid type", kNameLimit);
        g.instanceOf = r.string("instance parent", kNameLimit);
        g.begin = r.value<int64_t>("grid offset");
        g.block = r.value<int64_t>("grid block offset");
        g.end = r.value<int64_t>("grid end offset");
        // (An instance of another grid's tree has metadata and a transform,
        // no tree: no block of its own.)
        const bool instance = !g.instanceOf.empty() && g.block == 0;
        const int64_t block = instance ? g.end : g.block;
        if (g.begin != int64_t(r.at()) || block < g.begin || g.end < block)
            r.damaged(fmt::format(
                "grid '{}' has offsets {}, {}, {} that do not follow its descriptor at byte {}",
                g.name, g.begin, block, g.end, r.at()));
        if (uint64_t(g.end) > s.bytes)
            throw InputError(
                fmt::format("{}: a truncated .vdb file: grid '{}' ends at byte {}, the file has {} "
                            "bytes",
                            path, g.name, g.end, s.bytes));
        // The grid's compression word, metadata and transform's map type,
        // within its block.
        g.compression = r.value<uint32_t>("grid compression flags");
        metadata(uint64_t(block), nullptr, &g.leaves);
        if (r.at() + 4 > uint64_t(block))
            r.damaged(fmt::format("grid '{}' has no room for its transform", g.name));
        const std::string map = r.string("transform type", kNameLimit);
        if (!instance)
            checkRootCounts(r, g, map, uint64_t(block));
        r.seek(uint64_t(g.end));
        s.grids.push_back(std::move(g));
    }
    return s;
}

bool VdbSummary::Grid::half() const
{
    // (io::GridDescriptor's suffix for grids stored as halves)
    const std::string suffix = "_HalfFloat";
    return type.size() > suffix.size() &&
           type.compare(type.size() - suffix.size(), suffix.size(), suffix) == 0;
}

namespace {

FileIdentity identityOf(int fd)
{
    struct stat st {};
    if (::fstat(fd, &st) != 0)
        return {};
    return {uint64_t(st.st_dev), uint64_t(st.st_ino), int64_t(st.st_size),
            int64_t(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec,
            int64_t(st.st_ctim.tv_sec) * 1000000000 + st.st_ctim.tv_nsec};
}

/// Now, in the file times' nanoseconds.
int64_t nowNanoseconds()
{
    timespec t{};
    ::clock_gettime(CLOCK_REALTIME, &t);
    return int64_t(t.tv_sec) * 1000000000 + t.tv_nsec;
}

}  // namespace

bool verifyVdbChecksum(const std::string& path, const VdbSummary& s)
{
    const auto expected = s.strings.find(kChecksumKey);
    if (expected == s.strings.end() || s.checksumEnd == 0)
        return false;
    const ReadFile file(path);
    const FileIdentity before = identityOf(file.fd());
    if (s.verified.inode != 0 && before == s.verified)
        return true;
    s.verified = FileIdentity();
    Checksum64 sum;
    std::vector<char> chunk(size_t(1) << 20);
    const uint64_t end = std::max<uint64_t>(uint64_t(before.size), s.checksumEnd);
    for (uint64_t at = s.checksumEnd; at < end;) {
        const size_t n = size_t(std::min<uint64_t>(chunk.size(), end - at));
        file.read(at, chunk.data(), n);
        sum.update(chunk.data(), n);
        at += n;
    }
    // The digest is compared as a number, not as text: a fuzzer learns the
    // operands of byte-wise string compares and would write the computed
    // digest into its input, making any altered tree "verified"; it cannot
    // invert a 64-bit hash of the bytes it mutates (docs/errors.md).
    const std::string& digits = expected->second;
    uint64_t written = 0;
    const auto parsed = std::from_chars(digits.data(), digits.data() + digits.size(), written, 16);
    if (digits.size() != 16 || parsed.ec != std::errc() || parsed.ptr != digits.data() + 16 ||
        written != sum.value())
        throw InputError(fmt::format(
            "{}: a damaged .vdb file: its bytes do not match the checksum cambium wrote "
            "into it (changed or corrupted since)",
            path));
    // (recorded only where the file did not change while it was read, and
    // was last written more than two seconds before: a clock that ticks in
    // milliseconds or seconds dates two writes within a tick alike)
    constexpr int64_t kTick = 2000000000;
    const int64_t now = nowNanoseconds();
    if (before.inode != 0 && identityOf(file.fd()) == before && now - before.modified > kTick &&
        now - before.changed > kTick)
        s.verified = before;
    return true;
}

void requireVdbChecksum(const std::string& path, const VdbSummary& s)
{
    if (!verifyVdbChecksum(path, s))
        if (const std::string missing = missingChecksum(path, s); !missing.empty())
            throw InputError(missing);
}

std::string missingChecksum(const std::string& path, const VdbSummary& s)
{
    const auto creator = s.strings.find("creator");
    const bool cambiums =
        (creator != s.strings.end() && creator->second.rfind("cambium", 0) == 0) ||
        std::any_of(s.strings.begin(), s.strings.end(),
                    [](const auto& kv) { return kv.first.rfind("cambium_", 0) == 0; });
    if (s.checksumEnd != 0 || !cambiums)
        return {};
    return fmt::format(
        "{}: cambium's metadata without its checksum (cambium_checksum): the file was edited or "
        "damaged (or written by a cambium before checksums, 8e5b3d3)",
        path);
}

std::string framePart(long long frame)
{
    return fmt::format("frame {}", frame);
}

std::string tilePart(int k, int count)
{
    return fmt::format("tile {}/{}", k + 1, count);
}

FileStamp readFileStamp(const std::string& path, bool verify)
{
    const VdbSummary s = inspectVdb(path);
    if (verify)
        requireVdbChecksum(path, s);
    FileStamp stamp;
    if (const auto key = s.strings.find("cambium_sequence"); key != s.strings.end())
        stamp.key = key->second;
    if (const auto part = s.strings.find("cambium_part"); part != s.strings.end())
        stamp.part = part->second;
    return stamp;
}

bool looksLikeVdbFile(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    int64_t magic = 0;
    return in.read(reinterpret_cast<char*>(&magic), sizeof magic) && magic == kMagic;
}

}  // namespace cambium
