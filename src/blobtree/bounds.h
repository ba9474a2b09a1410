// cambium — conservative bounds of BlobTree fields, from primitive supports.
#pragma once

#include "blobtree/blobtree.h"
#include "core/box.h"

#include <vector>

namespace cambium {

/// Where a node's field can be nonzero (`support`) and where it can be
/// positive (`positive`).  Outside `positive` the field is <= 0 < T, so the
/// surface and the whole inside of the node lie within it.
struct NodeBounds {
    Box support;
    Box positive;
};

/// Bounds of every node (indexed like the tree's nodes).
std::vector<NodeBounds> computeBounds(const BlobTree& tree);

/// Bounds of the root's surface and inside: the positive support of the root.
Box surfaceBounds(const BlobTree& tree);

/// The image under a warp node's forward map of a box given in its child's
/// space: a box containing every point whose inverse warp falls in `box`.
Box warpImage(const Node& warp, const Box& box);

}  // namespace cambium
