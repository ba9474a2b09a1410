// cambium — what a .vdb file says of itself without OpenVDB: the metadata
// cambium writes into its files, and the structure check every reader runs
// first.  No OpenVDB here: the commands that plan, check and resume include
// this alone (io/vdb.h holds the grids' writer and readers).
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace cambium {

/// The file metadata holding a Checksum64 of every byte after it.
inline constexpr const char* kChecksumKey = "cambium_checksum";

/// What cambium writes into a file's metadata besides its grids.
struct VdbFileInfo {
    std::string scene;  ///< the source the grids were baked from
    double threshold = 0.5;
    double halfWidth = 3.0;
    long long frame = 0;  ///< growth frame number (0 for a single bake)
    double time = 0.0;    ///< model time of the frame
    bool half = false;    ///< store floats as 16-bit halves
    std::string
        sequence;  ///< a sequence's key (file metadata `cambium_sequence`), empty for a single bake
    /// Which of the sequence's or farm's files it is (file metadata
    /// `cambium_part`: framePart, tilePart), empty for a single bake: a file
    /// copied over another of the same sequence is told by it.
    std::string part;
};

/// `cambium_part` of a sequence's frame: "frame 12".
std::string framePart(long long frame);
/// `cambium_part` of tile `k` (from 0) of `count`: "tile 3/8".
std::string tilePart(int k, int count);

/// What tells one state of a file's bytes from another while a command
/// runs: a file replaced is another inode, a file written has another
/// modification and change time (the change time no user can set back).
struct FileIdentity {
    uint64_t device = 0, inode = 0;               ///< (inode 0: none)
    int64_t size = 0, modified = 0, changed = 0;  ///< (times in nanoseconds)
    bool operator==(const FileIdentity& o) const
    {
        return device == o.device && inode == o.inode && size == o.size && modified == o.modified &&
               changed == o.changed;
    }
};

/// What the structure of a .vdb file says, read without reading any grid.
struct VdbSummary {
    uint64_t bytes = 0;  ///< file size
    uint32_t fileVersion = 0;
    std::map<std::string, std::string> strings;  ///< the file's string metadata
    uint64_t checksumEnd = 0;  ///< where the bytes `cambium_checksum` covers begin (0: none)
    struct Grid {
        std::string name, type;
        std::string instanceOf;      ///< the grid whose tree this one shares (empty: none)
        int64_t begin = 0, end = 0;  ///< byte range in the file
        int64_t block = 0;           ///< where its leaves' values begin
        /// Leaves, from OpenVDB's delayed-load metadata (-1 where the grid
        /// has none: files written without compression or before OpenVDB 6).
        int64_t leaves = -1;
        uint32_t compression = 0;  ///< its openvdb::io::COMPRESS_* flags
        /// Where its tree begins (0: a tree of a type checkTreeStructure
        /// does not walk, or an instance), a value's bytes and how many
        /// real numbers it holds (0: integers, never stored as halves).
        int64_t tree = 0;
        uint32_t valueBytes = 0, reals = 0;
        /// Whether its floats are stored as halves (the type's _HalfFloat).
        bool half() const;
    };
    std::vector<Grid> grids;
    /// The file as it was when verifyVdbChecksum found its checksum held
    /// (inode 0: never, or written within two seconds of that, when a second
    /// write in the same tick of a coarse clock would look the same): while
    /// the file opened is still so, verifying it again reads nothing (a
    /// render verified its 214 MB frame three times, once for each read).
    mutable FileIdentity verified;
};

/// Checks that `path` is a whole .vdb file with grid offsets, in a few reads
/// and bounded memory whatever the file holds: header, file metadata, every
/// grid descriptor, and each grid's end within the file.  InputError naming
/// the file and the first problem (not a regular file, not a .vdb, truncated,
/// damaged) in one line.
VdbSummary inspectVdb(const std::string& path);

/// Walks grid `g`'s tree in `path` (inspectVdb's summary) as OpenVDB reads
/// it, before OpenVDB does: the root's children in order, every internal
/// node's masks and values, every leaf's value mask, and with `buffers` every
/// leaf's values after the topology; each node's block of values the size
/// its values can have.  OpenVDB reads the size a block claims into a buffer
/// of the values it expects before it compares the two: a byte changed in
/// another tool's file overflowed the heap.  InputError naming the file,
/// the grid and the first fault, and where it lies.  Returns the leaves it
/// found.  Trees of other value types (bool, masks, points) are not walked.
/// `layout` (when set): where the root's parts lie, for a reader of the
/// topology a child at a time.
struct TreeLayout {
    uint32_t rootTiles = 0;
    struct Child {
        int32_t origin[3];
        int64_t begin, end;  ///< its masks, values and descendants' topology
    };
    std::vector<Child> children;  ///< in the file's order
};
size_t checkTreeStructure(const std::string& path, const VdbSummary::Grid& g, bool buffers,
                          TreeLayout* layout = nullptr);

/// Checks the `cambium_checksum` a file written by cambium carries (inspectVdb
/// first) by reading the bytes it covers; InputError when they changed.
/// Returns false for a file without one (written by other software).  Where
/// it held, `summary.verified` records the file, and a file unchanged since
/// (the file opened: its identity from the descriptor) is not read again.
bool verifyVdbChecksum(const std::string& path, const VdbSummary& summary);

/// verifyVdbChecksum, and a file with cambium's metadata but no checksum
/// refused too (missingChecksum: a cambium file whose checksum key was
/// damaged was decoded as another tool's, unchecked).  Another tool's file
/// passes.
void requireVdbChecksum(const std::string& path, const VdbSummary& summary);

/// The message for a file with cambium's metadata (its creator, a
/// `cambium_` key) but no `cambium_checksum`, which cambium writes with the
/// rest: edited or damaged, not another tool's.  Empty for any other file.
std::string missingChecksum(const std::string& path, const VdbSummary& summary);

/// Whether `path` begins with OpenVDB's magic number (a .vdb file whatever
/// its name); false for a file that cannot be read.
bool looksLikeVdbFile(const std::string& path);

/// What a sequence's or farm's file says it is: its key (`cambium_sequence`)
/// and part (`cambium_part`; empty in files written before it).
struct FileStamp {
    std::string key, part;
};
/// The stamp of a .vdb (inspectVdb); InputError when the file is damaged:
/// its structure, and with `verify` every byte against cambium's checksum
/// (a frame with one byte changed passed `--resume` and a farm's status as
/// written, and was kept through every retry, sweep 20).
FileStamp readFileStamp(const std::string& path, bool verify = false);

/// What `cambium info FILE.vdb` says of a file: its structure (inspectVdb)
/// and each grid's metadata and transform as OpenVDB reads them, without
/// its tree (a second or less for any size).
struct VdbGridDescription {
    std::string name, valueType, gridClass;
    std::string compression;  ///< file_compression ("" when the writer gave none)
    bool half = false;        ///< stored as halves
    glm::dvec3 voxelSize{0.0};
    bool bounded = false;                     ///< the statistics give bounds
    glm::ivec3 indexMin{0}, indexMax{0};      ///< active voxels' (inclusive)
    glm::dvec3 worldMin{0.0}, worldMax{0.0};  ///< their voxel centres' in world space
    int64_t activeVoxels = -1, leaves = -1, memoryBytes = -1;  ///< -1: not recorded
    int64_t fileBytes = 0;
    /// Every other metadata entry as text, by name (cambium_* among them).
    std::map<std::string, std::string> metadata;
};
struct VdbDescription {
    VdbSummary summary;
    std::vector<VdbGridDescription> grids;
};
/// InputError naming the file when it is not a whole .vdb.
VdbDescription describeVdb(const std::string& path);

}  // namespace cambium
