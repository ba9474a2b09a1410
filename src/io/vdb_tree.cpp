// cambium — a grid's tree walked as OpenVDB 10 reads it, before OpenVDB
// does: every node's masks and every block of values the size its values
// can have (plain reads of the file; the layout from io/leaf_layout.h).
#include "io/vdb_header.h"

#include "core/error.h"
#include "io/leaf_layout.h"
#include "io/read_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <limits>
#include <optional>
#include <vector>

namespace cambium {

namespace {

/// Bytes [at, end) of a file through a window a few megabytes wide.
class Window {
public:
    Window(const std::string& path, uint64_t at, uint64_t end) : file_(path), at_(at), end_(end) {}

    uint64_t at() const { return at_; }
    uint64_t end() const { return end_; }
    /// The bytes from at(), at least min(n, end() - at()) of them in
    /// `available`.
    const char* bytes(size_t n, size_t& available)
    {
        const uint64_t want = std::min<uint64_t>(n, end_ - at_);
        if (at_ < start_ || at_ + want > start_ + buffer_.size()) {
            const size_t size = size_t(std::min<uint64_t>(std::max(n, kWidth), end_ - at_));
            buffer_.resize(size);
            file_.read(at_, buffer_.data(), size);
            start_ = at_;
        }
        available = size_t(start_ + buffer_.size() - at_);
        return buffer_.data() + (at_ - start_);
    }
    void advance(uint64_t n) { at_ += n; }

private:
    static constexpr size_t kWidth = size_t(4) << 20;
    ReadFile file_;
    uint64_t at_, end_, start_ = 0;
    std::vector<char> buffer_;
};

struct TreeWalk {
    const std::string& path;
    const VdbSummary::Grid& g;
    std::optional<Window> window;
    StoredValues stored;
    size_t leaves = 0;
    TreeLayout* layout = nullptr;

    TreeWalk(const std::string& p, const VdbSummary::Grid& grid, uint64_t end) : path(p), g(grid)
    {
        window.emplace(p, uint64_t(grid.tree), end);
        stored.compression = g.compression;
        stored.half = g.half() && g.reals > 0;
        stored.storedBytes = stored.half ? 2 * g.reals : g.valueBytes;
    }

    [[noreturn]] void damaged(const std::string& why) const
    {
        throw InputError(
            fmt::format("{}: a damaged .vdb file: grid '{}': {}", path, printable(g.name), why));
    }

    /// `n` bytes at the window's position, or damage: `what` runs past `where`.
    const char* take(size_t n, const char* what, const char* where)
    {
        size_t available;
        const char* p = window->bytes(n, available);
        if (available < n)
            damaged(fmt::format("{} at byte {} runs past {}", what, window->at(), where));
        window->advance(n);
        return p;
    }

    /// A node's values after its masks: the code, inactive values, selection
    /// mask and the block of its values; `mask` its value mask of `words`
    /// words (64 values each).
    void values(const uint64_t* mask, size_t words, const char* node, const char* where)
    {
        const size_t count = words * 64, maskBytes = words * 8;
        const uint64_t at = window->at();
        // (the code, inactive values and selection mask, then a block's size
        // and a blosc header: what is read of it)
        const size_t header = 1 + 2 * g.valueBytes + maskBytes + 8 + 16;
        size_t available;
        const char* p = window->bytes(header, available);
        if (available < 1)
            damaged(fmt::format("{} at byte {} runs past {}", node, at, where));
        const int8_t code = int8_t(p[0]);
        const size_t rest = valuesHeaderBytes(code, g.valueBytes, maskBytes);
        if (rest == std::numeric_limits<size_t>::max())
            damaged(fmt::format("{} at byte {} has an unknown inactive-value code {}", node, at,
                                int(code)));
        if (available < 1 + rest)
            damaged(fmt::format("{} at byte {} runs past {}", node, at, where));
        namespace io = openvdb::io;
        uint64_t active = 0;
        for (size_t w = 0; w < words; ++w)
            active += uint64_t(__builtin_popcountll(mask[w]));
        const bool maskCompressed = g.compression & io::COMPRESS_ACTIVE_MASK;
        const uint64_t n = maskCompressed && code != io::NO_MASK_AND_ALL_VALS ? active : count;
        size_t length;
        switch (valuesBlock(p + 1 + rest, available - 1 - rest, stored, n, length)) {
            case BlockFault::None:
                break;
            case BlockFault::Short:
                // (a block longer than the window, within what is left)
                if (length == 0 || length > window->end() - at - 1 - rest)
                    damaged(fmt::format("{} at byte {} runs past {}", node, at, where));
                break;
            case BlockFault::Size:
                damaged(
                    fmt::format("{} at byte {} stores {} values in a block whose size cannot be "
                                "theirs",
                                node, at, n));
        }
        window->advance(1 + rest + length);
    }

    /// A mask of `words` words at the window, copied.
    void mask(std::vector<uint64_t>& out, size_t words, const char* what, const char* where)
    {
        out.resize(words);
        std::memcpy(out.data(), take(words * 8, what, where), words * 8);
    }

    void node(int log2, const char* where)
    {
        const size_t words = (size_t(1) << (3 * log2)) / 64;
        const char* name = log2 == 5 ? "an internal node of 32^3" : "an internal node of 16^3";
        std::vector<uint64_t> children, active;
        mask(children, words, name, where);
        mask(active, words, name, where);
        values(active.data(), words, name, where);
        for (size_t w = 0; w < words; ++w)
            for (uint64_t bits = children[w]; bits; bits &= bits - 1) {
                if (log2 == 4) {
                    take(64, "a leaf's value mask", where);
                    ++leaves;
                } else {
                    node(log2 - 1, where);
                }
            }
    }

    void topology()
    {
        const char* where = "the grid's topology";
        take(4 + g.valueBytes, "the tree's header", where);  // buffer count, background
        uint32_t counts[2];
        std::memcpy(counts, take(8, "the root's counts", where), 8);
        for (uint32_t t = 0; t < counts[0]; ++t)
            take(12 + g.valueBytes + 1, "a root tile", where);
        // OpenVDB keeps the root's children in a map by origin and reads
        // their values in its order: in a file it wrote they come in it.
        if (layout)
            layout->rootTiles = counts[0];
        std::array<int32_t, 3> last{};
        for (uint32_t c = 0; c < counts[1]; ++c) {
            std::array<int32_t, 3> origin;
            std::memcpy(origin.data(), take(12, "a root child's origin", where), 12);
            if (c > 0 && !(last < origin))
                damaged(
                    fmt::format("the root's child at byte {} (origin {}, {}, {}) is out of "
                                "order or a duplicate",
                                window->at() - 12, origin[0], origin[1], origin[2]));
            last = origin;
            const int64_t begin = int64_t(window->at());
            node(5, where);
            if (layout)
                layout->children.push_back(
                    {{origin[0], origin[1], origin[2]}, begin, int64_t(window->at())});
        }
        if (g.leaves >= 0 && uint64_t(g.leaves) != leaves)
            damaged(fmt::format("its topology has {} leaves and its delayed-load metadata {}",
                                leaves, g.leaves));
    }

    /// The leaves' values, from the grid's block offset: each leaf's value
    /// mask and its values (OpenVDB's whole read takes the mask here, not
    /// the topology's, to count them).
    void buffers()
    {
        window.emplace(path, uint64_t(g.block), uint64_t(g.end));
        const char* where = "the end of the grid";
        uint64_t mask[8];
        for (size_t i = 0; i < leaves; ++i) {
            std::memcpy(mask, take(64, "a leaf's value mask", where), 64);
            values(mask, 8, "a leaf's values", where);
        }
    }
};

}  // namespace

size_t checkTreeStructure(const std::string& path, const VdbSummary::Grid& g, bool buffers,
                          TreeLayout* layout)
{
    if (g.tree == 0)
        return 0;
    TreeWalk walk(path, g, uint64_t(g.block));
    walk.layout = layout;
    walk.topology();
    if (buffers)
        walk.buffers();
    return walk.leaves;
}

}  // namespace cambium
