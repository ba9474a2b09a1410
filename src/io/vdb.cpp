// cambium — .vdb output, and the structure check of .vdb input.
#include "io/vdb.h"

#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"
#include "core/versions.h"

#include <fmt/format.h>
#include <openvdb/io/Archive.h>
#include <openvdb/io/DelayedLoadMetadata.h>
#include <openvdb/io/File.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <charconv>
#include <functional>
#include <stdexcept>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <type_traits>
#include <vector>

namespace cambium {

namespace {

/// A seekable output stream's buffer in memory.
class MemoryBuf : public std::streambuf {
public:
    std::vector<char>& data() { return data_; }
    /// Empty again, its memory kept for the next use.
    void clear()
    {
        data_.clear();
        pos_ = 0;
    }

protected:
    int_type overflow(int_type c) override
    {
        if (!traits_type::eq_int_type(c, traits_type::eof())) {
            const char ch = traits_type::to_char_type(c);
            xsputn(&ch, 1);
        }
        return traits_type::not_eof(c);
    }
    std::streamsize xsputn(const char* s, std::streamsize n) override
    {
        if (pos_ + size_t(n) > data_.size())
            data_.resize(pos_ + size_t(n));
        std::memcpy(data_.data() + pos_, s, size_t(n));
        pos_ += size_t(n);
        return n;
    }
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override
    {
        const off_type base = dir == std::ios_base::beg   ? 0
                              : dir == std::ios_base::cur ? off_type(pos_)
                                                          : off_type(data_.size());
        if (base + off < 0 || size_t(base + off) > data_.size())
            return pos_type(off_type(-1));
        pos_ = size_t(base + off);
        return pos_type(off_type(pos_));
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }

private:
    std::vector<char> data_;
    size_t pos_ = 0;
};

const char kChecksumKey[] = "cambium_checksum";

/// A grid whose statistics count its leaves' buffers as held in memory:
/// what a packed grid's (PackedLeaves) would be with its values.
template <class GridT>
class ResidentGrid : public GridT {
public:
    explicit ResidentGrid(const GridT& grid)
        : GridT(const_cast<GridT&>(grid), openvdb::ShallowCopy())
    {
    }
    openvdb::Index64 memUsage() const override
    {
        using LeafT = typename GridT::TreeType::LeafNodeType;
        return GridT::memUsage() +
               this->tree().leafCount() *
                   openvdb::Index64(LeafT::SIZE * sizeof(typename GridT::ValueType));
    }
};

/// A grid with its packed leaves (null: a grid written from its values, which
/// writePacked accepts only without leaves).
struct PackedGrid {
    openvdb::GridBase::ConstPtr grid;
    const PackedLeaves* packed;
    bool byOrder = false;  ///< slots: the leaves' order, not their transient data
};

/// OpenVDB's archive writer on a stream of our own: what io::File::write
/// does (a seekable stream, so that readers find every grid by its offsets),
/// but on the checked writer's stream instead of an unchecked std::ofstream.
/// Blosc and active-mask compression, grid statistics.
class StreamArchive : public openvdb::io::Archive {
public:
    StreamArchive()
    {
        // The archive adds the grids' statistics (file_bbox_min/max,
        // file_mem_bytes, file_voxel_count: Arnold and others read them) and
        // file_compression to a shallow copy of each grid's metadata.
        setGridStatsMetadataEnabled(true);
        setCompression(openvdb::io::COMPRESS_BLOSC | openvdb::io::COMPRESS_ACTIVE_MASK);
    }

    void writeTo(std::ostream& os, const openvdb::GridCPtrVec& grids,
                 const openvdb::MetaMap& meta) const
    {
        write(os, grids, /*seekable=*/true, meta);
    }

    /// The compression the archive applies to `grid`'s buffers.
    uint32_t gridCompression(const openvdb::GridBase& grid) const
    {
        MemoryBuf scratch;
        std::ostream os(&scratch);
        setGridCompression(os, grid);
        return openvdb::io::getDataCompression(os);
    }

    /// Archive::write (OpenVDB 10) for grids whose buffers were serialised
    /// while they were made: the same bytes, but the buffers are the packed
    /// ones and the delayed-load metadata (each leaf's mask-compression byte
    /// and compressed size, which Archive::writeGrid finds by compressing
    /// every leaf once more) is read from them.  Archive::write cannot be
    /// given such grids: it reads every leaf's values.
    void writePacked(std::ostream& os, const std::vector<PackedGrid>& grids,
                     const openvdb::MetaMap& meta) const
    {
        namespace io = openvdb::io;
        io::StreamMetadata::Ptr fileMeta = io::getStreamMetadataPtr(os);
        if (!fileMeta) {
            fileMeta = std::make_shared<io::StreamMetadata>();
            io::setStreamMetadataPtr(os, fileMeta, /*transfer=*/false);
        }
        io::setDataCompression(os, compression());
        io::setWriteGridStatsMetadata(os, isGridStatsMetadataEnabled());
        writeHeader(os, /*seekable=*/true);
        meta.writeMeta(os);
        const int32_t count = int32_t(grids.size());
        os.write(reinterpret_cast<const char*>(&count), sizeof(count));
        std::set<std::string> names;
        for (const PackedGrid& g : grids) {
            const openvdb::GridBase& grid = *g.grid;
            // (Archive::write suffixes empty and repeated names.)
            if (grid.getName().empty() || !names.insert(grid.getName()).second)
                throw std::logic_error("writePacked: grid names must be unique and not empty");
            writePackedGrid(os, g, fileMeta);
            io::setStreamMetadataPtr(os, fileMeta, /*transfer=*/false);
            io::setDataCompression(os, compression());
        }
    }

private:
    void writePackedGrid(std::ostream& os, const PackedGrid& g,
                         const openvdb::io::StreamMetadata::Ptr& fileMeta) const
    {
        namespace io = openvdb::io;
        const openvdb::GridBase& grid = *g.grid;
        auto gridMeta = std::make_shared<io::StreamMetadata>(*fileMeta);
        gridMeta->setHalfFloat(grid.saveFloatAsHalf());
        gridMeta->gridMetadata() = static_cast<const openvdb::MetaMap&>(grid);
        io::setStreamMetadataPtr(os, gridMeta, /*transfer=*/false);
        io::GridDescriptor gd(grid.getName(), grid.type(), grid.saveFloatAsHalf());
        gd.writeHeader(os);
        const int64_t offsetPos = int64_t(os.tellp());
        gd.writeStreamPos(os);
        gd.setGridPos(os.tellp());
        setGridCompression(os, grid);
        const bool known = grid.apply<openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid>>(
            [&](const auto& typed) {
                using G = std::decay_t<decltype(typed)>;
                const auto& tree = typed.tree();
                const size_t leaves = tree.leafCount();
                if (leaves && !g.packed)
                    throw std::logic_error("writePacked: a grid with leaves but no packed leaves");
                // Metadata as Archive::writeGrid writes it: delayed-load
                // metadata on a shallow copy, then the statistics.
                // (A packed grid's statistics count the values it does not hold.)
                const openvdb::GridBase::Ptr copy =
                    g.byOrder ? openvdb::ConstPtrCast<openvdb::GridBase>(typed.copyGrid())
                              : std::make_shared<ResidentGrid<G>>(typed);
                // Leaf i's packed bytes (i: its place in the tree's order).
                auto bytesOf = [&](const auto& leaf, uint32_t i) {
                    return g.packed->bytes(g.byOrder ? i : leaf.transientData());
                };
                io::DelayedLoadMetadata delayed;
                const bool sizes = compression() & (io::COMPRESS_BLOSC | io::COMPRESS_ZIP);
                if (leaves) {
                    delayed.resizeMask(leaves);
                    if (sizes)
                        delayed.resizeCompressedSize(leaves);
                    uint32_t i = 0;
                    for (auto it = tree.cbeginLeaf(); it; ++it, ++i) {
                        const std::string_view b = bytesOf(*it, i);
                        const auto [mask, values] =
                            packedLeafLayout<typename G::ValueType>(b, it->getValueMask());
                        delayed.setMask(i, io::DelayedLoadMetadata::MaskType(mask));
                        if (sizes)
                            delayed.setCompressedSize(
                                i, io::DelayedLoadMetadata::CompressedSizeType(b.size() - values));
                    }
                }
                copy->insertMeta(openvdb::GridBase::META_FILE_DELAYED_LOAD, delayed);
                if (io::getWriteGridStatsMetadata(os)) {
                    copy->addStatsMetadata();
                    copy->insertMeta(openvdb::GridBase::META_FILE_COMPRESSION,
                                     openvdb::StringMetadata(
                                         io::compressionToString(io::getDataCompression(os))));
                }
                copy->writeMeta(os);
                grid.writeTransform(os);
                grid.writeTopology(os);
                gd.setBlockPos(os.tellp());
                uint32_t i = 0;
                for (auto it = tree.cbeginLeaf(); it; ++it, ++i) {
                    const std::string_view b = bytesOf(*it, i);
                    os.write(b.data(), std::streamsize(b.size()));
                }
            });
        if (!known)
            throw std::logic_error("writePacked: a grid of a type cambium does not pack");
        gd.setEndPos(os.tellp());
        os.seekp(offsetPos, std::ios_base::beg);
        gd.writeStreamPos(os);
        gd.seekToEnd(os);
    }

    /// A packed leaf's mask-compression byte and where its compressed values
    /// begin (writeCompressedValues: value mask, that byte, up to two
    /// inactive values, a selection mask, the values).
    template <class ValueT, class MaskT>
    static std::pair<int8_t, size_t> packedLeafLayout(std::string_view b, const MaskT& mask)
    {
        namespace io = openvdb::io;
        const size_t maskBytes = MaskT::WORD_COUNT * sizeof(typename MaskT::Word);
        bool same = b.size() > maskBytes;
        for (openvdb::Index w = 0; same && w < MaskT::WORD_COUNT; ++w) {
            typename MaskT::Word word;
            std::memcpy(&word, b.data() + w * sizeof(word), sizeof(word));
            same = word == mask.template getWord<typename MaskT::Word>(w);
        }
        if (!same)
            throw std::logic_error("writePacked: a leaf whose packed bytes are not its own");
        const int8_t m = int8_t(b[maskBytes]);
        size_t at = maskBytes + 1;
        if (m == io::NO_MASK_AND_ONE_INACTIVE_VAL || m == io::MASK_AND_ONE_INACTIVE_VAL)
            at += sizeof(ValueT);
        if (m == io::MASK_AND_TWO_INACTIVE_VALS)
            at += 2 * sizeof(ValueT);
        if (m == io::MASK_AND_NO_INACTIVE_VALS || m == io::MASK_AND_ONE_INACTIVE_VAL ||
            m == io::MASK_AND_TWO_INACTIVE_VALS)
            at += maskBytes;
        if (at > b.size())
            throw std::logic_error("writePacked: a packed leaf shorter than its header");
        return {m, at};
    }
};

const char kPlaceholder[] = "0000000000000000";  // the checksum's 16 hex digits, before

/// The grids and file metadata of a .vdb: cambium's metadata on every grid,
/// the checksum's placeholder in the file's.
struct PreparedVdb {
    openvdb::GridCPtrVec grids;      ///< for OpenVDB's own writer (the tests)
    std::vector<PackedGrid> packed;  ///< or packed
    std::vector<std::shared_ptr<const PackedLeaves>> owned;  ///< (packed here)
    openvdb::MetaMap meta;
};

/// A grid's leaves packed on all cores, slots in their order: what OpenVDB's
/// serial writer does a leaf at a time, after compressing every leaf once
/// more for the delayed-load metadata.
std::shared_ptr<const PackedLeaves> packGrid(const openvdb::GridBase& grid, bool half)
{
    std::shared_ptr<PackedLeaves> out;
    grid.apply<openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid>>([&](const auto& typed) {
        using LeafT = typename std::decay_t<decltype(typed)>::TreeType::LeafNodeType;
        std::vector<const LeafT*> leaves;
        leaves.reserve(typed.tree().leafCount());
        for (auto it = typed.tree().cbeginLeaf(); it; ++it)
            leaves.push_back(it.getLeaf());
        out = std::make_shared<PackedLeaves>(grid, half, leaves.size());
        constexpr size_t kBlock = 256;  // leaves per block (about 100-300 kB)
        // A block per thread, its buffer reused: fresh pages cost more than
        // the compression (about 8 us each on the 2-core VM).
        tbb::enumerable_thread_specific<std::optional<PackedLeaves::Block>> blocks;
        tbb::parallel_for(size_t(0), (leaves.size() + kBlock - 1) / kBlock, [&](size_t b) {
            std::optional<PackedLeaves::Block>& block = blocks.local();
            if (!block)
                block.emplace(*out);
            for (size_t i = b * kBlock; i < std::min(leaves.size(), (b + 1) * kBlock); ++i)
                block->add(uint32_t(i), *leaves[i]);
            block->keep();
        });
    });
    return out;
}

PreparedVdb prepareVdb(const LevelSetGrids& grids, const VdbFileInfo& info, bool parallel)
{
    PreparedVdb v;
    openvdb::GridCPtrVec& out = v.grids;
    openvdb::MetaMap& fileMeta = v.meta;
    if (!grids.surface)
        throw std::logic_error("writeVdb: no surface grid");  // (it sets the file's voxel size)
    const bool packed = grids.surfacePacked || grids.colorPacked;
    const std::pair<openvdb::GridBase::Ptr, const PackedLeaves*> all[] = {
        {grids.surface, grids.surfacePacked.get()},
        {grids.color, grids.colorPacked.get()},
        {grids.density, nullptr}};
    for (const auto& [g, leaves] : all) {
        if (!g)
            continue;
        g->insertMeta("cambium_scene", openvdb::StringMetadata(info.scene));
        g->insertMeta("cambium_voxel_size", openvdb::DoubleMetadata(grids.surface->voxelSize()[0]));
        g->insertMeta("cambium_threshold", openvdb::DoubleMetadata(info.threshold));
        g->insertMeta("cambium_half_width", openvdb::DoubleMetadata(info.halfWidth));
        g->insertMeta("cambium_frame", openvdb::Int64Metadata(info.frame));
        g->insertMeta("cambium_time", openvdb::DoubleMetadata(info.time));
        g->insertMeta("cambium_version", openvdb::StringMetadata(version()));
        g->setSaveFloatAsHalf(info.half);
        if (leaves && leaves->half() != info.half)
            throw std::logic_error("writeVdb: leaves packed with another half setting");
        if (packed) {
            v.packed.push_back({g, leaves});
        } else if (parallel) {
            if (g->isType<openvdb::FloatGrid>() || g->isType<openvdb::Vec3fGrid>()) {
                v.owned.push_back(packGrid(*g, info.half));
                v.packed.push_back({g, v.owned.back().get(), /*byOrder=*/true});
            } else {
                v.packed.push_back({g, nullptr});  // (without leaves: writePacked checks)
            }
        } else {
            out.push_back(g);
        }
    }
    fileMeta.insertMeta("creator", openvdb::StringMetadata(fmt::format("cambium {}", version())));
    if (!info.sequence.empty())
        fileMeta.insertMeta("cambium_sequence", openvdb::StringMetadata(info.sequence));
    if (!info.part.empty())
        fileMeta.insertMeta("cambium_part", openvdb::StringMetadata(info.part));
    fileMeta.insertMeta(kChecksumKey, openvdb::StringMetadata(kPlaceholder));
    return v;
}

void writeArchive(std::ostream& os, const PreparedVdb& v)
{
    const StreamArchive archive;
    if (!v.grids.empty())
        archive.writeTo(os, v.grids, v.meta);
    else
        archive.writePacked(os, v.packed, v.meta);
}

/// Fills in the checksum of a file OpenVDB wrote from prepareVdb's grids:
/// its entry found in the file metadata (within the first 64 kB, before any
/// grid), the bytes after it summed in blocks read through `read(offset,
/// data, n)`, the digest written through `write(offset, data, n)`.
void patchChecksum(uint64_t size, const std::function<void(uint64_t, char*, size_t)>& read,
                   const std::function<void(uint64_t, const char*, size_t)>& write)
{
    const std::string placeholder = kPlaceholder;
    const std::string entry =
        std::string(kChecksumKey) + std::string("\x06\0\0\0string\x10\0\0\0", 14) + placeholder;
    std::vector<char> block(size_t(1) << 22);
    const size_t head = size_t(std::min<uint64_t>(size, 1 << 16));
    read(0, block.data(), head);
    const auto at =
        std::search(block.begin(), block.begin() + long(head), entry.begin(), entry.end());
    if (at == block.begin() + long(head))
        throw std::runtime_error("the checksum's place was not found in the file OpenVDB wrote");
    const uint64_t value = uint64_t(at - block.begin()) + entry.size() - placeholder.size();
    Checksum64 sum;
    for (uint64_t from = value + placeholder.size(); from < size;) {
        const size_t n = size_t(std::min<uint64_t>(block.size(), size - from));
        read(from, block.data(), n);
        sum.update(block.data(), n);
        from += n;
    }
    const std::string digest = fmt::format("{:016x}", sum.value());
    write(value, digest.data(), digest.size());
}

}  // namespace

void writeVdb(const LevelSetGrids& grids, const std::string& path, const VdbFileInfo& info)
{
    // Written straight into the checked writer's temporary (no copy of the
    // file in memory), then the checksum read back from it and patched in.
    const PreparedVdb v = prepareVdb(grids, info, true);
    writeFile(
        path, [&](std::ostream& os) { writeArchive(os, v); },
        [&](WrittenFile& f) {
            patchChecksum(
                f.size(), [&](uint64_t at, char* data, size_t n) { f.read(at, data, n); },
                [&](uint64_t at, const char* data, size_t n) { f.write(at, data, n); });
        });
}

std::vector<char> encodeVdb(const LevelSetGrids& grids, const VdbFileInfo& info, bool parallel)
{
    const PreparedVdb v = prepareVdb(grids, info, parallel);
    MemoryBuf memory;
    {
        std::ostream os(&memory);
        writeArchive(os, v);
    }
    std::vector<char> bytes = std::move(memory.data());
    patchChecksum(
        bytes.size(),
        [&](uint64_t at, char* data, size_t n) { std::memcpy(data, bytes.data() + at, n); },
        [&](uint64_t at, const char* data, size_t n) { std::memcpy(bytes.data() + at, data, n); });
    return bytes;
}

PackedLeaves::PackedLeaves(const openvdb::GridBase& grid, bool half, size_t slots)
    : half_(half), compression_(StreamArchive().gridCompression(grid)), slots_(slots)
{
    const bool known = grid.apply<openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid>>(
        [&](const auto& typed) {
            using V = typename std::decay_t<decltype(typed)>::ValueType;
            background_ = std::make_shared<V>(typed.background());
        });
    if (!known)
        throw std::logic_error("PackedLeaves: a grid of a type cambium does not pack");
}

PackedLeaves::~PackedLeaves() = default;

size_t PackedLeaves::addSlots(size_t n)
{
    const std::lock_guard<std::mutex> lock(mutex_);
    const size_t first = slots_.size();
    slots_.resize(first + n);
    return first;
}

std::string_view PackedLeaves::bytes(uint32_t slot) const
{
    return {slots_[slot].data, slots_[slot].size};
}

struct PackedLeaves::Block::Impl {
    explicit Impl(PackedLeaves& o) : owner(o), os(&buf)
    {
        // The stream state writeCompressedValues reads: the compression and
        // the background inactive values are compared with.
        openvdb::io::setDataCompression(os, owner.compression_);
        openvdb::io::setGridBackgroundValuePtr(os, owner.background_.get());
    }
    template <class LeafT>
    void add(uint32_t slot, const LeafT& leaf)
    {
        starts.emplace_back(slot, buf.data().size());
        leaf.writeBuffers(os, owner.half_);
    }
    PackedLeaves& owner;
    MemoryBuf buf;
    std::ostream os;
    std::vector<std::pair<uint32_t, size_t>> starts;
};

PackedLeaves::Block::Block(PackedLeaves& owner) : impl_(std::make_unique<Impl>(owner)) {}
PackedLeaves::Block::~Block() = default;

void PackedLeaves::Block::add(uint32_t slot, const openvdb::FloatTree::LeafNodeType& leaf)
{
    impl_->add(slot, leaf);
}

void PackedLeaves::Block::add(uint32_t slot, const openvdb::Vec3fTree::LeafNodeType& leaf)
{
    impl_->add(slot, leaf);
}

void PackedLeaves::Block::keep()
{
    Impl& b = *impl_;
    const size_t n = b.buf.data().size();
    if (n) {
        // An exact copy: the buffer grew by doubling and is reused.
        auto chunk = std::make_unique<char[]>(n);
        std::memcpy(chunk.get(), b.buf.data().data(), n);
        PackedLeaves& o = b.owner;
        const std::lock_guard<std::mutex> lock(o.mutex_);
        for (size_t k = 0; k < b.starts.size(); ++k) {
            const size_t end = k + 1 < b.starts.size() ? b.starts[k + 1].second : n;
            o.slots_[b.starts[k].first] = {chunk.get() + b.starts[k].second,
                                           uint32_t(end - b.starts[k].second)};
        }
        o.total_ += n;
        o.chunks_.push_back(std::move(chunk));
    }
    b.buf.clear();
    b.starts.clear();
}

namespace {

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

}  // namespace

VdbSummary inspectVdb(const std::string& path)
{
    VdbSummary s;
    s.bytes = checkInputFile(path, ".vdb file");
    VdbReader r(path, s.bytes);
    constexpr int64_t kMagic = 0x56444220;
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

    constexpr uint32_t kNameLimit = 1 << 12, kValueLimit = 1 << 16;
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
                const uint32_t count = r.value<uint32_t>("delayed-load count");
                const uint32_t packed = r.value<uint32_t>("delayed-load size");
                if (count > s.bytes || packed > n - 8)
                    r.damaged(fmt::format("metadata '{}' counts {} leaves in {} bytes", name, count,
                                          packed));
                if (leaves)
                    *leaves = count;
                r.skip(n - 8, "metadata value");
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
        r.skip(4, "grid compression flags");
        metadata(uint64_t(block), nullptr, &g.leaves);
        if (r.at() + 4 > uint64_t(block))
            r.damaged(fmt::format("grid '{}' has no room for its transform", g.name));
        r.string("transform type", kNameLimit);
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

bool verifyVdbChecksum(const std::string& path, const VdbSummary& s)
{
    const auto expected = s.strings.find(kChecksumKey);
    if (expected == s.strings.end() || s.checksumEnd == 0)
        return false;
    std::ifstream in(path, std::ios::binary);
    in.seekg(std::streamoff(s.checksumEnd));
    Checksum64 sum;
    std::vector<char> chunk(size_t(1) << 20);
    while (in) {
        in.read(chunk.data(), std::streamsize(chunk.size()));
        sum.update(chunk.data(), size_t(in.gcount()));
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
    return true;
}

std::string framePart(long long frame)
{
    return fmt::format("frame {}", frame);
}

std::string tilePart(int k, int count)
{
    return fmt::format("tile {}/{}", k + 1, count);
}

FileStamp readFileStamp(const std::string& path)
{
    const VdbSummary s = inspectVdb(path);
    FileStamp stamp;
    if (const auto key = s.strings.find("cambium_sequence"); key != s.strings.end())
        stamp.key = key->second;
    if (const auto part = s.strings.find("cambium_part"); part != s.strings.end())
        stamp.part = part->second;
    return stamp;
}

}  // namespace cambium
