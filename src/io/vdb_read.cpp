// cambium — reading .vdb files on all cores: OpenVDB reads a grid's
// metadata and transform, and its node reader the topology, each of the
// root's children on a core of its own (every leaf's values left in the
// file), then the leaves' values are read from the file in blocks and
// decoded in parallel (io/leaf_values.cpp, or OpenVDB's own leaf decoder).
// OpenVDB's io::File reads a tree on one thread.
#include "io/vdb.h"

#include "core/error.h"
#include "core/math.h"
#include "core/system.h"
#include "io/leaf_layout.h"
#include "io/leaf_values.h"
#include "io/read_file.h"

#include <fmt/format.h>
#include <openvdb/io/File.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <istream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <type_traits>
#include <utility>
#include <vector>

namespace cambium {

namespace {

/// A grid layout this reader does not decode (another leaf type, an
/// unfamiliar compression): io::File reads it instead.
struct NotParallel {};

/// A read-only, seekable stream buffer over bytes in memory.
class ViewBuf : public std::streambuf {
public:
    void view(const char* data, size_t size)
    {
        char* p = const_cast<char*>(data);
        setg(p, p, p + size);
    }

protected:
    pos_type seekoff(off_type off, std::ios_base::seekdir dir, std::ios_base::openmode) override
    {
        const off_type base = dir == std::ios_base::beg   ? 0
                              : dir == std::ios_base::cur ? off_type(gptr() - eback())
                                                          : off_type(egptr() - eback());
        if (base + off < 0 || base + off > off_type(egptr() - eback()))
            return pos_type(off_type(-1));
        setg(eback(), eback() + (base + off), egptr());
        return pos_type(base + off);
    }
    pos_type seekpos(pos_type pos, std::ios_base::openmode which) override
    {
        return seekoff(off_type(pos), std::ios_base::beg, which);
    }
};

/// A value a grid read may hold: any number for a distance; a colour's
/// components numbers of magnitude at most a half float's largest, what a
/// bake paints (a foreign Cd of 1e30 made pictures of 1e30 and infinity,
/// and meshes whose colours cambium's own reader refuses, exit 0).
bool finite(float v)
{
    return std::isfinite(v);
}
bool finite(const openvdb::Vec3f& v)
{
    const float most = float(kLargestHalf);
    return std::abs(v[0]) <= most && std::abs(v[1]) <= most && std::abs(v[2]) <= most;
}
/// What is wrong with a value `finite` refuses.
std::string notFinite(float)
{
    return "whose value is not a number";
}
std::string notFinite(const openvdb::Vec3f& v)
{
    return fmt::format(
        "whose colour ({:g}, {:g}, {:g}) is not one (a colour's components are "
        "numbers of magnitude at most {:g})",
        v[0], v[1], v[2], kLargestHalf);
}

std::string coordText(const openvdb::Coord& c)
{
    return fmt::format("({}, {}, {})", c.x(), c.y(), c.z());
}

/// Whether any of `count` values is one `finite` refuses: the largest
/// magnitude among their components, found on their bits (a float's
/// magnitude orders as its bits without the sign, NaNs above infinity), so
/// that the loop runs as vectors (a leaf's 512 values tested one by one were
/// a tenth of the reader's time).
template <class ValueT>
bool anyNonFinite(const ValueT* values, size_t count)
{
    constexpr size_t n = sizeof(ValueT) / sizeof(float);
    static_assert(n * sizeof(float) == sizeof(ValueT));
    const auto* bytes = reinterpret_cast<const char*>(values);
    uint32_t most = 0;
    for (size_t k = 0; k < n * count; ++k) {
        uint32_t bits;
        std::memcpy(&bits, bytes + 4 * k, 4);
        most = std::max(most, bits & 0x7FFFFFFFu);
    }
    float m;
    std::memcpy(&m, &most, sizeof m);
    if constexpr (n == 1)
        return !finite(m);
    else
        return !finite(ValueT(m));
}

/// `first` lowered to `index` (leaves found in parallel: the first in the
/// tree's order is named).
void lowerTo(std::atomic<size_t>& first, size_t index)
{
    size_t seen = first.load();
    while (index < seen && !first.compare_exchange_weak(seen, index))
        ;
}

/// InputError naming the first voxel of `leaf` whose value is not finite.
template <class LeafT>
void nameNonFinite(const LeafT& leaf, const std::string& path, const std::string& grid)
{
    for (auto v = leaf.cbeginValueAll(); v; ++v)
        if (!finite(*v))
            throw InputError(fmt::format("{}: grid '{}' has a voxel at {} {}", path, grid,
                                         coordText(v.getCoord()), notFinite(*v)));
}

/// A stream over a grid's bytes tagged as OpenVDB's reader tags its own:
/// the file's version, the grid's compression and its background (the
/// inactive values of mask-compressed nodes).
void tagStream(std::istream& is, uint32_t fileVersion, uint32_t compression, const void* background)
{
    namespace io = openvdb::io;
    io::setVersion(is,
                   openvdb::VersionId(OPENVDB_LIBRARY_MAJOR_VERSION_NUMBER,
                                      OPENVDB_LIBRARY_MINOR_VERSION_NUMBER),
                   fileVersion);
    io::setDataCompression(is, compression);
    io::setGridBackgroundValuePtr(is, background);
}

/// Whether a grid's leaves were left in the file by its read (a lazy read
/// of cambium's file: decodeLeaves or LazyLeaves put them in), not read
/// whole (values in its leaves, or no leaves).
template <class GridT>
bool valuesInFile(const GridT& grid)
{
    const auto first = grid.tree().cbeginLeaf();
    return first && first->buffer().empty();
}

/// Decodes a grid's leaf values in parallel: the leaves are stored one after
/// another in the tree's order from the grid's block offset, each as its
/// value mask, a byte saying which inactive values and selection mask
/// follow, those, and the (compressed) active values.  Those `want` selects
/// (all when empty) are decoded, and each handed to `visit` (when set) once
/// its values are in.
template <class GridT>
class LeafDecoder {
public:
    using LeafT = typename GridT::TreeType::LeafNodeType;
    using ValueT = typename GridT::ValueType;
    using HalfT = typename openvdb::io::RealToHalf<ValueT>::HalfT;
    using MaskT = typename LeafT::NodeMaskType;
    using Want = std::function<bool(const openvdb::Coord&)>;
    using Visit = std::function<void(size_t, LeafT&)>;

    LeafDecoder(const std::string& path, const VdbSummary& file, const VdbSummary::Grid& grid,
                GridT& target)
        : path_(path),
          grid_(grid),
          fileVersion_(file.fileVersion),
          background_(target.background()),
          file_(path)
    {
        for (auto it = target.tree().beginLeaf(); it; ++it)
            leaves_.push_back(it.getLeaf());
        namespace io = openvdb::io;
        if (grid.compression &
            ~uint32_t(io::COMPRESS_ZIP | io::COMPRESS_ACTIVE_MASK | io::COMPRESS_BLOSC))
            throw NotParallel{};
        stored_.compression = grid.compression;
        stored_.half = grid.half();
        stored_.storedBytes = stored_.half ? sizeof(HalfT) : sizeof(ValueT);
        direct_ = decodesLeafValues(stored_, fileVersion_);
    }

    /// The grid's leaves, in the tree's order (as at construction).
    const std::vector<LeafT*>& leaves() const { return leaves_; }

    /// The leaves `want` selects (all when empty), each handed to `visit`.
    void decode(const Want& want, const Visit& visit)
    {
        std::vector<size_t> picked;
        picked.reserve(want ? 0 : leaves_.size());
        for (size_t i = 0; i < leaves_.size(); ++i)
            if (!want || want(leaves_[i]->origin()))
                picked.push_back(i);
        decode(picked, visit);
    }

    /// Leaves `picked` (ascending indices into leaves()) decoded on all
    /// cores, each handed to `visit` (when set) once its values are in.  The
    /// first call reads the grid's block through, finding where each leaf
    /// lies; later calls read only the picked leaves' bytes.
    void decode(const std::vector<size_t>& picked, const Visit& visit)
    {
        visit_ = visit;
        firstNonFinite_ = std::numeric_limits<size_t>::max();
        if (at_.empty())
            scan(picked);
        else
            readPicked(picked);
        if (const size_t bad = firstNonFinite_.load(); bad < leaves_.size())
            nameNonFinite(*leaves_[bad], path_, grid_.name);
    }

private:
    [[noreturn]] void damaged(size_t leaf, const std::string& why) const
    {
        throw InputError(fmt::format("{}: a damaged .vdb file: grid '{}', leaf {} of {}: {}", path_,
                                     grid_.name, leaf, leaves_.size(), why));
    }

    /// Leaf i's bytes at `p` (of `left` in the block read): their length, or
    /// 0 when they run past it.
    size_t leafBytes(size_t i, const char* p, size_t left) const
    {
        namespace io = openvdb::io;
        const MaskT& mask = leaves_[i]->getValueMask();
        const LeafHeader h = readLeafHeader<ValueT>(p, left, mask);
        if (h.fault == LeafHeader::Fault::Short || h.length > left)
            return 0;
        if (h.fault == LeafHeader::Fault::MaskDiffers)
            damaged(i, "its value mask is not the topology's");
        if (h.fault == LeafHeader::Fault::UnknownCode)
            damaged(i, "an unknown inactive-value code");
        const bool maskCompressed = stored_.compression & io::COMPRESS_ACTIVE_MASK;
        const size_t count =
            maskCompressed && h.code != io::NO_MASK_AND_ALL_VALS ? mask.countOn() : LeafT::SIZE;
        size_t length;
        switch (valuesBlock(p + h.length, left - h.length, stored_, count, length)) {
            case BlockFault::None:
                return h.length + length;
            case BlockFault::Short:
                return 0;
            case BlockFault::Size:
                damaged(i, "its compressed size does not fit its values");
        }
        return 0;
    }

    /// The block read a megabyte at a time: each piece's whole leaves found
    /// (where each lies kept, for later calls), the picked ones decoded on
    /// all cores.
    void scan(const std::vector<size_t>& pickedLeaves)
    {
        const uint64_t end = uint64_t(grid_.end);
        std::vector<char>& piece = piece_;
        piece.resize(kPiece);
        std::vector<size_t> starts, picked;
        uint64_t at = uint64_t(grid_.block);
        size_t next = 0;
        auto wanted = pickedLeaves.begin();
        std::vector<uint64_t> offsets;
        offsets.reserve(leaves_.size() + 1);
        while (next < leaves_.size()) {
            const size_t n = size_t(std::min<uint64_t>(kPiece, end - at));
            if (n == 0)
                damaged(next, "the grid ends before its leaves");
            file_.read(at, piece.data(), n);
            starts.clear();
            picked.clear();
            size_t used = 0;
            const size_t first = next;
            while (next < leaves_.size()) {
                const size_t len = leafBytes(next, piece.data() + used, n - used);
                if (len == 0)
                    break;
                if (wanted != pickedLeaves.end() && *wanted == next) {
                    picked.push_back(next - first);
                    ++wanted;
                }
                offsets.push_back(at + used);
                starts.push_back(used);
                used += len;
                ++next;
            }
            if (next == first)
                damaged(next, "it runs past the end of its grid");
            starts.push_back(used);
            tbb::parallel_for(size_t(0), picked.size(), [&](size_t j) {
                const size_t k = picked[j];
                stream().leaf(first + k, piece.data() + starts[k], starts[k + 1] - starts[k]);
            });
            at += used;
        }
        offsets.push_back(at);
        at_ = std::move(offsets);
    }

    /// The picked leaves' bytes read in pieces of up to a megabyte (a gap
    /// of unpicked leaves up to kGap read through rather than skipped by
    /// another read), each piece's leaves decoded on all cores.
    void readPicked(const std::vector<size_t>& picked)
    {
        constexpr uint64_t kGap = 64 << 10;
        size_t j = 0;
        while (j < picked.size()) {
            const uint64_t begin = at_[picked[j]];
            size_t k = j + 1;
            while (k < picked.size() && at_[picked[k] + 1] - begin <= kPiece &&
                   at_[picked[k]] - at_[picked[k - 1] + 1] <= kGap)
                ++k;
            const uint64_t bytes = at_[picked[k - 1] + 1] - begin;
            if (piece_.size() < bytes)
                piece_.resize(size_t(bytes));
            file_.read(begin, piece_.data(), size_t(bytes));
            tbb::parallel_for(j, k, [&](size_t m) {
                const size_t i = picked[m];
                stream().leaf(i, piece_.data() + (at_[i] - begin), size_t(at_[i + 1] - at_[i]));
            });
            j = k;
        }
    }

    static constexpr size_t kPiece = size_t(1) << 20;

    /// A thread's stream, tagged as OpenVDB's reader tags its own.
    struct Stream {
        explicit Stream(const LeafDecoder& d) : owner(d), is(&buf)
        {
            tagStream(is, d.fileVersion_, d.stored_.compression, &d.background_);
        }
        void leaf(size_t index, const char* bytes, size_t n)
        {
            LeafT& leaf = *owner.leaves_[index];
            typename LeafT::Buffer values(openvdb::PartialCreate(), owner.background_);
            values.allocate();
            if (owner.direct_) {
                const std::string why =
                    decodeLeafValues(bytes, n, leaf.getValueMask(), owner.stored_,
                                     owner.background_, values.data(), scratch);
                if (!why.empty())
                    owner.damaged(index, fmt::format("its values cannot be decoded ({})", why));
            } else {
                readOpenVdb(index, leaf, bytes, n, values);
            }
            const bool nonFinite = anyNonFinite(values.data(), LeafT::SIZE);
            if (nonFinite)
                lowerTo(owner.firstNonFinite_, index);
            leaf.swap(values);  // (the leaf's delayed-load record goes with `values`)
            // (a leaf named for a value that is not a number keeps its
            // values to be named by: a visitor may drop them, and the tile
            // merge wrote a NaN of a re-signed tile with exit 0, sweep 19)
            if (owner.visit_ && !nonFinite)
                owner.visit_(index, leaf);
        }
        /// The values by OpenVDB's decoder (halves, zip, older files).
        void readOpenVdb(size_t index, LeafT& leaf, const char* bytes, size_t n,
                         typename LeafT::Buffer& values)
        {
            constexpr size_t maskBytes = sizeof(typename MaskT::Word) * MaskT::WORD_COUNT;
            buf.view(bytes + maskBytes, n - maskBytes);
            is.clear();
            try {
                openvdb::io::readCompressedValues(is, values.data(), LeafT::SIZE,
                                                  leaf.getValueMask(), owner.stored_.half);
            } catch (const std::bad_alloc&) {
                throw;  // (memory ran out: not damage, sweep 24)
            } catch (const std::exception& e) {
                // (a compressed block whose sizes fit and whose bytes do not
                // unpack: blosc or zlib says so)
                owner.damaged(index, fmt::format("its values cannot be decoded ({})", e.what()));
            }
            if (!is)
                owner.damaged(index, "its values cannot be decoded");
        }
        const LeafDecoder& owner;
        ViewBuf buf;
        std::istream is;
        std::vector<ValueT> scratch;  // (the active values, decoded directly)
    };

    /// This thread's stream.
    Stream& stream()
    {
        std::unique_ptr<Stream>& s = streams_.local();
        if (!s)
            s = std::make_unique<Stream>(*this);
        return *s;
    }

    std::string path_;
    VdbSummary::Grid grid_;
    uint32_t fileVersion_;
    StoredValues stored_;
    bool direct_ = false;  ///< decodeLeafValues reads its leaves, not OpenVDB's decoder
    ValueT background_;
    ReadFile file_;
    Visit visit_;
    std::vector<LeafT*> leaves_;
    std::vector<uint64_t>
        at_;  ///< where each leaf lies in the file, and the last's end, once found
    std::vector<char> piece_;
    tbb::enumerable_thread_specific<std::unique_ptr<Stream>> streams_;
    mutable std::atomic<size_t> firstNonFinite_{std::numeric_limits<size_t>::max()};
};

/// The grid by io::File: read whole (`delayed`: its leaves on first touch).
openvdb::GridBase::Ptr readWithOpenVdb(const std::string& path, const std::string& grid,
                                       bool delayed)
{
    try {
        openvdb::io::File file(path);
        file.setCopyMaxBytes(0);  // no private copy of the file for delayed loading
        file.open(delayed);
        openvdb::GridBase::Ptr g = file.readGrid(grid);
        file.close();
        // Named as the file indexes it: a grid's own name metadata may say
        // otherwise (a Cd stored as 'grad_sphere' was named so in messages).
        g->setName(grid);
        return g;
    } catch (const std::exception& e) {
        throw InputError(fmt::format("{}: cannot read it as a .vdb file: {}", path, e.what()));
    }
}

/// Grid `g` with its metadata and transform read by OpenVDB
/// (io::File::readGridMetadata) and its tree's topology by OpenVDB's own
/// node reader, each of the root's children (`layout`, from the structure
/// walk) from its bytes on a core of its own: OpenVDB reads a tree on one
/// thread, its internal nodes' tables and leaves allocated one after
/// another.  Every leaf's values are left in the file (its buffer empty),
/// for LeafDecoder.  Null for a tree with root tiles, or of another type
/// than float or Vec3f (io::File reads those).
openvdb::GridBase::Ptr readTopology(const std::string& path, const VdbSummary& summary,
                                    const VdbSummary::Grid& g, const TreeLayout& layout)
{
    if (layout.rootTiles != 0)
        return nullptr;
    openvdb::GridBase::Ptr grid;
    try {
        openvdb::io::File file(path);
        file.setCopyMaxBytes(0);
        file.open(false);
        grid = file.readGridMetadata(g.name);
        file.close();
    } catch (const std::exception& e) {
        throw InputError(fmt::format("{}: cannot read it as a .vdb file: {}", path, e.what()));
    }
    const ReadFile f(path);
    const bool ours =
        grid->apply<openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid>>([&](auto& typed) {
            using TreeT = typename std::decay_t<decltype(typed)>::TreeType;
            using UpperT = typename TreeT::RootNodeType::ChildNodeType;
            using ValueT = typename TreeT::ValueType;
            ValueT background;
            f.read(uint64_t(g.tree) + 4, reinterpret_cast<char*>(&background), sizeof background);
            std::vector<std::unique_ptr<UpperT>> nodes(layout.children.size());
            tbb::parallel_for(size_t(0), nodes.size(), [&](size_t i) {
                const TreeLayout::Child& c = layout.children[i];
                std::vector<char> bytes(size_t(c.end - c.begin));
                f.read(uint64_t(c.begin), bytes.data(), bytes.size());
                ViewBuf buf;
                buf.view(bytes.data(), bytes.size());
                std::istream is(&buf);
                tagStream(is, summary.fileVersion, g.compression, &background);
                auto node = std::make_unique<UpperT>(
                    openvdb::PartialCreate(), openvdb::Coord(c.origin[0], c.origin[1], c.origin[2]),
                    background);
                try {
                    node->readTopology(is, g.half());
                } catch (const std::bad_alloc&) {
                    throw;
                } catch (const std::exception& e) {
                    throw InputError(fmt::format("{}: a damaged .vdb file: grid '{}': {}", path,
                                                 g.name, e.what()));
                }
                if (!is || size_t(is.tellg()) != bytes.size())
                    throw InputError(fmt::format(
                        "{}: a damaged .vdb file: grid '{}': the node at byte {} is not the "
                        "size the walk of its tree found",
                        path, g.name, c.begin));
                nodes[i] = std::move(node);
            });
            auto tree = std::make_shared<TreeT>(background);
            for (std::unique_ptr<UpperT>& node : nodes) {
                tree->root().addChild(node.get());
                node.release();  // (the root's now)
            }
            typed.setTree(tree);
        });
    if (!ours)
        return nullptr;
    grid->setName(g.name);  // (as readWithOpenVdb names it)
    return grid;
}

/// InputError where the values of `leaves` leaves of `valueBytes`-byte
/// values would not fit, with 64 MB beside them for the decompressors: Blosc
/// carries on with a null buffer where its own allocation fails (a needle's
/// 437,508 leaves read under an address-space limit crashed in LZ4 about
/// one time in three, sweep 24), so reading must not reach the limit.
void checkDecodeFits(const std::string& path, const std::string& grid, double leaves,
                     double valueBytes)
{
    checkMemoryFits(
        leaves * 512.0 * valueBytes + 64e6,
        fmt::format("{}: reading grid '{}' ({} leaves)", path, grid, formatCount(leaves)),
        "read it on a machine with more memory");
}

/// The first voxel, in the tree's order, of a float or colour grid read
/// whole whose value is not finite, named (as LeafDecoder names it); then
/// any such tile, and the background.
void checkFiniteLeaves(openvdb::GridBase& base, const std::string& path)
{
    base.apply<openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid>>([&](auto& grid) {
        using LeafT = typename std::decay_t<decltype(grid)>::TreeType::LeafNodeType;
        std::vector<const LeafT*> leaves;
        for (auto it = grid.tree().cbeginLeaf(); it; ++it)
            leaves.push_back(it.getLeaf());
        std::atomic<size_t> first{leaves.size()};
        tbb::parallel_for(size_t(0), leaves.size(), [&](size_t i) {
            if (anyNonFinite(leaves[i]->buffer().data(), LeafT::SIZE))
                lowerTo(first, i);
        });
        if (first < leaves.size())
            nameNonFinite(*leaves[first], path, grid.getName());
        // (and the tiles', and the background: a lookup between leaves
        // reads them)
        auto tile = grid.tree().cbeginValueAll();
        tile.setMaxDepth(std::decay_t<decltype(tile)>::LEAF_DEPTH - 1);
        for (; tile; ++tile)
            if (!finite(*tile))
                throw InputError(fmt::format("{}: grid '{}' has a tile at {} {}", path,
                                             grid.getName(), coordText(tile.getCoord()),
                                             notFinite(*tile)));
        if (!finite(grid.background()))
            throw InputError(fmt::format("{}: grid '{}' has a background {}", path, grid.getName(),
                                         notFinite(grid.background())));
    });
}

}  // namespace

namespace {

const VdbSummary::Grid& gridNamed(const std::string& path, const VdbSummary& summary,
                                  const std::string& name)
{
    for (const VdbSummary::Grid& g : summary.grids)
        if (g.name == name)
            return g;
    throw InputError(fmt::format("{}: no grid named '{}'", path, name));
}

}  // namespace

openvdb::GridBase::Ptr readVdbGrid(const std::string& path, const VdbSummary& summary,
                                   const std::string& name, bool lazy)
{
    const VdbSummary::Grid* grid = &gridNamed(path, summary, name);
    // Its tree (an instance's, the grid it shares) walked as OpenVDB reads
    // it, before OpenVDB reads a byte of it: its topology always (a byte of
    // another tool's file changed the size of an internal node's values,
    // and OpenVDB's reader overflowed the heap), and the leaves' values
    // where OpenVDB decodes them (another tool's file, an instance), not
    // where cambium's decoder does, which checks each block as it goes.
    const bool instance = !grid->instanceOf.empty();
    const VdbSummary::Grid& tree = instance ? gridNamed(path, summary, grid->instanceOf) : *grid;
    const bool openVdbDecodes = summary.checksumEnd == 0 || instance;
    TreeLayout layout;
    checkTreeStructure(path, tree, openVdbDecodes, &layout);
    // Another program's file is read by OpenVDB whole, in one pass: a
    // delayed read trusts the grid's delayed-load metadata (a mask byte for
    // each leaf), which nothing vouches for there (a byte changed in a
    // foreign file's topology, a leaf more than the metadata counts, aborted
    // mesh on OpenVDB's assertion `index < mMask.size()`); cambium's own
    // files carry a checksum, verified before this.
    if (openVdbDecodes) {
        if (grid->leaves >= 0 && tree.valueBytes > 0)
            checkDecodeFits(path, name, double(grid->leaves), double(tree.valueBytes));
        openvdb::GridBase::Ptr whole = readWithOpenVdb(path, name, false);
        checkFiniteLeaves(*whole, path);
        return whole;
    }
    // The topology, each leaf's values left in the file (`lazy`: for
    // decodeLeaves).
    openvdb::GridBase::Ptr g = readTopology(path, summary, *grid, layout);
    if (!g)
        g = readWithOpenVdb(path, name, true);
    if (lazy)
        return g;
    try {
        const bool ours =
            g->apply<openvdb::TypeList<openvdb::FloatGrid, openvdb::Vec3fGrid>>([&](auto& typed) {
                using ValueT = typename std::decay_t<decltype(typed)>::ValueType;
                checkDecodeFits(path, name, double(typed.tree().leafCount()), sizeof(ValueT));
                using Decoder = LeafDecoder<std::decay_t<decltype(typed)>>;
                Decoder(path, summary, *grid, typed).decode(typename Decoder::Want(), {});
            });
        if (ours)
            return g;
    } catch (const NotParallel&) {
    }
    checkTreeStructure(path, tree, true);
    openvdb::GridBase::Ptr whole = readWithOpenVdb(path, name, false);
    checkFiniteLeaves(*whole, path);
    return whole;
}

namespace {

/// `emplace(stored)` (a decoder's construction) for a grid read lazily from
/// `path`, whose compression cambium must decode.
template <class Emplace>
void makeDecoder(const std::string& path, const VdbSummary& summary, const std::string& grid,
                 const Emplace& emplace)
{
    const VdbSummary::Grid& stored = gridNamed(path, summary, grid);
    try {
        emplace(stored);
    } catch (const NotParallel&) {
        throw InputError(
            fmt::format("{}: grid '{}' has a compression cambium does not read "
                        "(flags {})",
                        path, grid, stored.compression));
    }
}

/// decodeLeaves for either grid type.
template <class GridT, class Visit>
void decodeSome(const std::string& path, const VdbSummary& summary, GridT& grid,
                const std::function<bool(const openvdb::Coord&)>& want, const Visit& visit)
{
    if (!valuesInFile(grid)) {
        // (read whole: another tool's file; each leaf visited with its index
        // in the tree's order, as the decoder visits it)
        std::vector<std::pair<size_t, typename GridT::TreeType::LeafNodeType*>> leaves;
        size_t index = 0;
        for (auto it = grid.tree().beginLeaf(); it; ++it, ++index)
            if (!want || want(it->origin()))
                leaves.emplace_back(index, it.getLeaf());
        if (visit)
            tbb::parallel_for(size_t(0), leaves.size(),
                              [&](size_t i) { visit(leaves[i].first, *leaves[i].second); });
        return;
    }
    makeDecoder(path, summary, grid.getName(), [&](const VdbSummary::Grid& stored) {
        LeafDecoder<GridT>(path, summary, stored, grid).decode(want, visit);
    });
}

}  // namespace

void decodeLeaves(const std::string& path, const VdbSummary& summary, openvdb::FloatGrid& grid,
                  const std::function<bool(const openvdb::Coord&)>& want,
                  const std::function<void(size_t, openvdb::FloatTree::LeafNodeType&)>& visit)
{
    decodeSome(path, summary, grid, want, visit);
}

void decodeLeaves(const std::string& path, const VdbSummary& summary, openvdb::Vec3fGrid& grid,
                  const std::function<bool(const openvdb::Coord&)>& want,
                  const std::function<void(size_t, openvdb::Vec3fTree::LeafNodeType&)>& visit)
{
    decodeSome(path, summary, grid, want, visit);
}

namespace {

/// A grid's transform checked usable, as OpenVDB reads it (each of a map's
/// scale, voxel size and inverse is stored, and read as it is): linear, a
/// matrix of numbers, each axis as long as the stored voxel size, and an
/// inverse that undoes it.  Its matrix.
openvdb::Mat4d checkTransform(const openvdb::GridBase& grid, const std::string& path)
{
    const openvdb::math::MapBase& map = *grid.transform().baseMap();
    if (!map.isLinear())
        throw InputError(fmt::format(
            "{}: grid '{}' has a {} transform: not a usable level set (its voxels are not cubes)",
            path, grid.getName(), map.type()));
    // (a NaN in the translation left the voxel size and determinant as they
    // were: meshed with exit 0, every vertex at -inf)
    openvdb::Mat4d m;
    try {
        m = map.getAffineMap()->getMat4();
    } catch (const openvdb::Exception& e) {
        throw InputError(
            fmt::format("{}: grid '{}' has a transform OpenVDB cannot use ({}): not "
                        "a usable level set",
                        path, grid.getName(), e.what()));
    }
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
            if (!std::isfinite(m(i, j)))
                throw InputError(fmt::format(
                    "{}: grid '{}' has a transform whose matrix holds {:g} (row {}, column {}): "
                    "not a usable level set",
                    path, grid.getName(), m(i, j), i, j));
    // The map's own voxel size is stored beside its scale, and read as it
    // is: the two must agree (a scale of 3.6e307 under a stored 0.2 passed
    // as 0.2 voxels and meshed to vertices at -inf, exit 0).
    const openvdb::Vec3d v = grid.voxelSize();
    for (int k = 0; k < 3; ++k) {
        const double axis = std::hypot(m(k, 0), m(k, 1), m(k, 2));  // (no overflow)
        if (!(std::abs(axis - v[k]) <= 1e-6 * std::max(axis, v[k])))
            throw InputError(fmt::format(
                "{}: grid '{}' has a transform whose axis {} is {:g} long and whose voxel size "
                "says {:g}: damaged, not a usable level set",
                path, grid.getName(), "xyz"[k], axis, v[k]));
    }
    // World to index goes through the stored inverse.
    for (int k = 0; k < 4; ++k) {
        const openvdb::Vec3d index(k == 1 ? 1000.0 : 0.0, k == 2 ? 1000.0 : 0.0,
                                   k == 3 ? 1000.0 : 0.0);
        const openvdb::Vec3d back = map.applyInverseMap(map.applyMap(index));
        if (!((back - index).length() <= 1e-3))
            throw InputError(fmt::format(
                "{}: grid '{}' has a transform whose stored inverse does not undo it (index x {:g} "
                "comes back as ({:g}, {:g}, {:g})): damaged, not a usable level set",
                path, grid.getName(), index.x(), back.x(), back.y(), back.z()));
    }
    return m;
}

/// The most active voxels in a level set's tiles beside its leaves' own.
constexpr double kMaxTileVoxels = double(1 << 24);

/// What OpenVDB's tools take for granted of a level set, checked when it is
/// read (else they fail unnamed, or work on garbage):
/// - cubic voxels (the intersector and volumeToMesh refuse others);
/// - a positive background, its band's half-width (a fog volume labelled a
///   level set has 0);
/// - every active tile's value a number (the leaves' values are checked
///   as they are decoded);
/// - active tiles (a few bytes in a file) that fit in memory as voxels, for
///   whatever meshes, resamples or converts the grid makes them voxels, and
///   hold no more voxels than its leaves and kMaxTileVoxels.
void checkLevelSet(const openvdb::FloatGrid& grid, const std::string& path)
{
    checkTransform(grid, path);
    const openvdb::Vec3d v = grid.voxelSize();
    // A voxel of no size, a mirrored or a sheared one, or one beyond what
    // --voxel-size allows (volumeToMesh crashed on a voxel size of 0 and
    // wrote infinities for 1e300; a mirrored grid meshed inside out).
    const double det = grid.transform().baseMap()->determinant();
    if (!(v[0] >= 1e-9 && v[0] <= 1e9) || !std::isfinite(det) || !(det > 0.0))
        throw InputError(fmt::format(
            "{}: grid '{}' has voxels of {:g} x {:g} x {:g} (the transform's determinant "
            "{:g}): not a usable level set (voxels from 1e-09 to 1e+09, not mirrored)",
            path, grid.getName(), v[0], v[1], v[2], det));
    if (!(v[0] == v[1] && v[1] == v[2]))
        throw InputError(
            fmt::format("{}: grid '{}' has voxels of {:g} x {:g} x {:g}: a level set's "
                        "are cubes",
                        path, grid.getName(), v[0], v[1], v[2]));
    if (!(grid.background() > 0.0f))
        throw InputError(fmt::format(
            "{}: grid '{}' has the background {:g}, not a level set's positive half-width "
            "(a fog volume labelled a level set?)",
            path, grid.getName(), grid.background()));
    using Tree = openvdb::FloatTree;
    double voxels = 0.0;
    auto tile = grid.tree().cbeginValueOn();
    tile.setMaxDepth(Tree::ValueOnCIter::LEAF_DEPTH - 1);  // (tiles only, not leaves' voxels)
    for (; tile; ++tile) {
        if (!std::isfinite(*tile))
            throw InputError(
                fmt::format("{}: grid '{}' has a tile at {} whose value is not a "
                            "number ({})",
                            path, grid.getName(), coordText(tile.getCoord()), *tile));
        voxels += double(tile.getVoxelCount());
    }
    // (4.5 bytes a voxel: a value and its leaf's share of masks and node)
    checkMemoryFits(voxels * 4.5,
                    fmt::format("{}: grid '{}' has {:.3g} active voxels in tiles, which as voxels",
                                path, grid.getName(), voxels),
                    "not a narrow-band level set");
    // A tile holds one value over 8^3 voxels or more, and a distance changes
    // by about a voxel a voxel: a band has few active tiles, if any.  Tiles
    // beyond the leaves' own voxels (and 2^24 voxels) are refused, bounding
    // the time and memory of whatever reads them as voxels (750 tiles of
    // 128^3 in a 1.3 MB file fitted in memory as floats, then aborted mesh,
    // shape and preview for memory, and took a shape past a minute; sweep 21).
    const double leafVoxels = double(grid.tree().activeLeafVoxelCount());
    if (voxels > std::max(leafVoxels, kMaxTileVoxels))
        throw InputError(fmt::format(
            "{}: grid '{}' has {:.3g} active voxels in tiles (one value each, over 8^3 voxels "
            "or more), more than its leaves' {:.3g} and 2^24: not a narrow-band level set",
            path, grid.getName(), voxels, leafVoxels));
    // Meshes and pictures hold positions in single precision, as the bake
    // does (a sphere 1e7 from the origin meshed with exit 0 to vertices on
    // three x values, its volume negative).
    const openvdb::CoordBBox active = grid.evalActiveVoxelBoundingBox();
    if (!active.empty()) {
        double far = 0.0;
        for (int c = 0; c < 8; ++c) {
            const openvdb::Vec3d p =
                grid.indexToWorld(openvdb::Vec3d((c & 1 ? active.max() : active.min()).x(),
                                                 (c & 2 ? active.max() : active.min()).y(),
                                                 (c & 4 ? active.max() : active.min()).z()));
            far = std::max({far, std::abs(p.x()), std::abs(p.y()), std::abs(p.z())});
        }
        checkVoxelsFromOrigin(far, v[0], fmt::format("{}: grid '{}'", path, grid.getName()));
    }
}

/// What a level set's active values show of its surface: whether one lies
/// inside (below zero) and one outside (zero or above), as volumeToMesh and
/// the ray intersector find it, and the range of those seen.
struct SidesSeen {
    bool inside = false, outside = false;
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    bool both() const { return inside && outside; }
    void see(float v)
    {
        lo = std::min(lo, v);
        hi = std::max(hi, v);
        inside = inside || v < 0.0f;
        outside = outside || v >= 0.0f;
    }
    /// The active values of a tree or a leaf, until both sides show.
    template <class NodeT>
    void seeActive(const NodeT& node)
    {
        for (auto v = node.cbeginValueOn(); v && !both(); ++v)
            see(*v);
    }
    void see(const SidesSeen& o)
    {
        inside = inside || o.inside;
        outside = outside || o.outside;
        lo = std::min(lo, o.lo);
        hi = std::max(hi, o.hi);
    }
    /// InputError where the values of `grid` were seen on one side only.
    void refuseOneSided(const openvdb::FloatGrid& grid, const std::string& path) const
    {
        if ((inside || outside) && !both())
            throw InputError(fmt::format(
                "{}: grid '{}' has {} active voxels, every one {} (values from {:g} to {:g}): no "
                "zero crossing, no surface to see",
                path, grid.getName(), grid.activeVoxelCount(), inside ? "inside" : "outside", lo,
                hi));
    }
};

/// A level set's surface: an active value inside and one outside (a
/// foreign band of only positive values meshed to nothing and drew an empty
/// picture, exit 0).  A real level set's first leaf has both.
void checkZeroCrossing(const openvdb::FloatGrid& grid, const std::string& path)
{
    SidesSeen seen;
    seen.seeActive(grid.tree());
    seen.refuseOneSided(grid, path);
}

/// A colour grid's transform: usable, and the surface's, entry for entry
/// (OpenVDB's transform comparison takes NaN for any number: a Cd whose
/// matrix was all NaN passed as the surface's and painted nothing, exit 0).
void checkColourTransform(const openvdb::Vec3fGrid& colour, const openvdb::FloatGrid& surface,
                          const std::string& path)
{
    const openvdb::Mat4d c = checkTransform(colour, path);
    const openvdb::Mat4d s = surface.transform().baseMap()->getAffineMap()->getMat4();
    const double voxel = surface.voxelSize()[0];
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j)
            if (!(std::abs(c(i, j) - s(i, j)) <= 1e-6 * voxel))
                throw InputError(fmt::format(
                    "{}: grid '{}' has another transform than grid '{}' (voxels of {:g}, not "
                    "{:g}; row {}, column {} of its matrix {:g}, not {:g}): its colours are not "
                    "at the surface's voxels",
                    path, colour.getName(), surface.getName(), colour.voxelSize()[0], voxel, i, j,
                    c(i, j), s(i, j)));
}

}  // namespace

VdbSummary checkLevelSetFile(const std::string& path, const std::string& grid, bool tile,
                             const FileIdentity& verified)
{
    // A damaged file is named here, before OpenVDB decodes it: its structure,
    // and for cambium's own files the checksum of every byte (`verified`: not
    // again while the file is as it was when it held).
    VdbSummary summary = inspectVdb(path);
    summary.verified = verified;
    // (a tile holds a run of the frame's layers and their halo: meshed,
    // rendered or captured, it made a fragment of the surface with exit 0)
    if (const auto part = summary.strings.find("cambium_part");
        !tile && part != summary.strings.end() && part->second.rfind("tile ", 0) == 0)
        throw InputError(fmt::format(
            "{}: is {} of a frame baked in tiles, a part of its surface: merge the tiles "
            "(cambium farm --finish) or bake the frame whole",
            path, printable(part->second)));
    std::string names;
    bool found = false;
    for (const VdbSummary::Grid& g : summary.grids) {
        names += (names.empty() ? "" : ", ") + printable(g.name);
        // (OpenVDB stores a second grid of a name with a suffix of its own;
        // the colours read beside the surface are one grid too)
        for (const std::string& name : {grid, std::string(kColorGrid)})
            if (g.name != name && openvdb::io::GridDescriptor::stripSuffix(g.name) == name)
                throw InputError(
                    fmt::format("{}: more than one grid is named '{}': which one is meant?", path,
                                printable(name)));
        found = found || g.name == grid;
    }
    if (!found)
        throw InputError(fmt::format("{}: no grid named '{}' (it holds: {})", path, grid,
                                     names.empty() ? "no grids" : names));
    // The checksum (one thread, 0.05 s for 200 MB in the page cache) before OpenVDB reads a
    // byte of the trees: OpenVDB's topology reader corrupts the heap on
    // damaged bytes (a byte changed in a cambium file aborted mesh and
    // render with "malloc(): corrupted top size"; beside the read, the
    // verdict came too late).
    requireVdbChecksum(path, summary);
    // The trees' types from the file's descriptors, before any is decoded
    // (a surface grid relabelled Tree_vec3s was decoded as vectors from a
    // float tree's bytes, and the tools after that spun forever).
    for (const VdbSummary::Grid& g : summary.grids) {
        const bool surface = g.name == grid, cd = g.name == kColorGrid && grid != kColorGrid;
        const char* want = surface ? "Tree_float_5_4_3" : cd ? "Tree_vec3s_5_4_3" : nullptr;
        if (want && g.type.rfind(want, 0) != 0)
            throw InputError(fmt::format("{}: grid '{}' has the tree type {}, not a {}'s {}", path,
                                         printable(g.name), printable(g.type),
                                         surface ? "float level set" : "colour grid", want));
    }
    return summary;
}

namespace {

LevelSetGrids readGrids(const std::string& path, const std::string& grid, bool lazy,
                        ColourRead colour, bool tile, VdbSummary& summary)
{
    const FileIdentity known = summary.verified;
    summary = checkLevelSetFile(path, grid, tile, known);
    bool hasColour = false;
    for (const VdbSummary::Grid& g : summary.grids)
        hasColour = hasColour || g.name == kColorGrid;
    LevelSetGrids out;
    const openvdb::GridBase::Ptr g = readVdbGrid(path, summary, grid, lazy);
    out.surface = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
    if (!out.surface || g->getGridClass() != openvdb::GRID_LEVEL_SET)
        throw InputError(fmt::format("{}: grid '{}' is a {} {}, not a float level set", path, grid,
                                     g->valueType(),
                                     openvdb::GridBase::gridClassToString(g->getGridClass())));
    checkLevelSet(*out.surface, path);
    // (a tile's part of the band may lie on one side of the surface; the
    // values of leaves left in the file are checked as LazyLeaves decodes
    // them; another tool's file is read whole, lazy or not)
    if (!tile && !valuesInFile(*out.surface))
        checkZeroCrossing(*out.surface, path);
    if (hasColour && colour != ColourRead::None && grid != kColorGrid)
        out.color = openvdb::gridPtrCast<openvdb::Vec3fGrid>(
            readVdbGrid(path, summary, kColorGrid, colour == ColourRead::Lazy));
    if (out.color)
        checkColourTransform(*out.color, *out.surface, path);
    return out;
}

}  // namespace

LevelSetGrids readLevelSet(const std::string& path, const std::string& grid, ColourRead colour,
                           VdbSummary* checked)
{
    VdbSummary own;
    return readGrids(path, grid, false, colour, /*tile=*/false, checked ? *checked : own);
}

openvdb::Vec3fGrid::Ptr readColourGrid(const std::string& path, const openvdb::FloatGrid& surface,
                                       const std::vector<openvdb::Coord>* leaves,
                                       const VdbSummary* checked)
{
    VdbSummary summary = inspectVdb(path);
    if (checked)
        summary.verified = checked->verified;
    verifyVdbChecksum(path, summary);  // (as readGrids: before OpenVDB reads)
    for (const VdbSummary::Grid& g : summary.grids)
        if (g.name == kColorGrid) {
            openvdb::Vec3fGrid::Ptr colour = openvdb::gridPtrCast<openvdb::Vec3fGrid>(
                readVdbGrid(path, summary, kColorGrid, leaves != nullptr));
            if (!colour)
                return colour;
            checkColourTransform(*colour, surface, path);
            if (leaves) {
                checkDecodeFits(path, kColorGrid, double(leaves->size()), sizeof(openvdb::Vec3f));
                decodeLeaves(path, summary, *colour,
                             [&](const openvdb::Coord& origin) {
                                 return std::binary_search(leaves->begin(), leaves->end(), origin);
                             },
                             {});
            }
            return colour;
        }
    return nullptr;
}

VdbDescription describeVdb(const std::string& path)
{
    VdbDescription d;
    d.summary = inspectVdb(path);
    // Each grid's metadata by the name the file indexes it under, in the
    // file's order (a grid's own name metadata may differ: looked up by it,
    // such a file was refused as unreadable).
    std::vector<openvdb::GridBase::Ptr> grids;
    try {
        openvdb::io::File file(path);
        file.setCopyMaxBytes(0);
        file.open(true);
        for (const VdbSummary::Grid& s : d.summary.grids)
            grids.push_back(file.readGridMetadata(s.name));
        file.close();
    } catch (const std::exception& e) {
        throw InputError(fmt::format("{}: cannot read it as a .vdb file: {}", path, e.what()));
    }
    for (size_t i = 0; i < grids.size(); ++i) {
        const VdbSummary::Grid& s = d.summary.grids[i];
        const openvdb::GridBase& g = *grids[i];
        VdbGridDescription out;
        out.name = s.name;
        out.valueType = g.valueType();
        out.gridClass = openvdb::GridBase::gridClassToString(g.getGridClass());
        out.half = s.half();
        const openvdb::Vec3d voxel = g.voxelSize();
        out.voxelSize = glm::dvec3(voxel.x(), voxel.y(), voxel.z());
        out.leaves = s.leaves;
        out.fileBytes = s.end - s.begin;
        using openvdb::GridBase;
        for (auto m = g.beginMeta(); m != g.endMeta(); ++m) {
            const std::string& key = m->first;
            if (key == GridBase::META_FILE_BBOX_MIN || key == GridBase::META_FILE_BBOX_MAX ||
                key == GridBase::META_FILE_MEM_BYTES || key == GridBase::META_FILE_VOXEL_COUNT ||
                key == GridBase::META_FILE_DELAYED_LOAD || key == GridBase::META_GRID_NAME ||
                key == GridBase::META_GRID_CLASS || key == GridBase::META_SAVE_HALF_FLOAT)
                continue;
            if (key == GridBase::META_FILE_COMPRESSION)
                out.compression = m->second->str();
            else
                out.metadata[key] = m->second->str();
        }
        if (const auto v = g.getMetadata<openvdb::Int64Metadata>(GridBase::META_FILE_VOXEL_COUNT))
            out.activeVoxels = v->value();
        if (const auto v = g.getMetadata<openvdb::Int64Metadata>(GridBase::META_FILE_MEM_BYTES))
            out.memoryBytes = v->value();
        const auto lo = g.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MIN),
                   hi = g.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MAX);
        if (lo && hi && out.activeVoxels != 0) {
            out.bounded = true;
            const openvdb::Vec3i a = lo->value(), b = hi->value();
            out.indexMin = glm::ivec3(a.x(), a.y(), a.z());
            out.indexMax = glm::ivec3(b.x(), b.y(), b.z());
            for (int c = 0; c < 8; ++c) {  // (a transform may turn the box)
                const openvdb::Vec3d w = g.indexToWorld(openvdb::Vec3d(
                    c & 1 ? b.x() : a.x(), c & 2 ? b.y() : a.y(), c & 4 ? b.z() : a.z()));
                const glm::dvec3 v(w.x(), w.y(), w.z());
                out.worldMin = c ? glm::min(out.worldMin, v) : v;
                out.worldMax = c ? glm::max(out.worldMax, v) : v;
            }
        }
        d.grids.push_back(std::move(out));
    }
    return d;
}

LevelSetGrids readLevelSetDelayed(const std::string& path, VdbSummary& summary,
                                  const std::string& grid, ColourRead colour, bool tile)
{
    return readGrids(path, grid, true, colour, tile, summary);
}

struct LazyLeaves::Impl {
    Impl(const std::string& p, openvdb::FloatGrid& g) : path(p), grid(g) {}
    std::string path;
    openvdb::FloatGrid& grid;
    std::optional<LeafDecoder<openvdb::FloatGrid>> decoder;  ///< none: the grid was read whole
    std::vector<Leaf*> whole;                                ///< the leaves of a grid read whole
    std::atomic<bool> both{false};                           ///< both sides of the surface seen
    std::mutex mutex;
    SidesSeen seen;
    std::vector<uint8_t> examined;  ///< each leaf: decoded at least once, its values seen
};

LazyLeaves::LazyLeaves(const std::string& path, const VdbSummary& summary, openvdb::FloatGrid& grid)
    : impl_(std::make_unique<Impl>(path, grid))
{
    if (!valuesInFile(grid)) {
        for (auto it = grid.tree().beginLeaf(); it; ++it)
            impl_->whole.push_back(it.getLeaf());
        return;
    }
    makeDecoder(path, summary, grid.getName(), [&](const VdbSummary::Grid& stored) {
        impl_->decoder.emplace(path, summary, stored, grid);
    });
    const std::vector<Leaf*>& leaves = impl_->decoder->leaves();
    impl_->examined.assign(leaves.size(), 0);
    tbb::parallel_for(size_t(0), leaves.size(), [&](size_t i) { dropLeafValues(*leaves[i]); });
}

LazyLeaves::~LazyLeaves() = default;

const std::vector<LazyLeaves::Leaf*>& LazyLeaves::leaves() const
{
    return impl_->decoder ? impl_->decoder->leaves() : impl_->whole;
}

void LazyLeaves::decode(const std::vector<size_t>& picked)
{
    Impl& m = *impl_;
    if (!m.decoder)
        return;
    checkDecodeFits(m.path, m.grid.getName(), double(picked.size()), sizeof(float));
    for (size_t i : picked)
        m.examined[i] = 1;
    m.decoder->decode(picked, [&m](size_t, Leaf& leaf) {
        if (m.both.load(std::memory_order_relaxed))
            return;
        SidesSeen seen;
        seen.seeActive(leaf);
        const std::lock_guard<std::mutex> lock(m.mutex);
        m.seen.see(seen);
        m.both = m.seen.both();
    });
}

void LazyLeaves::drop(const std::vector<size_t>& picked)
{
    if (!impl_->decoder)
        return;
    const std::vector<Leaf*>& leaves = impl_->decoder->leaves();
    tbb::parallel_for(size_t(0), picked.size(),
                      [&](size_t i) { dropLeafValues(*leaves[picked[i]]); });
}

void LazyLeaves::checkZeroCrossing()
{
    Impl& m = *impl_;
    if (!m.decoder)
        return;  // (read whole: readLevelSetDelayed checked it)
    // The leaves decoded so far may all lie on one side (a close view of
    // the band's outer part, or none on the picture): the others are
    // decoded a few thousand at a time in the file's order, and dropped
    // again, until both sides show (a level set's first leaves show them).
    constexpr size_t kBatch = 4096;
    const size_t n = m.examined.size();
    std::vector<size_t> batch;
    for (size_t at = 0; at < n && !m.both; at += kBatch) {
        batch.clear();
        for (size_t i = at; i < std::min(n, at + kBatch); ++i)
            if (!m.examined[i])
                batch.push_back(i);
        decode(batch);
        drop(batch);
    }
    m.seen.refuseOneSided(m.grid, m.path);
}

}  // namespace cambium
