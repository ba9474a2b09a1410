// cambium — skeleton text format.
#include "model/skeleton.h"

#include "core/error.h"
#include "core/math.h"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_map>
#include <unordered_set>

namespace cambium {

Skeleton parseSkeleton(const std::string& text, const std::string& source)
{
    static const char* fields[] = {"id", "parent", "x0", "y0", "z0", "x1", "y1", "z1", "r0", "r1"};
    Skeleton s;
    std::unordered_set<long long> ids;
    std::vector<int> lines;  // each internode's line
    std::istringstream in(text);
    std::string line;
    int lineNo = 0;
    while (std::getline(in, line)) {
        ++lineNo;
        const auto first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos || line[first] == '#')
            continue;
        if (const auto hash = line.find('#'); hash != std::string::npos)
            line.resize(hash);  // a trailing comment
        std::istringstream ls(line);
        std::string tok[10], extra;
        int count = 0;
        while (count < 10 && ls >> tok[count])
            ++count;
        if (count < 10)
            throw InputError(
                fmt::format("{}:{}: expected 10 fields (id parent x0 y0 z0 x1 y1 z1 r0 r1), "
                            "found {}",
                            source, lineNo, count));
        if (ls >> extra)
            throw InputError(
                fmt::format("{}:{}: more than 10 fields ('{}')", source, lineNo, extra));
        double v[10];
        for (int k = 0; k < 10; ++k) {
            char* end = nullptr;
            errno = 0;
            v[k] = std::strtod(tok[k].c_str(), &end);
            if (end == tok[k].c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v[k]) ||
                writtenInHex(tok[k].c_str(), end))
                throw InputError(fmt::format("{}:{}: {} is not a finite number ('{}')", source,
                                             lineNo, fields[k], tok[k]));
        }
        if (!(std::abs(v[0]) < 1e15 && std::abs(v[1]) < 1e15) || std::trunc(v[0]) != v[0] ||
            std::trunc(v[1]) != v[1])
            throw InputError(
                fmt::format("{}:{}: id and parent must be integers below 1e15", source, lineNo));
        Internode n;
        n.id = (long long)v[0];
        n.parent = (long long)v[1];
        if (!ids.insert(n.id).second)
            throw InputError(fmt::format("{}:{}: id {} appears twice", source, lineNo, n.id));
        n.p0 = {v[2], v[3], v[4]};
        n.p1 = {v[5], v[6], v[7]};
        n.r0 = v[8];
        n.r1 = v[9];
        for (int k : {8, 9})
            if (!(v[k] > 0.0))
                throw InputError(fmt::format("{}:{}: {} must be greater than 0 (got {})", source,
                                             lineNo, fields[k], v[k]));
        if (n.p0 == n.p1)
            throw InputError(
                fmt::format("{}:{}: internode {} has no length (its two points are the same)",
                            source, lineNo, n.id));
        s.internodes.push_back(n);
        lines.push_back(lineNo);
    }
    std::unordered_map<long long, size_t> index;
    for (size_t i = 0; i < s.internodes.size(); ++i)
        index[s.internodes[i].id] = i;
    for (size_t i = 0; i < s.internodes.size(); ++i) {
        const Internode& n = s.internodes[i];
        if (n.parent != -1 && !ids.count(n.parent))
            throw InputError(
                fmt::format("{}:{}: internode {} has parent {}, which is not in the file", source,
                            lines[i], n.id, n.parent));
    }
    // Parents must form a forest: walk up from each internode, marking the
    // walk; meeting the walk again is a cycle (a self-loop is one of length 1).
    std::vector<size_t> walk(s.internodes.size(), 0);  // 0: not seen; k: seen on walk k; done after
    std::vector<bool> done(s.internodes.size(), false);
    for (size_t start = 0; start < s.internodes.size(); ++start) {
        size_t i = start;
        while (!done[i] && walk[i] != start + 1) {
            walk[i] = start + 1;
            const long long parent = s.internodes[i].parent;
            if (parent == -1)
                break;
            i = index.at(parent);
        }
        if (!done[i] && walk[i] == start + 1 && s.internodes[i].parent != -1) {
            // i is on a cycle: name it
            std::string cycle = std::to_string(s.internodes[i].id);
            for (size_t k = index.at(s.internodes[i].parent); k != i && cycle.size() < 200;
                 k = index.at(s.internodes[k].parent))
                cycle += fmt::format(" -> {}", s.internodes[k].id);
            throw InputError(fmt::format(
                "{}:{}: internode {} is its own ancestor (parents in a cycle: {} -> {})", source,
                lines[i], s.internodes[i].id, cycle, s.internodes[i].id));
        }
        for (size_t k = start;; k = index.at(s.internodes[k].parent)) {
            done[k] = true;
            if (s.internodes[k].parent == -1 || done[index.at(s.internodes[k].parent)])
                break;
        }
    }
    if (s.internodes.empty())
        throw InputError(fmt::format("{}: no internodes: the skeleton is empty", source));
    return s;
}

Skeleton loadSkeleton(const std::string& path)
{
    return parseSkeleton(readTextFile(path, "skeleton file"), path);
}

std::string formatInternode(const Internode& n)
{
    return fmt::format("{} {} {} {} {} {} {} {} {} {}", n.id, n.parent, n.p0.x, n.p0.y, n.p0.z,
                       n.p1.x, n.p1.y, n.p1.z, n.r0, n.r1);
}

BlobTree skeletonToBlend(const Skeleton& skeleton, double threshold)
{
    BlobTree tree(threshold);
    std::vector<int> cones;
    cones.reserve(skeleton.internodes.size());
    for (const Internode& n : skeleton.internodes) {
        cones.push_back(tree.cone(n.p0, n.p1, n.r0, n.r1));
        if (n.colour)
            tree.setColor(cones.back(), *n.colour);
    }
    tree.setRoot(tree.op({NodeType::BLEND}, std::move(cones)));
    tree.finalize();
    return tree;
}

}  // namespace cambium
