// cambium — parametric, bracketed, stochastic, context-sensitive L-systems in
// the notation of "The Algorithmic Beauty of Plants" (ABOP), read from files
// written as for cpfg (docs/lsystem-format.md).
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cambium {

/// One module of a derived string: a one-character name and its parameters.
struct Module {
    char name = 0;
    std::vector<double> params;
    bool operator==(const Module& o) const { return name == o.name && params == o.params; }
};
using ModuleString = std::vector<Module>;

/// An arithmetic expression over the formal parameters of a production
/// (compiled once; `#define` constants folded in).
struct Expr;

/// A module pattern on the left of a production: a name and formal parameters.
struct ModulePattern {
    char name = 0;
    std::vector<std::string> formals;
};

/// A module of a successor: a name and one expression per parameter.
struct ModuleTemplate {
    char name = 0;
    std::vector<std::shared_ptr<const Expr>> args;
};

struct Production {
    int line = 0;                           ///< where it is in the file
    std::vector<ModulePattern> left;        ///< left context (empty: none)
    ModulePattern strict;                   ///< the predecessor
    std::vector<ModulePattern> right;       ///< right context (empty: none)
    std::shared_ptr<const Expr> condition;  ///< null: always
    std::vector<ModuleTemplate> successor;
    double probability = -1.0;  ///< > 0 for a stochastic production, -1 for none given
};

/// An L-system and its turtle settings.
struct LSystem {
    std::string source;  ///< file name, for messages
    ModuleString axiom;
    std::vector<Production> productions;
    int derivationLength = 0;  ///< "derivation length:" (steps when not given on the command line)
    std::string ignore;        ///< symbols context matching skips ("ignore:")
    double angle = 90.0;       ///< default turn angle, degrees ("angle:")
    double step = 1.0;         ///< default F/f length ("step:")
    double width = 0.1;        ///< initial width, a diameter ("width:")
    /// What '!' and '#' without a parameter take from and add to the width
    /// ("width increment:"; default: a tenth of the initial width).
    std::optional<double> widthIncrement;
    /// The colours of colour indices ("color: INDEX R G B"), over the default
    /// palette (turtle.h).
    std::map<int, glm::dvec3> colours;
    double tropism[4] = {0, 0, 0, 0};  ///< "tropism: tx ty tz e" (e = 0: none)
    uint64_t seed = 1;                 ///< "seed:" for stochastic productions
};

/// Reads an L-system (docs/lsystem-format.md).  InputError naming the file,
/// line and column of anything it cannot read: an unknown directive, a
/// production or condition that does not parse, unbalanced brackets, a
/// parameter count that differs from another use of the same module, an
/// expression that names no parameter or constant.
LSystem parseLSystem(const std::string& text, const std::string& source);
LSystem loadLSystem(const std::string& path);

/// The module limit of a derivation unless one is given (`--max-modules`),
/// the largest limit that may be given (a module takes about 100 bytes while
/// a step is made), the most derivation steps, and the most module rewrites
/// of a whole derivation (its time: about 10^8 a second).
constexpr size_t kDefaultMaxModules = 2'000'000;
constexpr size_t kMaxModulesLimit = 50'000'000;
constexpr int kMaxSteps = 100'000;
constexpr double kMaxRewrites = 2e9;

/// Derives `steps` steps from the axiom: every module rewritten in parallel
/// by the first production (in file order) whose predecessor, contexts and
/// condition match, or by one of them chosen by their probabilities (seeded
/// by `seed`) when the matching productions are stochastic; modules without
/// a production stay.  After each step `%` removes the rest of its branch
/// (and stays, marking the cut).  InputError before a step would exceed `maxModules` modules.
/// `progress` is told of each step; `maxRewrites` bounds the work (module
/// rewrites and the modules context searches pass) of the whole derivation.
ModuleString derive(const LSystem& system, int steps, uint64_t seed, size_t maxModules,
                    const std::function<void(const char*, double)>& progress = {},
                    double maxRewrites = kMaxRewrites);

/// The index of the ']' that closes the branch holding module `from` (the
/// string's size at the top level): where a cut at `from` ends.
size_t branchEnd(const ModuleString& s, size_t from);

/// The string in the L-system notation: modules without parameters as their
/// symbol, others as `F(1.5,2)`, numbers in their shortest exact form.
std::string formatModules(const ModuleString& s);
/// The same, handed to `sink` in parts of about 64 KB with the fraction of
/// the modules written so far (a string of 13 million parameters is 2 GB of
/// text: --print-string ran out of memory making it whole).
void formatModules(const ModuleString& s,
                   const std::function<void(std::string_view, double)>& sink);

}  // namespace cambium
