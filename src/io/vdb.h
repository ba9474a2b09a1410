// cambium — .vdb files: writing baked grids that other software opens and
// reading level sets back (the structure check every reader runs first, and
// the metadata, are io/vdb_header.h).
#pragma once

#include "io/grids.h"
#include "io/vdb_header.h"

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

namespace cambium {

/// Writes the grids (surface, Cd, density if present) with grid statistics
/// metadata and cambium's own metadata, Blosc-compressed, through the checked
/// writer (core/files.h): the file appears whole or not at all.  The file
/// metadata `cambium_checksum` (16 hex digits) is a Checksum64 of every byte
/// after it, so that readers find a file changed after writing before
/// OpenVDB decodes it.  WriteError when writing fails (a full disk),
/// InputError for a path that cannot be an output.
void writeVdb(const LevelSetGrids& grids, const std::string& path, const VdbFileInfo& info);

/// The bytes writeVdb writes.  `parallel`: the grids' leaves compressed on
/// all cores (the bytes are those OpenVDB's serial writer makes, apart from
/// the header's random UUID; false: OpenVDB's own writer, for the tests;
/// packed grids are always written from their bytes).
std::vector<char> encodeVdb(const LevelSetGrids& grids, const VdbFileInfo& info,
                            bool parallel = true);

/// A .vdb's bytes signed again: its `cambium_checksum` recomputed over the
/// bytes after it, as the writer computes it (false where it has none).
/// For the tests and the fuzzer, which damage a file past its checksum so
/// that the readers behind it see the damage.
bool signVdbAgain(std::string& bytes);

/// A grid's leaf buffers serialised as writeVdb writes them (each leaf's value
/// mask, then its compressed values), made while a bake runs so that the grid
/// never holds all its values at once: the grid keeps each leaf's value mask
/// only (a leaf without a buffer) and names its slot here in the leaf's
/// transient data.  writeVdb writes such a grid (LevelSetGrids::surfacePacked,
/// colorPacked) from these bytes: the file is byte for byte the one its
/// values would have given (tests/test_bake.cpp).
class PackedLeaves {
public:
    /// For the leaves of `grid` (a FloatGrid or a Vec3fGrid: its background
    /// and class decide the compression, as the writer's would), stored as
    /// halves or not; `slots` slots.
    PackedLeaves(const openvdb::GridBase& grid, bool half, size_t slots);
    ~PackedLeaves();
    PackedLeaves(const PackedLeaves&) = delete;
    PackedLeaves& operator=(const PackedLeaves&) = delete;

    /// Leaves serialised one after another by one thread into one buffer,
    /// then kept together.
    class Block {
    public:
        explicit Block(PackedLeaves& owner);
        ~Block();
        void add(uint32_t slot, const openvdb::FloatTree::LeafNodeType& leaf);
        void add(uint32_t slot, const openvdb::Vec3fTree::LeafNodeType& leaf);
        /// The bytes into the owner (thread-safe); empty again.
        void keep();

    private:
        struct Impl;
        std::unique_ptr<Impl> impl_;
    };

    bool half() const { return half_; }
    /// `n` more slots: the first's index (thread-safe).
    size_t addSlots(size_t n);
    /// A slot's bytes (empty where nothing was packed).
    std::string_view bytes(uint32_t slot) const;
    /// Every slot's, in all.
    size_t size() const { return total_; }

private:
    struct Slot {
        const char* data = nullptr;
        uint32_t size = 0;
    };
    bool half_;
    uint32_t compression_;
    std::shared_ptr<void> background_;  // the value the writer's mask compression compares with
    std::vector<Slot> slots_;
    std::vector<std::unique_ptr<char[]>> chunks_;
    std::mutex mutex_;
    size_t total_ = 0;
};

/// How much of a file's colour grid `Cd` a reader loads.
enum class ColourRead {
    None,   ///< none
    Whole,  ///< every leaf, now
    /// Its topology, each leaf's values left in the file for decodeLeaves
    /// (no leaf of it may be touched before: it holds no values, or, in a
    /// tree with tiles at its root, which OpenVDB reads, OpenVDB's delayed
    /// loading would read them unchecked).
    Lazy,
};

/// Reads grid `grid` (a float level set) and `Cd` from a .vdb file
/// (inspectVdb first; verifyVdbChecksum beside OpenVDB's read of the
/// topology, and done before any leaf is decoded: a damaged file is named by
/// its checksum), each grid by readVdbGrid: its leaves decoded on all cores.  InputError for an
/// unreadable or damaged file, a missing grid (the message lists the file's grids) or one that is
/// not a float level set.  `density` is not read.  `checked`: a summary of
/// the file from an earlier check (a command checks every frame before the
/// first is read): the file's structure and grids are checked again, its
/// checksum only where the file changed since (verifyVdbChecksum); it is
/// left the file's summary as read, for readColourGrid.
LevelSetGrids readLevelSet(const std::string& path, const std::string& grid = kSurfaceGrid,
                           ColourRead colour = ColourRead::Whole, VdbSummary* checked = nullptr);

/// What readLevelSet checks before OpenVDB reads a byte of the trees: the
/// file's structure, that it holds one grid `grid` of a float tree (and a
/// vec3s tree for `Cd`), cambium's checksum, and (unless `tile`) that it is
/// a whole frame, not one tile of a tiled bake.  InputError naming the file;
/// its summary.  What mesh and render check of every frame before the first.
VdbSummary checkLevelSetFile(const std::string& path, const std::string& grid = kSurfaceGrid,
                             bool tile = false, const FileIdentity& verified = {});

/// The `Cd` grid of a file readLevelSet has read (null when it has none),
/// with the values of the leaves at `leaves` (sorted origins; null: all): a
/// render's colour, read once its level set is gone, for the leaves its
/// hits look up.  Only those leaves may be touched.  InputError unless its
/// transform is `surface`'s (as readLevelSet checks; `surface` may be an
/// empty grid of the same transform and name).  `checked`: readLevelSet's
/// summary of the file: its checksum not verified again while the file has
/// not changed since.
openvdb::Vec3fGrid::Ptr readColourGrid(const std::string& path, const openvdb::FloatGrid& surface,
                                       const std::vector<openvdb::Coord>* leaves,
                                       const VdbSummary* checked = nullptr);

/// One grid of a .vdb file (inspectVdb's `summary` of it; its checksum
/// checked by the caller), equal voxel for voxel to what OpenVDB's io::File
/// reads: its tree's structure checked first (checkTreeStructure), then
/// metadata and transform by OpenVDB, its topology by OpenVDB's node reader
/// (each of the root's children from its bytes on a core of its own; a tree
/// with root tiles by io::File), then the leaves' values read
/// from the file a few megabytes at a time and decoded on all cores
/// (OpenVDB's own decoder, io::readCompressedValues, on blocks checked to be
/// the size of their values).  Float and Vec3f grids of cambium's files;
/// other types, instanced grids and other tools' files through io::File,
/// whole.  `lazy`: the topology only, each leaf's values left in the file
/// for decodeLeaves (a grid read whole has them all).  InputError naming the
/// file for damage.
openvdb::GridBase::Ptr readVdbGrid(const std::string& path, const VdbSummary& summary,
                                   const std::string& grid, bool lazy = false);

/// The leaves of `grid` (read by readVdbGrid with `lazy` from `path`) that
/// `want` selects (all when empty), decoded on all cores, each handed to
/// `visit` (when set; on any thread, with its index in the tree's order)
/// once its values are in: the caller may drop them then.  A leaf not
/// decoded must not be touched.  InputError naming the file and the leaf
/// for one that cannot be decoded (the others are left as they were).
void decodeLeaves(const std::string& path, const VdbSummary& summary, openvdb::FloatGrid& grid,
                  const std::function<bool(const openvdb::Coord&)>& want,
                  const std::function<void(size_t, openvdb::FloatTree::LeafNodeType&)>& visit);
void decodeLeaves(const std::string& path, const VdbSummary& summary, openvdb::Vec3fGrid& grid,
                  const std::function<bool(const openvdb::Coord&)>& want,
                  const std::function<void(size_t, openvdb::Vec3fTree::LeafNodeType&)>& visit);

/// readLevelSet's grids with their topology only (`surface`, and `Cd` as
/// `colour` says, as ColourRead::Lazy leaves it) and the file's summary, for
/// decodeLeaves or LazyLeaves: a reader going a few leaves at a time and
/// dropping their values after holds about those leaves' values (the file
/// must stay as it is while the grids live).  `tile`: the file may be one
/// tile of a tiled bake.  The zero crossing of a level set whose leaves are
/// left in the file is not checked here: LazyLeaves::checkZeroCrossing.
LevelSetGrids readLevelSetDelayed(const std::string& path, VdbSummary& summary,
                                  const std::string& grid = kSurfaceGrid,
                                  ColourRead colour = ColourRead::Lazy, bool tile = true);

/// A leaf's values given back (or OpenVDB's record for reading them later,
/// unread): it keeps its value mask, and holds no values until they are put
/// in again (LeafNode::getValue reads zero; an accessor caches the leaf's
/// buffer, and reads nothing or, through a tree it may change, values
/// allocated unset: such a leaf must not be looked up).
template <class LeafT>
void dropLeafValues(LeafT& leaf)
{
    typename LeafT::Buffer none(openvdb::PartialCreate(),
                                openvdb::zeroVal<typename LeafT::ValueType>());
    leaf.buffer().swap(none);
}

/// The leaves of a level set read with its topology only
/// (readLevelSetDelayed), decoded a selection at a time on all cores and
/// dropped again, so that a reader holds only the leaves it works on.  The
/// first decode reads the grid's block through and finds where each leaf
/// lies; later ones read only the picked leaves' bytes.  Every leaf is
/// empty after construction (any record of OpenVDB's for reading it later
/// goes): a leaf not decoded holds no values (dropLeafValues), never read
/// silently from the file, and must not be looked up.  A grid
/// read whole (another tool's file) keeps its values: decode and drop leave
/// it as it is.  The file must stay as it is while this lives.
class LazyLeaves {
public:
    using Leaf = openvdb::FloatTree::LeafNodeType;
    LazyLeaves(const std::string& path, const VdbSummary& summary, openvdb::FloatGrid& grid);
    ~LazyLeaves();
    LazyLeaves(const LazyLeaves&) = delete;
    LazyLeaves& operator=(const LazyLeaves&) = delete;
    /// The grid's leaves at construction, in the tree's order.
    const std::vector<Leaf*>& leaves() const;
    /// Leaves `picked` (ascending indices into leaves()) decoded.  InputError
    /// naming the file and the leaf for one that cannot be decoded or holds
    /// a value that is not a number.
    void decode(const std::vector<size_t>& picked);
    /// Leaves `picked`'s values given back (none until decoded again).
    void drop(const std::vector<size_t>& picked);
    /// InputError unless the level set holds an active value inside the
    /// surface and one outside, as readLevelSet checks of a level set it
    /// reads (no picture or mesh without them): seen in the leaves decoded
    /// so far, else in the others, decoded a few thousand at a time and
    /// dropped again until both show (a leaf held stays held).
    void checkZeroCrossing();

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace cambium
