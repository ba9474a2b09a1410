// cambium lsystem — an L-system derived: its string, skeleton or a summary.
#include "app/app.h"

#include "core/math.h"
#include "model/lsystem.h"
#include "model/skeleton.h"
#include "model/turtle.h"

#include <fmt/format.h>

#include <algorithm>

namespace cambium {

namespace {

/// Derives `steps` steps (the file's derivation length when negative) and
/// prints the string (one line, ABOP notation), the skeleton
/// (docs/skeleton-format.md, each line's order and module in a trailing
/// comment) or, without either, a summary.
struct LSystemRequest {
    std::string input;
    int steps = -1;
    long long seed = -1;  ///< < 0: the file's seed:
    size_t maxModules = kDefaultMaxModules;
    bool printString = false, printSkeleton = false;
};

int runLSystemCommand(const LSystemRequest& req)
{
    const LSystem sys = loadLSystem(req.input);
    const int steps = req.steps >= 0 ? req.steps : sys.derivationLength;
    ProgressBar bar;
    const ModuleString s =
        derive(sys, steps, req.seed >= 0 ? uint64_t(req.seed) : sys.seed, req.maxModules,
               [&](const char* stage, double f) { bar(stage, f); });
    bar.clear();
    const Skeleton sk = interpretTurtle(sys, s);
    if (req.printString) {
        formatModules(s, [&](std::string_view part, double f) {
            fmt::print("{}", part);
            bar("printing the string", f);
        });
        bar.clear();
        fmt::print("\n");
    }
    if (req.printSkeleton) {
        fmt::print("# {} after {} steps: {}  # order module [cut]\n", req.input, steps,
                   kSkeletonColumns);
        for (const Internode& n : sk.internodes)
            fmt::print("{}  # {} {}{}\n", formatInternode(n), n.order, n.module,
                       n.cut ? " cut" : "");
    }
    if (!req.printString && !req.printSkeleton) {
        int maxOrder = 0;
        for (const Internode& n : sk.internodes)
            maxOrder = std::max(maxOrder, n.order);
        fmt::print("{}: {} steps, {} modules, {} internodes, branch orders 0-{}\n", req.input,
                   steps, s.size(), sk.internodes.size(), maxOrder);
    }
    return 0;
}

}  // namespace

void addLSystemCommand(CLI::App& app, Action& action)
{
    auto req = std::make_shared<LSystemRequest>();
    auto* cmd =
        app.add_subcommand("lsystem",
                           "Derive an L-system (docs/lsystem-format.md) and print the string, "
                           "its skeleton or a summary");
    cmd->add_option("input", req->input, "L-system file")->required();
    cmd->add_option("--steps", req->steps,
                    "Derivation steps (default: the file's derivation length)")
        ->check(CLI::Range(0, kMaxSteps));
    cmd->add_option("--seed", req->seed,
                    "Seed of stochastic productions (default: the file's seed:)")
        ->check(CLI::Range(0LL, kMaxSeed));
    cmd->add_option("--max-modules", req->maxModules, "Refuse a derivation that makes more modules")
        ->capture_default_str()
        ->check(CLI::Range(size_t(1), kMaxModulesLimit));
    cmd->add_flag("--print-string", req->printString,
                  "Print the derived string (one line, ABOP notation)");
    cmd->add_flag("--print-skeleton", req->printSkeleton,
                  "Print the internodes in the skeleton format, which cambium bake reads");
    cmd->callback([req, &action] { action = [req] { return runLSystemCommand(*req); }; });
}

}  // namespace cambium
