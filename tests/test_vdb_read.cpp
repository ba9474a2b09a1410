// cambium tests — the parallel .vdb reader (io/vdb.h readVdbGrid,
// readLevelSet) against OpenVDB's io::File, voxel for voxel: cambium's own
// files (surface, Cd, density; floats and halves) and files OpenVDB wrote
// with every compression it offers.
#include "bake_util.h"
#include "scenes.h"
#include "temp_dir.h"
#include "test_util.h"

#include "bake/tiles.h"
#include "core/error.h"
#include "core/hash.h"
#include "io/leaf_layout.h"
#include "io/leaf_values.h"
#include "io/vdb.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <algorithm>
#include <filesystem>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <numeric>
#include <random>
#include <set>
#include <sstream>
#include <chrono>
#include <thread>

using namespace cambium;
using namespace cambium::test;

namespace {

/// The grid as OpenVDB's io::File reads it, whole.
openvdb::GridBase::Ptr openVdbRead(const std::string& path, const std::string& name)
{
    openvdb::io::File f(path);
    f.open(false);
    openvdb::GridBase::Ptr g = f.readGrid(name);
    f.close();
    return g;
}

/// Same metadata, transform, background, tiles and voxels (values compared
/// bit for bit, inactive ones too): the trees iterated side by side.
template <class GridT>
void expectSameGrid(const GridT& a, const GridT& b, const std::string& what)
{
    ASSERT_EQ(a.tree().leafCount(), b.tree().leafCount()) << what;
    ASSERT_EQ(a.tree().activeTileCount(), b.tree().activeTileCount()) << what;
    ASSERT_EQ(a.activeVoxelCount(), b.activeVoxelCount()) << what;
    EXPECT_EQ(a.transform(), b.transform()) << what;
    EXPECT_EQ(a.getGridClass(), b.getGridClass()) << what;
    EXPECT_EQ(a.str(), b.str()) << what;  // the metadata
    EXPECT_EQ(std::memcmp(&a.background(), &b.background(), sizeof a.background()), 0) << what;
    auto ib = b.tree().cbeginValueAll();
    size_t values = 0, differ = 0;
    for (auto ia = a.tree().cbeginValueAll(); ia; ++ia, ++ib, ++values) {
        ASSERT_TRUE(bool(ib)) << what;
        ASSERT_EQ(ia.getCoord(), ib.getCoord()) << what;
        ASSERT_EQ(ia.getDepth(), ib.getDepth()) << what;
        const auto va = *ia, vb = *ib;
        differ += ia.isValueOn() != ib.isValueOn() || std::memcmp(&va, &vb, sizeof va) != 0;
    }
    EXPECT_FALSE(bool(ib)) << what;
    EXPECT_EQ(differ, 0u) << what << ": of " << values << " values and tiles";
    EXPECT_GT(values, 1000u) << what;
}

void expectReadsAsOpenVdb(const std::string& path, const std::string& what)
{
    const VdbSummary s = inspectVdb(path);
    for (const VdbSummary::Grid& grid : s.grids) {
        const std::string label = what + ", grid " + grid.name;
        const openvdb::GridBase::Ptr ours = readVdbGrid(path, s, grid.name),
                                     theirs = openVdbRead(path, grid.name);
        ASSERT_EQ(ours->type(), theirs->type()) << label;
        const bool known = theirs->apply<
            openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid, openvdb::Int32Grid>>(
            [&](const auto& t) {
                using G = std::decay_t<decltype(t)>;
                expectSameGrid(*openvdb::gridConstPtrCast<G>(ours), t, label);
            });
        EXPECT_TRUE(known) << label;
        // Read with its topology only (each root child's on a core of its
        // own): every leaf of cambium's file empty, then the same grid once
        // decodeLeaves has put their values in.
        const openvdb::GridBase::Ptr lazy = readVdbGrid(path, s, grid.name, /*lazy=*/true);
        theirs->apply<openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid>>(
            [&](const auto& t) {
                using G = std::decay_t<decltype(t)>;
                G& g = *openvdb::gridPtrCast<G>(lazy);
                size_t empty = 0;
                for (auto leaf = g.tree().cbeginLeaf(); leaf; ++leaf)
                    empty += leaf->buffer().empty();
                // (another tool's file, or an instance, is read whole)
                const bool topologyOnly = s.checksumEnd != 0 && grid.instanceOf.empty();
                EXPECT_EQ(empty, topologyOnly ? t.tree().leafCount() : 0u) << label;
                decodeLeaves(path, s, g, {}, {});
                expectSameGrid(g, t, label + " (topology, then its leaves)");
            });
    }
}

/// A level-set sphere of radius 1 named "surface", written by OpenVDB's
/// io::File (no cambium checksum: another program's file) as `file` in a
/// fresh directory `dir`; its path.
/// The grid of `summary` named `name` (null: none).
const VdbSummary::Grid* gridIn(const VdbSummary& summary, const std::string& name)
{
    for (const VdbSummary::Grid& g : summary.grids)
        if (g.name == name)
            return &g;
    return nullptr;
}

std::string writeForeignSphere(const std::string& dir, const std::string& file,
                               const openvdb::Vec3f& centre, float voxelSize)
{
    openvdb::initialize();
    openvdb::FloatGrid::Ptr sphere =
        openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, centre, voxelSize);
    sphere->setName("surface");
    const std::string path = freshDir(dir).string() + "/" + file;
    openvdb::io::File f(path);
    f.write({sphere});
    f.close();
    return path;
}

}  // namespace

TEST(VdbRead, CambiumsOwnFilesReadAsOpenVdbReadsThem)
{
    // surface, Cd (many colours) and density, packed by the writer on all
    // cores into blocks of leaves, stored as floats and as halves.
    openvdb::initialize();
    const BakedGrids g = bakeTree(redAndBlueSpheres(), 0.0045, 3.0, true, /*fog=*/true);
    ASSERT_GT(g.surface->tree().leafCount(), 1500u);
    ASSERT_GT(g.color->activeVoxelCount(), 1000u);
    const std::string dir = freshDir("cambium_vdb_read").string();
    for (bool halves : {false, true}) {
        VdbFileInfo info;
        info.scene = "two spheres";
        info.half = halves;
        const std::string path = dir + (halves ? "/half.vdb" : "/float.vdb");
        writeVdb(g, path, info);
        // (more than one of the megabytes the reader reads at a time)
        const VdbSummary s = inspectVdb(path);
        ASSERT_GT(s.grids[0].end - s.grids[0].block, 1 << 20);
        // (the topology read a root child at a time, on all cores)
        TreeLayout layout;
        checkTreeStructure(path, s.grids[0], false, &layout);
        EXPECT_GT(layout.children.size(), 1u);
        expectReadsAsOpenVdb(path, halves ? "halves" : "floats");
        // readLevelSet: the level set and its colour, each read so.
        const LevelSetGrids r = readLevelSet(path);
        expectSameGrid(*r.surface,
                       *openvdb::gridPtrCast<openvdb::FloatGrid>(openVdbRead(path, "surface")),
                       "readLevelSet surface");
        ASSERT_TRUE(r.color);
        expectSameGrid(*r.color, *openvdb::gridPtrCast<openvdb::Vec3fGrid>(openVdbRead(path, "Cd")),
                       "readLevelSet Cd");
        EXPECT_FALSE(readLevelSet(path, "surface", ColourRead::None).color);
    }
}

TEST(VdbRead, FilesOpenVdbWroteReadAsOpenVdbReadsThem)
{
    // What other tools write: OpenVDB's own writer with each of its
    // compressions (Blosc, zip, none; with and without the active-value
    // mask), halves, a grid with active tiles, a narrow band with both
    // inactive values (+-background), an integer grid (read by io::File) and
    // a grid instancing another's tree.
    openvdb::initialize();
    openvdb::FloatGrid::Ptr sphere =
        openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.1f), 0.04f);
    sphere->setName("surface");
    openvdb::Vec3fGrid::Ptr colour = openvdb::Vec3fGrid::create(openvdb::Vec3f(0.0f));
    colour->setName("Cd");
    colour->setTransform(sphere->transform().copy());
    {
        auto acc = colour->getAccessor();
        for (auto it = sphere->cbeginValueOn(); it; ++it) {
            const openvdb::Coord c = it.getCoord();
            acc.setValue(c, openvdb::Vec3f(float(c.x() & 7) / 7.0f, *it, 0.5f));
        }
        // active tiles: a level-1 tile and a level-2 one
        colour->tree().addTile(1, openvdb::Coord(800, 0, 0), openvdb::Vec3f(0.25f), true);
        colour->tree().addTile(2, openvdb::Coord(4096, 0, 0), openvdb::Vec3f(0.75f), true);
    }
    openvdb::Int32Grid::Ptr ids = openvdb::Int32Grid::create(-1);
    ids->setName("ids");
    for (int i = 0; i < 3000; ++i)
        ids->tree().setValue(openvdb::Coord(i % 97, i / 97, i % 13), i);
    openvdb::FloatGrid::Ptr instance = openvdb::FloatGrid::create(sphere->treePtr());
    instance->setName("surface_instance");
    instance->setTransform(sphere->transform().copy());
    namespace io = openvdb::io;
    const uint32_t compressions[] = {io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK,
                                     io::COMPRESS_BLOSC,
                                     io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK,
                                     io::COMPRESS_ZIP,
                                     io::COMPRESS_ACTIVE_MASK,
                                     io::COMPRESS_NONE};
    const std::string dir = freshDir("cambium_vdb_read_foreign").string();
    int k = 0;
    for (uint32_t c : compressions)
        for (bool halves : {false, true}) {
            const std::string path = dir + "/foreign" + std::to_string(k++) + ".vdb";
            sphere->setSaveFloatAsHalf(halves);
            colour->setSaveFloatAsHalf(halves);
            io::File f(path);
            f.setCompression(c);
            f.write({sphere, colour, ids, instance});
            f.close();
            expectReadsAsOpenVdb(path,
                                 fmt::format("compression {} ({}){}", c, io::compressionToString(c),
                                             halves ? ", halves" : ""));
        }
}

TEST(VdbRead, AForeignFileIsReadWholeAsOpenVdbReadsIt)
{
    // A file without cambium's checksum is read by OpenVDB whole: a delayed
    // read trusts its delayed-load metadata, which nothing vouches for.
    // (1) The first leaf's value mask changed in its value block: read as
    // OpenVDB reads it (the buffer's mask), not named as damage.
    const std::string path =
        writeForeignSphere("cambium_vdb_read_damaged", "d.vdb", openvdb::Vec3f(0.0f), 0.05f);
    const VdbSummary s = inspectVdb(path);
    ASSERT_EQ(s.grids.size(), 1u);
    {
        std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
        io.seekp(s.grids[0].block);
        char byte = 0;
        io.read(&byte, 1);
        io.seekp(s.grids[0].block);
        byte = char(~byte);
        io.write(&byte, 1);
    }
    const openvdb::GridBase::Ptr ours = readVdbGrid(path, s, "surface");
    expectSameGrid(*openvdb::gridPtrCast<openvdb::FloatGrid>(ours),
                   *openvdb::gridPtrCast<openvdb::FloatGrid>(openVdbRead(path, "surface")),
                   "a changed mask");
    // (2) A zip-compressed foreign sphere with a byte of its topology
    // changed (the sweep's find): a leaf more than its delayed-load metadata
    // counts aborted the delayed read on OpenVDB's assertion
    // `index < mMask.size()`.  Read, or refused by name; never an abort.
    const std::string leafMore =
        CAMBIUM_SOURCE_DIR "/tests/data/foreign-leaf-beyond-its-delayed-load-metadata.vdb";
    try {
        const LevelSetGrids g = readLevelSet(leafMore);
        EXPECT_TRUE(g.surface);
    } catch (const InputError&) {
    }
}

namespace {

/// A leaf's bytes as OpenVDB writes them under `compression` (its mask,
/// inactive-value code and what follows, its values).
template <class LeafT>
std::string leafBytesWritten(const LeafT& leaf, uint32_t compression,
                             const typename LeafT::ValueType& background)
{
    std::ostringstream os(std::ios::binary);
    openvdb::io::setDataCompression(os, compression);
    openvdb::io::setGridBackgroundValuePtr(os, &background);
    leaf.writeBuffers(os, /*toHalf=*/false);
    return os.str();
}

/// The leaf's values as OpenVDB's own reader decodes those bytes.
template <class LeafT>
LeafT leafReadByOpenVdb(const std::string& bytes, const LeafT& like, uint32_t compression,
                        const typename LeafT::ValueType& background)
{
    std::istringstream is(bytes, std::ios::binary);
    openvdb::io::setVersion(is,
                            openvdb::VersionId(OPENVDB_LIBRARY_MAJOR_VERSION_NUMBER,
                                               OPENVDB_LIBRARY_MINOR_VERSION_NUMBER),
                            openvdb::OPENVDB_FILE_VERSION);
    openvdb::io::setDataCompression(is, compression);
    openvdb::io::setGridBackgroundValuePtr(is, &background);
    LeafT leaf(like.origin(), background);
    leaf.readBuffers(is, /*fromHalf=*/false);
    return leaf;
}

template <class ValueT>
ValueT valueOf(float v)
{
    return ValueT(v);
}

/// Leaves of every inactive-value layout OpenVDB's writer chooses (the
/// seven codes), written under every compression the direct decoder takes:
/// encoded directly, the bytes OpenVDB's writer writes; decoded by it and by
/// OpenVDB's reader, the same bits.
template <class ValueT>
void expectDirectDecodeAsOpenVdb()
{
    namespace io = openvdb::io;
    using LeafT = typename openvdb::tree::Tree4<ValueT, 5, 4, 3>::Type::LeafNodeType;
    const ValueT bg = valueOf<ValueT>(0.015f);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-0.015f, 0.015f);
    // (inactive voxels: +bg, -bg, or the values x and y; `density`: of the active ones)
    const ValueT x = valueOf<ValueT>(0.25f), y = valueOf<ValueT>(-4.0f);
    const std::vector<std::vector<ValueT>> inactiveSets = {
        {bg},      {openvdb::math::negative(bg)},
        {x},       {bg, openvdb::math::negative(bg)},
        {bg, x},   {x, y},
        {bg, x, y}};
    std::set<int> codes;
    size_t compared = 0;
    for (const uint32_t compression : {uint32_t(io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK),
                                       uint32_t(io::COMPRESS_ACTIVE_MASK),
                                       uint32_t(io::COMPRESS_BLOSC), uint32_t(io::COMPRESS_NONE)}) {
        StoredValues stored;
        stored.compression = compression;
        stored.storedBytes = sizeof(ValueT);
        ASSERT_TRUE(decodesLeafValues(stored, openvdb::OPENVDB_FILE_VERSION));
        for (const double density : {0.0, 1.0 / 512, 0.3, 0.97, 1.0})
            for (const std::vector<ValueT>& inactive : inactiveSets) {
                LeafT leaf(openvdb::Coord(8, -16, 24), bg);
                std::uniform_real_distribution<double> coin(0.0, 1.0);
                for (openvdb::Index i = 0; i < LeafT::SIZE; ++i) {
                    const bool on =
                        density >= 1.0 || (density > 0.0 && (i == 77 || coin(rng) < density));
                    if (on)
                        leaf.setValueOn(i, valueOf<ValueT>(u(rng)));
                    else
                        leaf.setValueOff(i, inactive[size_t(rng()) % inactive.size()]);
                }
                const std::string bytes = leafBytesWritten(leaf, compression, bg);
                codes.insert(int(int8_t(bytes[64])));
                // Encoded directly: OpenVDB's bytes.
                std::vector<char> encoded;
                std::vector<ValueT> active;
                ASSERT_TRUE(encodesLeafValues(compression, false));
                encodeLeafValues(leaf.getValueMask(), leaf.buffer().data(), bg, compression,
                                 encoded, active);
                ASSERT_EQ(std::string(encoded.begin(), encoded.end()), bytes)
                    << "encoded: compression " << compression << ", density " << density
                    << ", code " << int(bytes[64]);
                const LeafT theirs = leafReadByOpenVdb(bytes, leaf, compression, bg);
                std::vector<ValueT> ours(LeafT::SIZE, valueOf<ValueT>(1234.0f)), scratch;
                const std::string why =
                    decodeLeafValues(bytes.data(), bytes.size(), leaf.getValueMask(), stored, bg,
                                     ours.data(), scratch);
                ASSERT_EQ(why, "") << compression << " " << density;
                ASSERT_EQ(
                    std::memcmp(ours.data(), theirs.buffer().data(), LeafT::SIZE * sizeof(ValueT)),
                    0)
                    << "compression " << compression << ", density " << density << ", code "
                    << int(bytes[64]);
                ++compared;
            }
    }
    EXPECT_EQ(compared, 4u * 5u * inactiveSets.size());
    // Every code OpenVDB writes came up (mask compression's six, and all values).
    EXPECT_EQ(codes.size(), 7u);
}

}  // namespace

TEST(VdbRead, LeavesCodedDirectlyAreWhatOpenVdbsCodersMakeAndRead)
{
    expectDirectDecodeAsOpenVdb<float>();
    expectDirectDecodeAsOpenVdb<openvdb::Vec3f>();
}

TEST(VdbRead, ALeafsValuesThatDoNotUnpackAreRefusedByTheDirectDecoder)
{
    // What OpenVDB's reader throws on, the direct decoder says: a blosc
    // block that unpacks to fewer bytes than the values take, a raw block
    // of another size, values cut short; and halves, zip and old files are
    // left to OpenVDB.
    namespace io = openvdb::io;
    using LeafT = openvdb::FloatTree::LeafNodeType;
    const float bg = 0.1f;
    LeafT leaf(openvdb::Coord(0), bg);
    for (openvdb::Index i = 0; i < LeafT::SIZE; i += 3)
        leaf.setValueOn(i, float(i) * 1e-4f);
    const uint32_t compression = io::COMPRESS_BLOSC | io::COMPRESS_ACTIVE_MASK;
    StoredValues stored;
    stored.compression = compression;
    stored.storedBytes = 4;
    const std::string good = leafBytesWritten(leaf, compression, bg);
    std::vector<float> out(LeafT::SIZE), scratch;
    ASSERT_EQ(decodeLeafValues(good.data(), good.size(), leaf.getValueMask(), stored, bg,
                               out.data(), scratch),
              "");
    const size_t block = 64 + 1 + valuesHeaderBytes(int8_t(good[64]), 4, 64);
    // Blosc's header (after the block's 8-byte size): its unpacked size at byte 4.
    std::string fewer = good;
    const uint32_t less = uint32_t(leaf.getValueMask().countOn() * 4 - 8);
    std::memcpy(fewer.data() + block + 8 + 4, &less, 4);
    EXPECT_NE(decodeLeafValues(fewer.data(), fewer.size(), leaf.getValueMask(), stored, bg,
                               out.data(), scratch),
              "");
    EXPECT_ANY_THROW(leafReadByOpenVdb(fewer, leaf, compression, bg));
    // A raw block (negative size) of other than the active values' bytes.
    std::string raw = good.substr(0, block);
    const int64_t wrong = -int64_t(leaf.getValueMask().countOn() * 4 + 4);
    raw.append(reinterpret_cast<const char*>(&wrong), 8);
    raw.append(size_t(-wrong), '\0');
    // (not given to OpenVDB's reader: it reads the length a raw block
    // claims into a buffer of the values it expects before it compares the
    // two, the heap overflow the structure check keeps from it)
    EXPECT_NE(decodeLeafValues(raw.data(), raw.size(), leaf.getValueMask(), stored, bg, out.data(),
                               scratch),
              "");
    // A raw block of the right size decodes as OpenVDB decodes it.
    std::string right = good.substr(0, block);
    std::vector<float> active;
    for (auto it = leaf.cbeginValueOn(); it; ++it)
        active.push_back(*it);
    const int64_t size = -int64_t(active.size() * 4);
    right.append(reinterpret_cast<const char*>(&size), 8);
    right.append(reinterpret_cast<const char*>(active.data()), active.size() * 4);
    ASSERT_EQ(decodeLeafValues(right.data(), right.size(), leaf.getValueMask(), stored, bg,
                               out.data(), scratch),
              "");
    EXPECT_EQ(
        std::memcmp(out.data(), leafReadByOpenVdb(right, leaf, compression, bg).buffer().data(),
                    LeafT::SIZE * 4),
        0);
    // Cut short; a Blosc header claiming more bytes than its block holds
    // (Blosc would read them); a raw size that does not negate.
    EXPECT_NE(decodeLeafValues(good.data(), good.size() - 5, leaf.getValueMask(), stored, bg,
                               out.data(), scratch),
              "");
    std::string claims = good;
    const uint32_t more = uint32_t(good.size() - block);
    std::memcpy(claims.data() + block + 8 + 12, &more, 4);
    EXPECT_NE(decodeLeafValues(claims.data(), claims.size(), leaf.getValueMask(), stored, bg,
                               out.data(), scratch),
              "");
    std::string lowest = good.substr(0, block);
    const int64_t least = std::numeric_limits<int64_t>::min();
    lowest.append(reinterpret_cast<const char*>(&least), 8);
    lowest.append(64, '\0');
    EXPECT_NE(decodeLeafValues(lowest.data(), lowest.size(), leaf.getValueMask(), stored, bg,
                               out.data(), scratch),
              "");
    // Layouts left to OpenVDB's decoder.
    StoredValues halves = stored, zip = stored;
    halves.half = true;
    zip.compression = io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK;
    EXPECT_FALSE(decodesLeafValues(halves, openvdb::OPENVDB_FILE_VERSION));
    EXPECT_FALSE(decodesLeafValues(zip, openvdb::OPENVDB_FILE_VERSION));
    EXPECT_FALSE(encodesLeafValues(zip.compression, false));
    EXPECT_FALSE(encodesLeafValues(stored.compression, true));
    EXPECT_FALSE(
        decodesLeafValues(stored, openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION - 1));
}

TEST(VdbRead, ABlockOfAnotherSizeThanItsValuesIsNamedBeforeOpenVdbReadsIt)
{
    // OpenVDB 10 reads the length a raw block of values claims into a
    // buffer of the values it expects before it compares the two, and blosc
    // reads as many bytes as its header claims: a byte changed in another
    // tool's file (or in a cambium file signed again) overflowed the heap in
    // mesh, render and a shape's base (sweep 18).  The structure check walks
    // every node's blocks first, in the topology and among the leaves.
    const std::string path =
        writeForeignSphere("cambium_vdb_read_block", "b.vdb", openvdb::Vec3f(0.0f), 0.05f);
    const VdbSummary s = inspectVdb(path);
    ASSERT_EQ(s.grids.size(), 1u);
    const VdbSummary::Grid& g = s.grids[0];
    ASSERT_GT(g.tree, 0);
    ASSERT_TRUE(g.compression & openvdb::io::COMPRESS_BLOSC);
    EXPECT_NO_THROW(readLevelSet(path));
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    auto changed = [&](size_t at, const void* value, size_t n) {
        std::string b = bytes;
        std::memcpy(b.data() + at, value, n);
        const std::string out = path + ".changed.vdb";
        std::ofstream(out, std::ios::binary) << b;
        return out;
    };
    // The first internal node's values: after the buffer count, the
    // background, the root's counts and tiles, the node's origin and its
    // two masks of 32^3 bits, its code, inactive values and selection mask.
    uint32_t counts[2];
    std::memcpy(counts, bytes.data() + g.tree + 8, 8);
    ASSERT_GT(counts[1], 0u);
    size_t at = size_t(g.tree) + 16 + counts[0] * (12 + 4 + 1) + 12 + 2 * 4096;
    at += 1 + valuesHeaderBytes(int8_t(bytes[at]), 4, 4096);
    const int64_t raw = -1000003;  // (no count of floats)
    expectInputError([&] { readLevelSet(changed(at, &raw, 8)); },
                     "a damaged .vdb file: grid 'surface': an internal node of 32^3 at byte",
                     "a raw block of a megabyte for its values");
    int64_t n;
    // The first leaf's values: its mask, code, header, then a blosc block
    // whose header claims more bytes than the block holds.
    at = size_t(g.block) + 64;
    at += 1 + valuesHeaderBytes(int8_t(bytes[at]), 4, 64);
    std::memcpy(&n, bytes.data() + at, 8);
    ASSERT_GT(n, 16) << "a leaf's values compressed";
    const uint32_t claimed = uint32_t(n) + 1000;
    expectInputError([&] { readLevelSet(changed(at + 8 + 12, &claimed, 4)); },
                     "a damaged .vdb file: grid 'surface': a leaf's values at byte " +
                         std::to_string(g.block + 64) + " stores",
                     "a blosc header claiming 1000 bytes more than its block");
}

TEST(VdbRead, ALeafThatDoesNotDecodeIsNamedWhereverItIsRead)
{
    // A cambium file whose checksum was computed again over a Cd leaf whose
    // blosc block does not unpack (sweep 18): OpenVDB's delayed loading
    // threw from a render's thread and left the leaf's buffer half made (a
    // crash at the next touch, or when the grid was freed), and the whole
    // read failed with exit 1.  Every reader now decodes with cambium's
    // decoder and names the leaf; the leaves decoded before are freed whole.
    openvdb::initialize();
    const BakedGrids g = bakeTree(redAndBlueSpheres(), 0.02, 3.0, true);
    ASSERT_TRUE(g.color);
    const std::string dir = freshDir("cambium_vdb_read_leaf").string();
    const std::string path = dir + "/signed-again.vdb";
    writeVdb(g, path, VdbFileInfo());
    const VdbSummary s = inspectVdb(path);
    const VdbSummary::Grid* cd = gridIn(s, "Cd");
    ASSERT_TRUE(cd);
    ASSERT_TRUE(cd->compression & openvdb::io::COMPRESS_BLOSC);
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    // The first Cd leaf stored compressed: its blosc header's unpacked size
    // one more than its values'.
    const size_t maskBytes = 64;
    size_t at = size_t(cd->block), leaf = 0;
    for (;; ++leaf) {
        ASSERT_LT(at, size_t(cd->end));
        at += maskBytes;
        at += 1 + valuesHeaderBytes(int8_t(bytes[at]), 12, maskBytes);
        int64_t n;
        std::memcpy(&n, bytes.data() + at, 8);
        if (n > 16) {
            uint32_t unpacked;
            std::memcpy(&unpacked, bytes.data() + at + 8 + 4, 4);
            ++unpacked;
            std::memcpy(bytes.data() + at + 8 + 4, &unpacked, 4);
            break;
        }
        at += 8 + size_t(n < 0 ? -n : n);
    }
    Checksum64 sum;
    sum.update(bytes.data() + s.checksumEnd, bytes.size() - s.checksumEnd);
    const std::string digits = fmt::format("{:016x}", sum.value());
    bytes.replace(s.checksumEnd - 16, 16, digits);
    std::ofstream(path, std::ios::binary) << bytes;
    EXPECT_TRUE(verifyVdbChecksum(path, inspectVdb(path)));
    const std::string message =
        "signed-again.vdb: a damaged .vdb file: grid 'Cd', leaf " + std::to_string(leaf) + " of ";
    expectInputError([&] { readLevelSet(path); }, message, "readLevelSet");
    std::vector<openvdb::Coord> all;
    for (auto it = g.color->tree().cbeginLeaf(); it; ++it)
        all.push_back(it->origin());
    std::sort(all.begin(), all.end());
    expectInputError([&] { readColourGrid(path, *g.surface, &all); }, message,
                     "readColourGrid, the leaves a render looks up");
    expectInputError([&] { mergeTiles({path}, false); }, message, "mergeTiles");
    // (a leaf not asked for is not decoded)
    const std::vector<openvdb::Coord> none = {openvdb::Coord(1 << 20)};
    EXPECT_NO_THROW(readColourGrid(path, *g.surface, &none));
}

TEST(VdbRead, AValueThatIsNotANumberIsNamedByTheTileMerge)
{
    // A tile whose checksum was computed again over a NaN among its values
    // (sweep 19): the merge decodes and drops each leaf as it packs it, and
    // wrote the NaN into the frame with exit 0, which every reader then
    // refused.  The leaf is kept to be named instead.
    openvdb::initialize();
    openvdb::FloatGrid::Ptr sphere =
        openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f), 0.05f);
    sphere->setName("surface");
    const openvdb::Coord at = sphere->tree().cbeginValueOn().getCoord();
    sphere->tree().setValueOn(at, std::numeric_limits<float>::quiet_NaN());
    LevelSetGrids g;
    g.surface = sphere;
    const std::string path = freshDir("cambium_vdb_read_nan").string() + "/nan.vdb";
    writeVdb(g, path, VdbFileInfo());
    const std::string message = fmt::format(
        "nan.vdb: grid 'surface' has a voxel at ({}, {}, {}) whose value is not a number", at.x(),
        at.y(), at.z());
    expectInputError([&] { readLevelSet(path); }, message, "readLevelSet");
    expectInputError([&] { mergeTiles({path}, false); }, message, "mergeTiles");
}

TEST(VdbRead, ARootClaimingMoreNodesThanItsTreeHoldsIsNamed)
{
    // OpenVDB makes each node its root claims before reading it: a changed
    // byte of a foreign 1.2 MB file claimed 58,000 children, 16 GB made
    // before the read failed (and the unwinding aborted).
    const std::string path =
        writeForeignSphere("cambium_vdb_read_root", "r.vdb", openvdb::Vec3f(0.0f), 0.05f);
    EXPECT_NO_THROW(inspectVdb(path));
    std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(io)), {});
    // After the map's name: its 5 vectors, the buffer count, the
    // background, the root's tile count, then its child count.
    const size_t map = bytes.find("UniformScaleMap");
    ASSERT_NE(map, std::string::npos);
    const size_t children = map + 15 + 120 + 4 + 4 + 4;
    uint32_t count = 0;
    std::memcpy(&count, bytes.data() + children, 4);
    EXPECT_GT(count, 0u);
    EXPECT_LT(count, 100u);
    count = 58376;
    io.seekp(std::streamoff(children));
    io.write(reinterpret_cast<const char*>(&count), 4);
    io.close();
    expectInputError([&] { inspectVdb(path); },
                     "a damaged .vdb file: grid 'surface' claims 0 tiles and 58376 nodes at its "
                     "root, at least 478916704 bytes, and its tree has",
                     "a root of 58,376 children");
}

namespace {

/// A grid of type GridT with an active tile and one voxel under `xform`,
/// written by io::File to `path`; the root's child count at `offset` (after
/// the map's type: its values, the buffer count, the background and the
/// tile count) changed to 58376, the damaged file's message.
template <class GridT>
std::string rootClaimMessage(const std::string& path, openvdb::math::Transform::Ptr xform,
                             const std::string& mapName, size_t mapBytes)
{
    using ValueT = typename GridT::ValueType;
    typename GridT::Ptr g = GridT::create();
    g->setName("g");
    g->setTransform(xform);
    g->tree().addTile(3, openvdb::Coord(4096), ValueT(), true);
    g->tree().setValueOn(openvdb::Coord(1, 2, 3));
    openvdb::io::File f(path);
    f.write({g});
    f.close();
    EXPECT_NO_THROW(inspectVdb(path)) << path;
    std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(io)), {});
    const size_t map = bytes.find(mapName);
    EXPECT_NE(map, std::string::npos);
    const size_t children = map + mapName.size() + mapBytes + 4 + sizeof(ValueT) + 4;
    uint32_t count = 0;
    std::memcpy(&count, bytes.data() + children, 4);
    EXPECT_EQ(count, 1u) << path;
    count = 58376;
    io.seekp(std::streamoff(children));
    io.write(reinterpret_cast<const char*>(&count), 4);
    io.close();
    try {
        inspectVdb(path);
    } catch (const InputError& e) {
        return e.what();
    }
    return "(read)";
}

}  // namespace

TEST(VdbRead, EveryTreeTypeUnderEveryMapHasItsRootClaimChecked)
{
    // The check knew the sizes of linear maps only: under a frustum map the
    // 58,376-child claim went on to abort (sweep 10).
    openvdb::initialize();
    const std::string dir = freshDir("cambium_vdb_read_roots").string();
    const std::string claim = "a damaged .vdb file: grid 'g' claims 1 tiles and 58376 nodes";
    int n = 0;
    for (bool frustum : {false, true}) {
        auto xform = [&] {
            return frustum ? openvdb::math::Transform::createFrustumTransform(
                                 openvdb::BBoxd(openvdb::Vec3d(0.0), openvdb::Vec3d(100.0)), 0.5,
                                 2.0, 0.1)
                           : openvdb::math::Transform::createLinearTransform(0.1);
        };
        // (A frustum's box, taper and depth, then its affine map by name.)
        const std::string mapName = frustum ? "AffineMap" : "UniformScaleMap";
        const size_t mapBytes = frustum ? 128 : 120;
        auto path = [&] { return dir + "/" + std::to_string(n++) + ".vdb"; };
        const std::vector<std::string> messages = {
            rootClaimMessage<openvdb::FloatGrid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::DoubleGrid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::Int32Grid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::Int64Grid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::BoolGrid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::MaskGrid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::Vec3SGrid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::Vec3DGrid>(path(), xform(), mapName, mapBytes),
            rootClaimMessage<openvdb::Vec3IGrid>(path(), xform(), mapName, mapBytes)};
        for (const std::string& m : messages)
            EXPECT_NE(m.find(claim), std::string::npos) << m;
    }
}

TEST(VdbRead, AColourGridOnAnotherOrAnUnusableTransformIsNamedByEveryReader)
{
    // The CPU render read Cd apart from the level set, unchecked: colours at
    // voxels of 0.034 painted onto a surface at 0.05, exit 0; and OpenVDB's
    // transform comparison takes NaN for any number, so a Cd whose matrix
    // was all NaN passed everywhere (sweep 10).
    openvdb::initialize();
    const std::string dir = freshDir("cambium_vdb_read_cd").string();
    auto write = [&](const std::string& file, double cdVoxel, bool nan) {
        openvdb::FloatGrid::Ptr sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
            1.0f, openvdb::Vec3f(0.0f), 0.05f);
        sphere->setName("surface");
        openvdb::Vec3fGrid::Ptr colour = openvdb::Vec3fGrid::create(openvdb::Vec3f(0.0f));
        colour->setName("Cd");
        colour->setTransform(openvdb::math::Transform::createLinearTransform(cdVoxel));
        colour->tree().setValueOn(openvdb::Coord(20, 0, 0), openvdb::Vec3f(1.0f, 0.0f, 0.0f));
        const std::string path = dir + "/" + file;
        openvdb::io::File f(path);
        f.write({sphere, colour});
        f.close();
        if (nan) {
            // The second map's 15 values (after its name) all NaN.
            std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
            const std::string bytes((std::istreambuf_iterator<char>(io)), {});
            const size_t map = bytes.find("UniformScaleMap", bytes.find("UniformScaleMap") + 1);
            EXPECT_NE(map, std::string::npos);
            io.seekp(std::streamoff(map + 15));
            const double q = std::numeric_limits<double>::quiet_NaN();
            for (int i = 0; i < 15; ++i)
                io.write(reinterpret_cast<const char*>(&q), sizeof q);
        }
        return path;
    };
    const std::string same = write("same.vdb", 0.05, false);
    const LevelSetGrids ok = readLevelSet(same);
    ASSERT_TRUE(ok.color);
    EXPECT_TRUE(readColourGrid(same, *ok.surface, nullptr));
    const std::string otherFile = write("other.vdb", 0.0344828, false);
    const std::string nan = write("nan.vdb", 0.05, true);
    const std::string other =
        "grid 'Cd' has another transform than grid 'surface' (voxels of "
        "0.0344828, not 0.05; row 0, column 0 of its matrix 0.0344828, "
        "not 0.05)";
    expectInputError([&] { readLevelSet(otherFile); }, other, "readLevelSet, another voxel size");
    expectInputError([&] { readColourGrid(otherFile, *ok.surface, nullptr); }, other,
                     "readColourGrid, another voxel size");
    const std::string unusable = "grid 'Cd' has a transform OpenVDB cannot use";
    expectInputError([&] { readLevelSet(nan); }, unusable, "readLevelSet, a NaN matrix");
    expectInputError([&] { readColourGrid(nan, *ok.surface, nullptr); }, unusable,
                     "readColourGrid, a NaN matrix");
}

TEST(VdbRead, AForeignColourGridOfNoColourIsNamed)
{
    // Finite colours of 1e30 in a foreign Cd made pictures of 1e30 and
    // infinity, and meshes whose colours cambium's own reader refuses, exit 0
    // (sweep 11): a colour's components are at most a half float's largest,
    // as a bake paints them; in voxels, tiles and the background alike.
    openvdb::initialize();
    const std::string dir = freshDir("cambium_vdb_read_colours").string();
    openvdb::FloatGrid::Ptr sphere =
        openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f), 0.1f);
    sphere->setName("surface");
    auto write = [&](const std::string& file, const openvdb::Vec3f& voxel,
                     const openvdb::Vec3f& tile, const openvdb::Vec3f& background) {
        openvdb::Vec3fGrid::Ptr cd = openvdb::Vec3fGrid::create(background);
        cd->setName("Cd");
        cd->setTransform(sphere->transform().copy());
        cd->tree().setValueOn(openvdb::Coord(10, 0, 0), voxel);
        cd->tree().addTile(1, openvdb::Coord(0, 0, 64), tile, true);
        const std::string path = dir + "/" + file;
        openvdb::io::File f(path);
        f.write({sphere, cd});
        f.close();
        return path;
    };
    const openvdb::Vec3f red(1.0f, 0.0f, 0.0f), huge(1e30f, -1e30f, 3e38f);
    const openvdb::Vec3f bright(65504.0f, 0.0f, 0.0f);  // (an HDR photo's brightest)
    EXPECT_TRUE(readLevelSet(write("ok.vdb", bright, red, openvdb::Vec3f(0.0f))).color);
    expectInputError([&] { readLevelSet(write("voxel.vdb", huge, red, openvdb::Vec3f(0.0f))); },
                     "grid 'Cd' has a voxel at (10, 0, 0) whose colour (1e+30, -1e+30, 3e+38) is "
                     "not one (a colour's components are numbers of magnitude at most 65504)",
                     "a voxel");
    expectInputError([&] { readLevelSet(write("tile.vdb", red, huge, openvdb::Vec3f(0.0f))); },
                     "grid 'Cd' has a tile at (0, 0, 64) whose colour (1e+30", "a tile");
    // (the background fills the leaf's inactive voxels too: named there)
    expectInputError([&] { readLevelSet(write("background.vdb", red, red, huge)); },
                     "grid 'Cd' has a voxel at (8, 0, 0) whose colour (1e+30", "the background");
}

TEST(VdbRead, AFrustumLevelSetAndAMapWhoseInverseDoesNotUndoItAreNamed)
{
    openvdb::initialize();
    openvdb::FloatGrid::Ptr sphere =
        openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f), 0.1f);
    sphere->setName("surface");
    sphere->setTransform(openvdb::math::Transform::createFrustumTransform(
        openvdb::BBoxd(openvdb::Vec3d(-20.0), openvdb::Vec3d(20.0)), 0.5, 2.0, 0.1));
    const std::string dir = freshDir("cambium_vdb_read_maps").string();
    openvdb::io::File f(dir + "/frustum.vdb");
    f.write({sphere});
    f.close();
    expectInputError([&] { readLevelSet(dir + "/frustum.vdb"); },
                     "grid 'surface' has a NonlinearFrustumMap transform: not a usable level set",
                     "a frustum");
    // A uniform scale map stores its scale, voxel size and inverse apart:
    // the inverse's x doubled moves every world point's index.
    const std::string path =
        writeForeignSphere("cambium_vdb_read_inverse", "i.vdb", openvdb::Vec3f(0.0f), 0.1f);
    EXPECT_NO_THROW(readLevelSet(path));
    std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(io)), {});
    const size_t map = bytes.find("UniformScaleMap");
    ASSERT_NE(map, std::string::npos);
    const double inverse = 20.0;  // (1 / 0.1, doubled)
    io.seekp(std::streamoff(map + 15 + 48));
    io.write(reinterpret_cast<const char*>(&inverse), sizeof inverse);
    io.close();
    expectInputError([&] { readLevelSet(path); },
                     "grid 'surface' has a transform whose stored inverse does not undo it",
                     "a damaged inverse");
}

TEST(VdbRead, LazyLeavesDecodeWhatIsPickedAsOpenVdbReadsIt)
{
    // A level set read with its topology only, its leaves decoded a
    // selection at a time and dropped (what render does, a strip of the
    // picture at a time): the first decode reads the grid through, later
    // ones only the picked leaves' bytes, near ones in one read and far ones
    // in reads of their own.  A leaf decoded equals io::File's, bit for bit;
    // one not decoded, or dropped, reads as zero.  Floats (cambium's decoder)
    // and halves (OpenVDB's).
    openvdb::initialize();
    const BakedGrids g = bakeTree(redAndBlueSpheres(), 0.0045, 3.0, true);
    const std::string dir = freshDir("cambium_vdb_read_lazy").string();
    using Leaf = openvdb::FloatTree::LeafNodeType;
    for (bool halves : {false, true}) {
        VdbFileInfo info;
        info.half = halves;
        const std::string path = dir + (halves ? "/half.vdb" : "/float.vdb");
        writeVdb(g, path, info);
        const openvdb::FloatGrid::Ptr ref =
            openvdb::gridPtrCast<openvdb::FloatGrid>(openVdbRead(path, "surface"));
        VdbSummary summary;
        const LevelSetGrids r =
            readLevelSetDelayed(path, summary, kSurfaceGrid, ColourRead::None, false);
        ASSERT_FALSE(r.color);
        LazyLeaves lazy(path, summary, *r.surface);
        const std::vector<Leaf*>& leaves = lazy.leaves();
        ASSERT_EQ(leaves.size(), ref->tree().leafCount());
        ASSERT_GT(leaves.size(), 1500u);
        // Leaves that are io::File's, and leaves that read as zero.
        auto count = [&](bool decoded) {
            size_t n = 0;
            for (const Leaf* leaf : leaves) {
                const Leaf* want = ref->tree().probeConstLeaf(leaf->origin());
                bool same = want && want->getValueMask() == leaf->getValueMask(), zero = true;
                for (openvdb::Index k = 0; k < Leaf::SIZE; ++k) {
                    const float a = leaf->getValue(k);
                    same = same && want && std::memcmp(&a, &want->getValue(k), sizeof a) == 0;
                    zero = zero && a == 0.0f;
                }
                n += decoded ? same : zero;
            }
            return n;
        };
        EXPECT_EQ(count(false), leaves.size()) << "every leaf reads as zero before a decode";
        std::vector<size_t> thirds, others, far;
        for (size_t i = 0; i < leaves.size(); ++i) {
            (i % 3 == 0 ? thirds : others).push_back(i);
            if (i % 211 == 5)  // (more than the 64 kB a read goes through between picks)
                far.push_back(i);
        }
        lazy.decode(thirds);  // (the grid read through)
        EXPECT_EQ(count(true), thirds.size());
        EXPECT_EQ(count(false), others.size());
        lazy.drop(thirds);
        lazy.decode(far);  // (leaves read on their own)
        EXPECT_EQ(count(true), far.size());
        EXPECT_EQ(count(false), leaves.size() - far.size());
        lazy.decode(others);  // (near leaves read together, gaps read through)
        EXPECT_EQ(count(true),
                  others.size() + size_t(std::count_if(far.begin(), far.end(),
                                                       [](size_t i) { return i % 3 == 0; })));
        lazy.decode(thirds);
        EXPECT_EQ(count(true), leaves.size());
        EXPECT_NO_THROW(lazy.checkZeroCrossing());
    }
}

TEST(VdbRead, ABandWithoutAZeroCrossingIsNamed)
{
    // A foreign band of values all on one side meshed to nothing and drew an
    // empty picture, exit 0 (sweep 10).
    openvdb::initialize();
    const std::string dir = freshDir("cambium_vdb_read_crossing").string();
    for (float sign : {1.0f, -1.0f}) {
        openvdb::FloatGrid::Ptr sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
            1.0f, openvdb::Vec3f(0.0f), 0.1f);
        sphere->setName("surface");
        for (auto v = sphere->tree().beginValueOn(); v; ++v)
            v.setValue(sign * (std::abs(*v) + 0.01f));
        const std::string path = dir + (sign > 0.0f ? "/out.vdb" : "/in.vdb");
        openvdb::io::File f(path);
        f.write({sphere});
        f.close();
        expectInputError(
            [&] { readLevelSet(path); },
            fmt::format("active voxels, every one {}", sign > 0.0f ? "outside" : "inside"), path);
        // The same band in a file of cambium's, read with its topology only
        // (render): named once its leaves are decoded.
        LevelSetGrids grids;
        grids.surface = sphere;
        const std::string ours = dir + (sign > 0.0f ? "/our-out.vdb" : "/our-in.vdb");
        writeVdb(grids, ours, VdbFileInfo());
        VdbSummary summary;
        const LevelSetGrids r =
            readLevelSetDelayed(ours, summary, kSurfaceGrid, ColourRead::None, false);
        LazyLeaves lazy(ours, summary, *r.surface);
        // (nothing decoded yet: the check reads the leaves itself)
        expectInputError(
            [&] { lazy.checkZeroCrossing(); },
            fmt::format("active voxels, every one {}", sign > 0.0f ? "outside" : "inside"), ours);
        // Another tool's file read so is read whole, and checked as it is read.
        VdbSummary foreign;
        expectInputError(
            [&] { readLevelSetDelayed(path, foreign, kSurfaceGrid, ColourRead::None, false); },
            fmt::format("active voxels, every one {}", sign > 0.0f ? "outside" : "inside"), path);
    }
    // A real level set whose leaves decoded so far all lie outside (a close
    // view of the band's outer part) passes, reading other leaves to see
    // both sides, and keeps those held.
    LevelSetGrids grids;
    grids.surface =
        openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f), 0.05f);
    grids.surface->setName("surface");
    const std::string real = dir + "/real.vdb";
    writeVdb(grids, real, VdbFileInfo());
    VdbSummary summary;
    const LevelSetGrids r =
        readLevelSetDelayed(real, summary, kSurfaceGrid, ColourRead::None, false);
    LazyLeaves lazy(real, summary, *r.surface);
    std::vector<size_t> outside;
    for (size_t i = 0; i < lazy.leaves().size(); ++i) {
        const auto* leaf = grids.surface->tree().probeConstLeaf(lazy.leaves()[i]->origin());
        ASSERT_TRUE(leaf);
        bool in = false;
        for (auto v = leaf->cbeginValueOn(); v; ++v)
            in = in || *v < 0.0f;
        if (!in)
            outside.push_back(i);
    }
    ASSERT_GT(outside.size(), 10u);
    ASSERT_LT(outside.size(), lazy.leaves().size());
    lazy.decode(outside);
    EXPECT_NO_THROW(lazy.checkZeroCrossing());
    size_t held = 0;
    for (size_t i = 0; i < lazy.leaves().size(); ++i)
        held += !lazy.leaves()[i]->buffer().empty();
    EXPECT_EQ(held, outside.size())
        << "the leaves the check read are dropped again, the others kept";
}

TEST(VdbRead, ATransformWhoseScaleIsNotItsVoxelSizeIsNamed)
{
    // A uniform scale map stores its scale and its voxel size apart, and
    // OpenVDB reads both as they are: a scale of 3.6e307 under a stored 0.2
    // passed as 0.2 voxels and meshed to vertices at -inf, exit 0.
    const std::string path =
        writeForeignSphere("cambium_vdb_read_map", "m.vdb", openvdb::Vec3f(0.0f), 0.2f);
    EXPECT_NO_THROW(readLevelSet(path));
    std::fstream io(path, std::ios::in | std::ios::out | std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(io)), {});
    const size_t map = bytes.find("UniformScaleMap");
    ASSERT_NE(map, std::string::npos);
    // The scale's z, its top byte (sign and exponent) changed.
    io.seekp(std::streamoff(map + 15 + 23));
    io.put('\x7f');
    io.close();
    expectInputError([&] { readLevelSet(path); },
                     "grid 'surface' has a transform whose axis z is 3.59539e+307 long and whose "
                     "voxel size says 0.2",
                     "a scale of 3.6e307");
}

TEST(VdbRead, ALevelSetBeyondFloatPrecisionIsRefused)
{
    // Meshes and pictures hold positions as floats: a sphere 1e7 from the
    // origin meshed with exit 0 to vertices on three x values.
    const std::string path = writeForeignSphere("cambium_vdb_read_far", "far.vdb",
                                                openvdb::Vec3f(1e7f, 0.0f, 0.0f), 0.05f);
    expectInputError([&] { readLevelSet(path); },
                     "grid 'surface' reaches 1e+07 from the origin, 2e+08 voxels of 0.05: beyond "
                     "1048576 voxels",
                     "a sphere at 1e7");
}

TEST(VdbRead, AVerifiedFileIsReadAgainOnlyWhereItChanged)
{
    // A command reads a frame's grids in turn, each verified before OpenVDB
    // decodes it: once verified, the file is not read again while it stays
    // as it was; replaced, or written and dated otherwise, it is.
    openvdb::initialize();
    const BakedGrids g = bakeTree(redAndBlueSpheres(), 0.01, 3.0, true);
    const std::string dir = freshDir("cambium_vdb_read_verified").string();
    const std::string path = dir + "/frame.vdb", damaged = dir + "/damaged.vdb";
    writeVdb(g, path, VdbFileInfo());
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    // (a file written within two seconds is verified every time: a coarse
    // clock dates two writes within a tick alike)
    VdbSummary summary = checkLevelSetFile(path);
    EXPECT_EQ(summary.verified.inode, 0u) << "just written: not recorded";
    std::this_thread::sleep_for(std::chrono::milliseconds(2100));
    summary = checkLevelSetFile(path);
    ASSERT_NE(summary.verified.inode, 0u) << "the verdict is recorded";
    const FileIdentity recorded = summary.verified;
    EXPECT_TRUE(verifyVdbChecksum(path, summary));
    EXPECT_TRUE(summary.verified == recorded);
    ASSERT_TRUE(gridIn(summary, "surface"));
    const int64_t last = gridIn(summary, "surface")->end - 1;  // (a byte of its values)
    std::string flipped = bytes;
    flipped[size_t(last)] ^= 0x10;
    const std::string message = "a damaged .vdb file: its bytes do not match the checksum";
    // 1. Replaced (renamed over it: another inode).
    std::ofstream(damaged, std::ios::binary) << flipped;
    std::filesystem::rename(damaged, path);
    expectInputError([&] { verifyVdbChecksum(path, summary); }, message, "replaced");
    summary.verified = recorded;
    expectInputError([&] { readLevelSet(path, kSurfaceGrid, ColourRead::Whole, &summary); },
                     message, "replaced, read with the old summary");
    // 2. Verified again once good, then written in place and dated (its
    //    size, inode and, where the clock is coarse, its time unchanged but
    //    for the date set).
    std::ofstream(path, std::ios::binary) << bytes;
    std::this_thread::sleep_for(std::chrono::milliseconds(2100));
    summary = checkLevelSetFile(path);
    ASSERT_NE(summary.verified.inode, 0u);
    const FileIdentity good = summary.verified;
    LevelSetGrids read = readLevelSet(path, kSurfaceGrid, ColourRead::Lazy, &summary);
    ASSERT_TRUE(read.surface && read.color);
    std::fstream(path, std::ios::binary | std::ios::in | std::ios::out)
        .seekp(last)
        .put(flipped[size_t(last)]);
    const struct timespec dates[2] = {{1, 0}, {1, 0}};
    ASSERT_EQ(::utimensat(AT_FDCWD, path.c_str(), dates, 0), 0);
    expectInputError([&] { verifyVdbChecksum(path, summary); }, message, "written in place");
    summary.verified = good;
    expectInputError([&] { readColourGrid(path, *read.surface, nullptr, &summary); }, message,
                     "written in place, its colour read with the old summary");
}

TEST(VdbRead, DamageInCambiumsOwnFilesIsNamedByTheChecksum)
{
    // readLevelSet checks the checksum before OpenVDB reads the topology:
    // a bit changed in the topology or in the values is named by the
    // checksum, before OpenVDB reads a byte of the trees (unless the file
    // is signed again, below).
    openvdb::initialize();
    const BakedGrids g = bakeTree(redAndBlueSpheres(), 0.01, 3.0, true);
    const std::string dir = freshDir("cambium_vdb_read_checksum").string();
    const std::string good = dir + "/good.vdb";
    writeVdb(g, good, VdbFileInfo());
    const VdbSummary s = inspectVdb(good);
    const VdbSummary::Grid* surface = gridIn(s, "surface");
    ASSERT_TRUE(surface);
    ASSERT_GT(surface->block - surface->begin, 100);
    std::ifstream in(good, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    const int64_t places[] = {surface->begin + (surface->block - surface->begin) / 2,
                              surface->block - 1, (surface->block + surface->end) / 2};
    for (int64_t at : places) {
        for (unsigned char flip : {0x01, 0x80}) {
            std::string damaged = bytes;
            damaged[size_t(at)] = char(damaged[size_t(at)] ^ flip);
            const std::string path = dir + "/damaged.vdb";
            std::ofstream(path, std::ios::binary) << damaged;
            const std::string what = "byte " + std::to_string(at) + " ^ " + std::to_string(flip),
                              message =
                                  "damaged.vdb: a damaged .vdb file: its bytes do not "
                                  "match the checksum";
            expectInputError([&] { readLevelSet(path); }, message, what);
            expectInputError(
                [&] {
                    VdbSummary summary;
                    readLevelSetDelayed(path, summary);
                },
                message, what + " (delayed)");
        }
    }
    // Bytes of the topology set to other values all along it: OpenVDB's
    // topology reader corrupted the heap on some (a sweep's byte set to
    // 0xd9 aborted mesh and render), so the checksum comes first.
    const int64_t step = std::max<int64_t>(1, (surface->block - surface->begin) / 150);
    for (int64_t at = surface->begin; at < surface->block; at += step)
        for (unsigned char value : {0x00, 0xd9, 0xff}) {
            if (bytes[size_t(at)] == char(value))
                continue;
            std::string damaged = bytes;
            damaged[size_t(at)] = char(value);
            const std::string path = dir + "/topology.vdb";
            std::ofstream(path, std::ios::binary) << damaged;
            expectInputError([&] { readLevelSet(path); }, "topology.vdb: a damaged .vdb file",
                             "byte " + std::to_string(at) + " = " + std::to_string(value));
        }
    EXPECT_TRUE(readLevelSet(good).surface);
    // signVdbAgain (the signedvdb fuzzer's): a file signed as it was
    // written stays byte for byte; one changed in its values and signed
    // again reaches the readers behind the checksum; a foreign file has no
    // checksum to sign.
    std::string same = bytes;
    ASSERT_TRUE(signVdbAgain(same));
    EXPECT_EQ(same, bytes);
    std::string changed = bytes;
    const size_t inValues = size_t((surface->block + surface->end) / 2);
    changed[inValues] = char(changed[inValues] ^ 0x10);
    ASSERT_TRUE(signVdbAgain(changed));
    const std::string signedPath = dir + "/signed.vdb";
    std::ofstream(signedPath, std::ios::binary) << changed;
    try {
        readLevelSet(signedPath);  // (the value changed, or a leaf that does not decode)
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
    }
    const std::string foreign =
        writeForeignSphere("cambium_vdb_read_signed_foreign", "f.vdb", openvdb::Vec3f(0.0f), 0.1f);
    std::ifstream fin(foreign, std::ios::binary);
    std::string foreignBytes((std::istreambuf_iterator<char>(fin)), {});
    EXPECT_FALSE(signVdbAgain(foreignBytes));
}
