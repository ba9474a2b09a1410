// cambium — .vdb output: baked grids as OpenVDB writes them, on all cores.
#include "io/vdb.h"

#include "core/error.h"
#include "core/files.h"
#include "core/hash.h"
#include "core/versions.h"
#include "io/leaf_layout.h"
#include "io/leaf_values.h"

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
#include <future>
#include <stdexcept>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>
#include <tuple>
#include <type_traits>
#include <vector>

namespace cambium {

namespace {

/// An output stream's buffer whose every write goes through xsputn and
/// every seek through seekoff (MemoryBuf, PiecesBuf).
class OutputBuf : public std::streambuf {
protected:
    int_type overflow(int_type c) override
    {
        if (!traits_type::eq_int_type(c, traits_type::eof())) {
            const char ch = traits_type::to_char_type(c);
            xsputn(&ch, 1);
        }
        return traits_type::not_eof(c);
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }
};

/// A seekable output stream's buffer in memory.
class MemoryBuf : public OutputBuf {
public:
    std::vector<char>& data() { return data_; }
    /// Empty again, its memory kept for the next use.
    void clear()
    {
        data_.clear();
        pos_ = 0;
    }

protected:
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

private:
    std::vector<char> data_;
    size_t pos_ = 0;
};

/// A seekable output stream's buffer that keeps what is written to it in
/// memory but long runs of bytes that outlive it (packed leaves) by
/// reference: an archive laid out once and then written to a file while
/// another thread sums it (writeVdb), without a copy of its leaves.  A seek
/// back lands in the bytes it holds (a grid's stream positions), and writes
/// there overwrite them.
class PiecesBuf : public OutputBuf {
public:
    /// `n` bytes at `p`, which outlive this buffer, appended by reference.
    void reference(const char* p, size_t n)
    {
        if (pos_ != owned_.size())
            throw std::logic_error("PiecesBuf: a reference written over");
        refs_.push_back({owned_.size(), p, n});
        refBytes_ += n;
    }
    uint64_t size() const { return owned_.size() + refBytes_; }
    /// The bytes it holds before the first reference.
    std::string_view head() const
    {
        return {owned_.data(), refs_.empty() ? owned_.size() : refs_.front().at};
    }
    /// Every piece in order.
    template <class F>
    void forEach(F&& f) const
    {
        size_t from = 0;
        for (const Ref& r : refs_) {
            if (r.at > from)
                f(owned_.data() + from, r.at - from);
            f(r.p, r.n);
            from = r.at;
        }
        if (owned_.size() > from)
            f(owned_.data() + from, owned_.size() - from);
    }

protected:
    std::streamsize xsputn(const char* s, std::streamsize n) override
    {
        if (pos_ == owned_.size()) {
            owned_.insert(owned_.end(), s, s + n);
        } else {
            // (a patch: within the held bytes, before the next reference)
            size_t limit = owned_.size();
            for (const Ref& r : refs_)
                if (r.at > pos_) {
                    limit = r.at;
                    break;
                }
            if (pos_ + size_t(n) > limit)
                throw std::logic_error("PiecesBuf: a patch past the bytes it holds there");
            std::memcpy(owned_.data() + pos_, s, size_t(n));
        }
        pos_ += size_t(n);
        return n;
    }
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override
    {
        const off_type base = dir == std::ios_base::beg   ? 0
                              : dir == std::ios_base::cur ? off_type(logical(pos_))
                                                          : off_type(size());
        const off_type to = base + off;
        if (to < 0 || uint64_t(to) > size())
            return pos_type(off_type(-1));
        // The held byte at logical offset `to` (not inside a reference).
        uint64_t before = 0;  // referenced bytes before it
        for (const Ref& r : refs_) {
            const uint64_t start = r.at + before;
            if (uint64_t(to) < start)
                break;
            if (uint64_t(to) < start + r.n)
                return pos_type(off_type(-1));
            before += r.n;
        }
        pos_ = size_t(uint64_t(to) - before);
        return pos_type(to);
    }

private:
    /// The logical offset of held byte `at`: the references before it counted.
    uint64_t logical(size_t at) const
    {
        uint64_t n = at;
        for (const Ref& r : refs_)
            if (r.at <= at)
                n += r.n;
        return n;
    }
    struct Ref {
        size_t at;  ///< the held bytes' offset it comes before
        const char* p;
        size_t n;
    };
    std::vector<char> owned_;
    std::vector<Ref> refs_;
    uint64_t refBytes_ = 0;
    size_t pos_ = 0;
};

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
                std::vector<std::string_view> leafBytes;  // (in the tree's order)
                leafBytes.reserve(leaves);
                if (leaves) {
                    delayed.resizeMask(leaves);
                    if (sizes)
                        delayed.resizeCompressedSize(leaves);
                    uint32_t i = 0;
                    for (auto it = tree.cbeginLeaf(); it; ++it, ++i) {
                        const std::string_view b = leafBytes.emplace_back(bytesOf(*it, i));
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
                // (by reference where the archive is laid out to be written
                // later: the packed leaves outlive it)
                auto* pieces = dynamic_cast<PiecesBuf*>(os.rdbuf());
                for (const std::string_view b : leafBytes) {
                    if (pieces)
                        pieces->reference(b.data(), b.size());
                    else
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

    /// A packed leaf's inactive-value code and where its compressed values
    /// begin (io/leaf_layout.h).
    template <class ValueT, class MaskT>
    static std::pair<int8_t, size_t> packedLeafLayout(std::string_view b, const MaskT& mask)
    {
        const LeafHeader h = readLeafHeader<ValueT>(b.data(), b.size(), mask);
        if (h.fault == LeafHeader::Fault::MaskDiffers)
            throw std::logic_error("writePacked: a leaf whose packed bytes are not its own");
        if (h.fault != LeafHeader::Fault::None || h.length > b.size())
            throw std::logic_error("writePacked: a packed leaf shorter than its header");
        return {h.code, h.length};
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

/// Where the checksum's value goes in a file written from prepareVdb's
/// grids, from its first bytes (`head`, 64 kB or less: the entry is in the
/// file metadata, before any grid); the checksum covers the bytes after it.
uint64_t checksumPlace(std::string_view head)
{
    // (its key, its type and its length: the 16 digits follow, the
    // placeholder's or a digest)
    const std::string entry =
        std::string(kChecksumKey) + std::string("\x06\0\0\0string\x10\0\0\0", 14);
    head = head.substr(0, size_t(1) << 16);
    const size_t at = head.find(entry);
    if (at == std::string_view::npos || head.size() < at + entry.size() + sizeof kPlaceholder - 1)
        throw std::runtime_error("the checksum's place was not found in the file OpenVDB wrote");
    return uint64_t(at) + entry.size();
}

/// The checksum's digest of the bytes after its place `value`, the file
/// given as its pieces in order (`forEach(f)` calls f(data, n) on each).
template <class ForEach>
std::string checksumAfter(uint64_t value, const ForEach& forEach)
{
    Checksum64 sum;
    const uint64_t from = value + sizeof kPlaceholder - 1;
    uint64_t at = 0;
    forEach([&](const char* p, size_t n) {
        const uint64_t skip = std::min<uint64_t>(n, from > at ? from - at : 0);
        sum.update(p + skip, n - size_t(skip));
        at += n;
    });
    return fmt::format("{:016x}", sum.value());
}

/// A file in memory signed: its checksum computed and written in its place
/// (std::runtime_error where it has none).
void signBytes(char* data, size_t size)
{
    const uint64_t value = checksumPlace({data, size});
    const std::string digest = checksumAfter(value, [&](const auto& f) { f(data, size); });
    std::memcpy(data + value, digest.data(), digest.size());
}

}  // namespace

void writeVdb(const LevelSetGrids& grids, const std::string& path, const VdbFileInfo& info)
{
    // The archive laid out in memory, its leaves by reference (no copy of
    // them), then written to the checked writer's temporary while another
    // thread sums it, and the checksum patched in (the sum, a chain of
    // dependent multiplications, took as long as the writing after it).
    const PreparedVdb v = prepareVdb(grids, info, true);
    PiecesBuf pieces;
    uint64_t value = 0;
    std::vector<std::string_view> all;
    // (declared last: joined before the pieces it sums go, whatever happens)
    std::future<std::string> digest;
    writeFile(
        path,
        [&](std::ostream&) {
            {
                std::ostream os(&pieces);
                os.exceptions(std::ios::badbit | std::ios::failbit);  // (a failed seek too)
                writeArchive(os, v);
            }
            value = checksumPlace(pieces.head());
            digest = std::async(std::launch::async, [&] {
                return checksumAfter(value, [&](const auto& f) { pieces.forEach(f); });
            });
            pieces.forEach([&](const char* p, size_t n) { all.emplace_back(p, n); });
        },
        [&](WrittenFile& f) {
            f.write(0, all);
            const std::string d = digest.get();
            f.write(value, d.data(), d.size());
        });
}

std::vector<char> encodeVdb(const LevelSetGrids& grids, const VdbFileInfo& info, bool parallel)
{
    const PreparedVdb v = prepareVdb(grids, info, parallel);
    MemoryBuf memory;
    {
        std::ostream os(&memory);
        os.exceptions(std::ios::badbit);  // (see Block::Impl)
        writeArchive(os, v);
    }
    std::vector<char> bytes = std::move(memory.data());
    signBytes(bytes.data(), bytes.size());
    return bytes;
}

bool signVdbAgain(std::string& bytes)
{
    try {
        signBytes(bytes.data(), bytes.size());
    } catch (const std::runtime_error&) {
        return false;
    }
    return true;
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
        // A stream swallows its buffer's exceptions and sets badbit: short
        // of memory, leaves were packed cut short, and a tile merge ended in
        // "a packed leaf shorter than its header" instead of out of memory.
        os.exceptions(std::ios::badbit);
    }
    template <class LeafT>
    void add(uint32_t slot, const LeafT& leaf)
    {
        using ValueT = typename LeafT::ValueType;
        starts.emplace_back(slot, buf.data().size());
        if (!encodesLeafValues(owner.compression_, owner.half_)) {
            leaf.writeBuffers(os, owner.half_);
            return;
        }
        // (OpenVDB's bytes, without its stream and allocations: leaf_values.h)
        auto& values = std::get<std::vector<ValueT>>(scratch);
        encodeLeafValues(leaf.getValueMask(), leaf.buffer().data(),
                         *static_cast<const ValueT*>(owner.background_.get()), owner.compression_,
                         bytes, values);
        os.write(bytes.data(), std::streamsize(bytes.size()));
    }
    PackedLeaves& owner;
    MemoryBuf buf;
    std::ostream os;
    std::vector<std::pair<uint32_t, size_t>> starts;
    std::vector<char> bytes;  // (a leaf's, encoded)
    std::tuple<std::vector<float>, std::vector<openvdb::Vec3f>> scratch;
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
        // (Not cleared first, as make_unique would: the copy overwrites it.)
        std::unique_ptr<char[]> chunk(new char[n]);
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

}  // namespace cambium
