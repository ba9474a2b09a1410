// cambium — skeleton text format.
#include "model/skeleton.h"

#include "core/error.h"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <unordered_set>

namespace cambium {

Skeleton parseSkeleton(const std::string& text, const std::string& source)
{
    static const char* fields[] = {"id", "parent", "x0", "y0", "z0", "x1", "y1", "z1", "r0", "r1"};
    Skeleton s;
    std::unordered_set<long long> ids;
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
            throw InputError(fmt::format("{}:{}: expected 10 fields (id parent x0 y0 z0 x1 y1 z1 r0 r1), "
                                         "found {}",
                                         source, lineNo, count));
        if (ls >> extra)
            throw InputError(fmt::format("{}:{}: more than 10 fields ('{}')", source, lineNo, extra));
        double v[10];
        for (int k = 0; k < 10; ++k) {
            char* end = nullptr;
            errno = 0;
            v[k] = std::strtod(tok[k].c_str(), &end);
            if (end == tok[k].c_str() || *end != '\0' || errno == ERANGE || !std::isfinite(v[k]))
                throw InputError(fmt::format("{}:{}: {} is not a finite number ('{}')", source, lineNo,
                                             fields[k], tok[k]));
        }
        Internode n;
        n.id = (long long)v[0];
        n.parent = (long long)v[1];
        if (double(n.id) != v[0] || double(n.parent) != v[1])
            throw InputError(fmt::format("{}:{}: id and parent must be integers", source, lineNo));
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
        s.internodes.push_back(n);
    }
    for (const Internode& n : s.internodes)
        if (n.parent != -1 && !ids.count(n.parent))
            throw InputError(fmt::format("{}: internode {} has parent {}, which is not in the file",
                                         source, n.id, n.parent));
    if (s.internodes.empty())
        throw InputError(fmt::format("{}: no internodes: the skeleton is empty", source));
    return s;
}

Skeleton loadSkeleton(const std::string& path)
{
    return parseSkeleton(readTextFile(path, "skeleton file"), path);
}

BlobTree skeletonToBlend(const Skeleton& skeleton, double threshold)
{
    BlobTree tree(threshold);
    std::vector<int> cones;
    cones.reserve(skeleton.internodes.size());
    for (const Internode& n : skeleton.internodes)
        cones.push_back(tree.cone(n.p0, n.p1, n.r0, n.r1));
    tree.setRoot(tree.op({NodeType::BLEND}, std::move(cones)));
    tree.finalize();
    return tree;
}

}  // namespace cambium
