// cambium — writing baked grids to .vdb files that other software opens.
#pragma once

#include "bake/levelset.h"
#include "core/files.h"

#include <string>

namespace cambium {

struct VdbFileInfo {
    std::string scene;      ///< the source the grids were baked from
    double threshold = 0.5;
    double halfWidth = 3.0;
    long long frame = 0;    ///< growth frame number (0 for a single bake)
    double time = 0.0;      ///< model time of the frame
    bool half = false;      ///< store floats as 16-bit halves
    std::string sequence;   ///< a sequence's key (file metadata `cambium_sequence`), empty for a single bake
};

/// Writes the grids (surface, Cd, density if present) with grid statistics
/// metadata and cambium's own metadata, Blosc-compressed, to a temporary
/// file beside `path` that is renamed over it only when complete: a crash
/// never leaves a half-written .vdb.  Throws InputError when the path cannot
/// be written.
void writeVdb(const BakedGrids& grids, const std::string& path, const VdbFileInfo& info);

/// The `cambium_sequence` file metadata of a .vdb; empty when it has none or
/// cannot be read.
std::string readSequenceKey(const std::string& path);

}  // namespace cambium
