// cambium growth — a growth model's tree at a time, as counts or a skeleton.
#include "app/app.h"

#include "blobtree/stats.h"
#include "core/math.h"
#include "model/growth.h"
#include "model/growth_params.h"
#include "model/skeleton.h"
#include "model/tree_builder.h"

#include <fmt/format.h>

#include <optional>

namespace cambium {

namespace {

struct GrowthRequest {
    std::string input;
    std::optional<double> time;  ///< default: the last year
    long long seed = -1;         ///< < 0: the file's
    bool leaves = true;
    bool printStats = false, printSkeleton = false;
};

void printGrowthStats(const GrowthModel& model, const Skeleton& sk, const GrowthStats& s)
{
    fmt::print("order  branches  internodes\n");
    long long branches = 0, internodes = 0;
    for (const auto& [order, count] : s.branchesByOrder) {
        const auto it = s.internodesByOrder.find(order);
        const long long in = it == s.internodesByOrder.end() ? 0 : it->second;
        fmt::print("{:>5}  {:>8}  {:>10}\n", order, count, in);
        branches += count;
        internodes += in;
    }
    fmt::print("  all  {:>8}  {:>10}\n", branches, internodes);
    fmt::print("organs: {} leaves, {} buds, {} bud scale scar rings, {} scars\n", s.leaves, s.buds,
               s.rings, sk.scars.size());
    fmt::print("shoots: {} grown, {} with their metamer count moved by the {:g} degree rule\n",
               s.shoots, s.shootsAdjusted, model.params().longestSeparation);
    // (at time 0 nothing has grown: no tree to count, not an error)
    if (sk.internodes.empty()) {
        fmt::print("BlobTree: none (nothing has grown yet)\n");
        return;
    }
    const TreeStats ts = computeStats(buildTree(sk, model.buildOptions()));
    fmt::print("BlobTree: {} primitives, {} operators, {} warps, depth {}\n", ts.primitives,
               ts.operators, ts.warps, ts.depth);
    for (const auto& [type, count] : ts.countByType)
        fmt::print("  {:<14} {}\n", typeName(type), count);
}

int runGrowthCommand(const GrowthRequest& req)
{
    GrowthParameters p = loadGrowthParameters(req.input);
    if (req.seed >= 0)
        p.seed = uint64_t(req.seed);
    const double t = timeOfLife(p, req.time, req.input, "--year/--time");
    const GrowthModel model(p);
    const Skeleton sk = model.skeleton(t, req.leaves);
    if (req.printSkeleton) {
        fmt::print("# {} at t = {}: {}  # order age\n", req.input, t, kSkeletonColumns);
        for (const Internode& n : sk.internodes)
            fmt::print("{}  # {} {:.4g}\n", formatInternode(n), n.order, n.age);
    }
    if (!req.printStats && req.printSkeleton)
        return 0;
    const GrowthStats s = model.stats(t, sk);
    fmt::print(
        "{} at t = {:g} (year {} of {}): height {:.3f}, {} branches grown in all ({} lost so "
        "far)\n",
        req.input, t, growthYear(t), p.years, s.height, model.branches().size(), s.lostBranches);
    if (req.printStats)
        printGrowthStats(model, sk, s);
    return 0;
}

}  // namespace

void addGrowthCommand(CLI::App& app, Action& action)
{
    struct Options {
        GrowthRequest request;
        double year = 0.0, time = 0.0;
        bool noLeaves = false;
    };
    auto o = std::make_shared<Options>();
    GrowthRequest& req = o->request;
    auto* cmd =
        app.add_subcommand("growth",
                           "Grow a tree from a growth parameter file (docs/growth-format.md) "
                           "and print its counts or skeleton at a time");
    cmd->add_option("input", req.input, "Growth parameter file (.json)")->required();
    auto* yearOpt = cmd->add_option("--year", o->year, "The end of this year (default: the last)");
    auto* timeOpt =
        cmd->add_option("--time", o->time, "Any time in years, e.g. 3.5 (mid-season of year 4)")
            ->excludes(yearOpt);
    cmd->add_option("--seed", req.seed, "Seed of the stochastic orientation (default: the file's)")
        ->check(CLI::Range(0LL, kMaxSeed));
    cmd->add_flag("--no-leaves", o->noLeaves, "Leave the leaves out");
    cmd->add_flag("--print-stats", req.printStats,
                  "Branches and internodes by order, organs, BlobTree primitives and operators");
    cmd->add_flag("--print-skeleton", req.printSkeleton, "Print the internodes (skeleton format)");
    cmd->callback([o, yearOpt, timeOpt, &action] {
        if (yearOpt->count())
            o->request.time = o->year;
        if (timeOpt->count())
            o->request.time = o->time;
        o->request.leaves = !o->noLeaves;
        action = [o] { return runGrowthCommand(o->request); };
    });
}

}  // namespace cambium
