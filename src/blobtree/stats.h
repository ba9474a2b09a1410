// cambium — what a BlobTree is made of.
#pragma once

#include "blobtree/blobtree.h"
#include "core/box.h"

#include <map>

namespace cambium {

struct TreeStats {
    std::map<NodeType, size_t> countByType;  ///< nodes reachable from the root
    size_t primitives = 0, operators = 0, warps = 0;
    int depth = 0;  ///< nodes on the longest root-to-leaf path (a lone primitive: 1)
    Box bounds;     ///< surfaceBounds()
};

TreeStats computeStats(const BlobTree& tree);

}  // namespace cambium
