// cambium — BlobTree statistics.
#include "blobtree/stats.h"

#include "blobtree/bounds.h"

#include <algorithm>

namespace cambium {

TreeStats computeStats(const BlobTree& tree)
{
    TreeStats s;
    if (tree.root() < 0)
        return s;
    // Depth of each node seen from the root; parents come after their
    // children, so a reverse sweep assigns a parent's depth before its children.
    std::vector<int> depth(tree.size(), 0);
    depth[size_t(tree.root())] = 1;
    for (size_t i = tree.size(); i-- > 0;) {
        if (depth[i] == 0)
            continue;
        const Node& n = tree.node(int(i));
        ++s.countByType[n.type];
        switch (kindOf(n.type)) {
            case NodeKind::Primitive:
                ++s.primitives;
                break;
            case NodeKind::Operator:
                ++s.operators;
                break;
            case NodeKind::Warp:
                ++s.warps;
                break;
        }
        s.depth = std::max(s.depth, depth[i]);
        auto visit = [&](int c) { depth[size_t(c)] = std::max(depth[size_t(c)], depth[i] + 1); };
        for (int c : n.children)
            visit(c);
        if (n.type == NodeType::GBB)
            visit(n.gbb().bound);
    }
    s.bounds = surfaceBounds(tree);
    return s;
}

}  // namespace cambium
