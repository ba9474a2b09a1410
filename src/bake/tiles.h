// cambium — one frame baked as spatial tiles (bake --tiles): each tile's bake
// (BakeOptions::tile) runs in a process of its own and writes the leaves it
// owns, exactly the whole bake's; their files merged are the whole bake's
// grids.
#pragma once

#include "bake/levelset.h"

#include <string>
#include <vector>

namespace cambium {

/// The grids of tile files (bakes of BakeOptions::tile k of n for every k)
/// merged into the grids the whole bake makes: each leaf packed for writeVdb
/// as the bake packs its own (as halves where `half`), one tile file decoded
/// at a time, then the tiles above the leaves flood-filled.  InputError
/// naming a file that is not a level set like the first.
BakedGrids mergeTiles(const std::vector<std::string>& files, bool half);

}  // namespace cambium
