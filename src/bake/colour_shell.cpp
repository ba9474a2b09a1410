// cambium — the colour grid where it is read: a renderer or a mesh looks Cd
// up at the surface, trilinearly, so it reads the eight corners of the cell
// the surface point lies in; a cell the surface crosses has corners on both
// sides of it.  Cd keeps those voxels (the shell), with the band's values,
// and a leaf whose shell colours lie within a step of the bake's 8-bit
// colours becomes one tile.
#include "bake/stages.h"

#include "core/error.h"

#include <fmt/format.h>

#include <openvdb/tree/LeafManager.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace cambium {

namespace {

/// --colour's words, in ColourExtent's order.
const std::vector<std::string> kColourExtentNames{"shell", "band", "none"};

}  // namespace

ColourExtent parseColourExtent(const std::string& name)
{
    return ColourExtent(optionChoice(name, kColourExtentNames, "--colour"));
}

const char* colourExtentName(ColourExtent e)
{
    return kColourExtentNames[size_t(e)].c_str();
}

InsideBits colourShell(const InsideBits* const around[27])
{
    // The inside bits of the 10 x 10 x 10 voxels from (-1, -1, -1): a row
    // of ten bits (x + 1) for each (y, z).  A missing leaf's voxels take the
    // side of the leaf's nearest voxel (no surface comes within a voxel of a
    // leaf the topology left out, so no cell there is crossed).
    uint16_t row[10][10];
    const InsideBits& self = *around[neighbourSlot(0, 0, 0)];
    auto bits = [&](int sx, int sy, int sz, int y, int z) -> unsigned {
        // The eight bits x = 0..7 of row (y, z) of the leaf at (sx, sy, sz),
        // y and z within it; or of this leaf's nearest row where there is none.
        const InsideBits* leaf = around[neighbourSlot(sx, sy, sz)];
        if (leaf)
            return unsigned((*leaf)[size_t(z)] >> (8 * y)) & 0xFFu;
        const unsigned own = unsigned(self[size_t(sz < 0   ? 0
                                                  : sz > 0 ? 7
                                                           : z)] >>
                                      (8 * (sy < 0   ? 0
                                            : sy > 0 ? 7
                                                     : y))) &
                             0xFFu;
        // (x beyond the leaf: its edge voxel's bit, copied across the row)
        return sx < 0 ? (own & 1u) * 0xFFu : sx > 0 ? ((own >> 7) & 1u) * 0xFFu : own;
    };
    for (int pz = 0; pz < 10; ++pz)
        for (int py = 0; py < 10; ++py) {
            const int y = py - 1, z = pz - 1;
            const int sy = y < 0 ? -1 : y > 7 ? 1 : 0, sz = z < 0 ? -1 : z > 7 ? 1 : 0;
            const int ly = y - 8 * sy, lz = z - 8 * sz;
            const unsigned left = (bits(-1, sy, sz, ly, lz) >> 7) & 1u,
                           mid = bits(0, sy, sz, ly, lz), right = bits(1, sy, sz, ly, lz) & 1u;
            row[pz][py] = uint16_t(left | (mid << 1) | (right << 9));
        }
    // Crossed cells: cell (x, y, z), x, y, z from -1 to 7, has corners at
    // padded x + 1 and x + 2 of rows y + 1, y + 2 and z + 1, z + 2; bit x + 1
    // of crossed[z + 1][y + 1].
    uint16_t crossed[9][9];
    for (int cz = 0; cz < 9; ++cz)
        for (int cy = 0; cy < 9; ++cy) {
            const unsigned all = row[cz][cy] & row[cz][cy + 1] & row[cz + 1][cy] &
                                 row[cz + 1][cy + 1],
                           any = row[cz][cy] | row[cz][cy + 1] | row[cz + 1][cy] |
                                 row[cz + 1][cy + 1];
            crossed[cz][cy] = uint16_t((any | (any >> 1)) & ~(all & (all >> 1)) & 0x1FFu);
        }
    // Voxel (x, y, z) is a corner of cells x - 1 and x of rows y - 1, y and
    // z - 1, z: padded cell bits x and x + 1 of crossed[z or z + 1][y or y + 1].
    InsideBits shell{};
    for (int z = 0; z < 8; ++z)
        for (int y = 0; y < 8; ++y) {
            const unsigned c =
                crossed[z][y] | crossed[z][y + 1] | crossed[z + 1][y] | crossed[z + 1][y + 1];
            const unsigned voxels = (c | (c >> 1)) & 0xFFu;
            shell[size_t(z)] |= uint64_t(voxels) << (8 * y);
        }
    return shell;
}

std::optional<openvdb::Vec3f> nearlyUniform(const openvdb::Vec3fTree::LeafNodeType& leaf)
{
    auto it = leaf.cbeginValueOn();
    if (!it)
        return std::nullopt;
    openvdb::Vec3f lo = *it, hi = *it;
    for (; it; ++it) {
        lo = openvdb::math::minComponent(lo, *it);
        hi = openvdb::math::maxComponent(hi, *it);
    }
    // (the bake's colours are bytes / 255; a photo's any float)
    constexpr float kStep = 1.0f / 255.0f + 1e-6f;
    if (hi[0] - lo[0] > kStep || hi[1] - lo[1] > kStep || hi[2] - lo[2] > kStep)
        return std::nullopt;
    return *leaf.cbeginValueOn();
}

void keepColourShell(LevelSetGrids& grids)
{
    if (!grids.color || !grids.surface || grids.colorPacked)
        throw std::logic_error("keepColourShell: a surface and a colour grid with their values");
    using SurfaceLeaf = openvdb::FloatTree::LeafNodeType;
    const openvdb::FloatTree& surface = grids.surface->tree();
    openvdb::tree::LeafManager<openvdb::Vec3fTree> manager(grids.color->tree());
    const size_t n = manager.leafCount();
    // Each Cd leaf's shell from the signs of the level set around it (its
    // own values; a tile's or the background's sign where no leaf is), then
    // its voxels off the shell set off to the background; an empty leaf
    // goes, a leaf of one colour becomes a tile.
    // The inside bits of every leaf of the level set, by its origin.
    std::unordered_map<uint64_t, InsideBits> inside;
    {
        std::vector<const SurfaceLeaf*> leaves;
        for (auto it = surface.cbeginLeaf(); it; ++it)
            leaves.push_back(it.getLeaf());
        std::vector<InsideBits> bits(leaves.size());
        tbb::parallel_for(size_t(0), leaves.size(), [&](size_t i) {
            const float* v = leaves[i]->buffer().data();
            InsideBits& b = bits[i];
            b.fill(0);
            for (int x = 0; x < 8; ++x)
                for (int y = 0; y < 8; ++y)
                    for (int z = 0; z < 8; ++z)
                        b[size_t(z)] |= uint64_t(v[64 * x + 8 * y + z] < 0.0f) << (x + 8 * y);
        });
        inside.reserve(leaves.size());
        for (size_t i = 0; i < leaves.size(); ++i) {
            const openvdb::Coord& o = leaves[i]->origin();
            inside.emplace(nodeKey(o[0], o[1], o[2], 3), bits[i]);
        }
    }
    std::vector<uint8_t> fate(n, 0);  // 0 keep, 1 remove, 2 tile
    std::vector<openvdb::Vec3f> tile(n);
    const openvdb::Vec3f background = grids.color->background();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> acc(surface);
        for (size_t i = r.begin(); i < r.end(); ++i) {
            auto& leaf = manager.leaf(i);
            InsideBits uniform[27];
            const InsideBits* around[27];
            for (int dz = -1; dz <= 1; ++dz)
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int s = neighbourSlot(dx, dy, dz);
                        const openvdb::Coord o = leaf.origin().offsetBy(8 * dx, 8 * dy, 8 * dz);
                        const auto found = inside.find(nodeKey(o[0], o[1], o[2], 3));
                        if (found != inside.end()) {
                            around[s] = &found->second;
                        } else {  // a tile's sign, or the background's
                            uniform[s].fill(acc.getValue(o) < 0.0f ? ~uint64_t(0) : 0);
                            around[s] = &uniform[s];
                        }
                    }
            const InsideBits shell = colourShell(around);
            for (auto v = leaf.beginValueOn(); v; ++v) {
                const openvdb::Coord c = v.getCoord() - leaf.origin();
                if (!((shell[size_t(c[2])] >> (c[0] + 8 * c[1])) & 1u)) {
                    v.setValue(background);
                    v.setValueOff();
                }
            }
            if (leaf.isEmpty()) {
                fate[i] = 1;
            } else if (const auto one = nearlyUniform(leaf)) {
                fate[i] = 2;
                tile[i] = *one;
            }
        }
    });
    std::vector<openvdb::Coord> origins(n);
    for (size_t i = 0; i < n; ++i)
        origins[i] = manager.leaf(i).origin();
    openvdb::Vec3fTree& tree = grids.color->tree();
    for (size_t i = 0; i < n; ++i) {
        if (fate[i] == 1)
            tree.addTile(1, origins[i], background, false);
        else if (fate[i] == 2)
            tree.addTile(1, origins[i], tile[i], true);
    }
}

}  // namespace cambium
