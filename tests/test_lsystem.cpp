// L-systems: derivations of ABOP's classic systems, parametric conditions,
// seeded stochastic choice, context, cuts, limits and errors with their
// line and column; the turtle against hand-computed coordinates.
#include "model/lsystem.h"
#include "model/turtle.h"
#include "model/tree_builder.h"
#include "blobtree/evaluator.h"

#include "core/error.h"
#include "test_util.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace {

using namespace cambium;

std::string run(const std::string& text, int steps, uint64_t seed = 1, size_t maxModules = 1000000)
{
    const LSystem sys = parseLSystem(text, "test.l");
    return formatModules(derive(sys, steps, seed, maxModules));
}

/// `text` n times, `separator` between them (axioms of many modules, long
/// sums).
std::string repeated(const std::string& text, int n, const std::string& separator = "")
{
    std::string out;
    for (int k = 0; k < n; ++k)
        out += (k ? separator : "") + text;
    return out;
}

TEST(LSystem, AlgaeGrowsAsInABOP)
{
    // ABOP 1.1: the lengths are Fibonacci numbers.
    const std::string algae = "Axiom: A\nA --> AB\nB --> A\n";
    EXPECT_EQ(run(algae, 0), "A");
    EXPECT_EQ(run(algae, 1), "AB");
    EXPECT_EQ(run(algae, 4), "ABAABABA");
    EXPECT_EQ(run(algae, 5), "ABAABABAABAAB");
    size_t previous = 1, current = 2;  // after 0 and 1 steps
    for (int n = 2; n <= 15; ++n) {
        const size_t next = previous + current;
        EXPECT_EQ(run(algae, n).size(), next) << n;
        previous = current;
        current = next;
    }
}

TEST(LSystem, KochCurveAndABracketedPlant)
{
    // ABOP figure 1.9 (quadratic Koch island, first step) and 1.24a.
    EXPECT_EQ(run("Axiom: F-F-F-F\nF --> F-F+F+FF-F-F+F\n", 1),
              "F-F+F+FF-F-F+F-F-F+F+FF-F-F+F-F-F+F+FF-F-F+F-F-F+F+FF-F-F+F");
    EXPECT_EQ(run("Axiom: F\nF --> F[+F]F[-F]F\n", 1), "F[+F]F[-F]F");
    EXPECT_EQ(run("Axiom: F\nF --> F[+F]F[-F]F\n", 2),
              "F[+F]F[-F]F[+F[+F]F[-F]F]F[+F]F[-F]F[-F[+F]F[-F]F]F[+F]F[-F]F");
}

TEST(LSystem, ParametricProductionsAndConditions)
{
    // ABOP 1.10: the example derivation of section 1.10.1.
    const std::string text =
        "#define R 1.456\n"
        "Axiom: B(2)A(4,4)\n"
        "A(x,y) : y <= 3 --> A(x*2,x+y)\n"
        "A(x,y) : y > 3 --> B(x)A(x/y,0)\n"
        "B(x) : x < 1 --> C\n"
        "B(x) : x >= 1 --> B(x-1)\n";
    EXPECT_EQ(run(text, 1), "B(1)B(4)A(1,0)");
    EXPECT_EQ(run(text, 2), "B(0)B(3)A(2,1)");
    EXPECT_EQ(run(text, 3), "CB(2)A(4,3)");
    EXPECT_EQ(run(text, 4), "CB(1)A(8,7)");
    // Expressions: precedence, functions (degrees), constants, logic.
    EXPECT_EQ(run("#define k 3\nAxiom: X(1)\nX(a) --> Y(a+2*k^2, -a^2, sin(90), max(a,k), a<2 && "
                  "k>2 || 0)\n",
                  1),
              "Y(19,-1,1,3,1)");
}

TEST(LSystem, StochasticChoiceFollowsTheSeed)
{
    const std::string text =
        "Axiom: F\nF --> F[+F]F : 0.33\nF --> F[-F]F : 0.33\nF --> F[+F]F[-F] : 0.34\n";
    const std::string a = run(text, 5, 7), b = run(text, 5, 7), c = run(text, 5, 8);
    EXPECT_EQ(a, b);
    EXPECT_NE(a, c);
    // The choice follows the probabilities: over many modules, about a third each.
    const LSystem sys = parseLSystem(
        "Axiom: AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA\nA --> X : 1\nA --> Y : 3\n", "t");
    size_t x = 0, y = 0;
    for (uint64_t seed = 0; seed < 100; ++seed)
        for (const Module& m : derive(sys, 1, seed, 1000)) {
            x += m.name == 'X';
            y += m.name == 'Y';
        }
    EXPECT_EQ(x + y, 4000u);
    EXPECT_NEAR(double(y) / double(x + y), 0.75, 0.03);
}

TEST(LSystem, TheSameSeedDerivesTheSameStringWithAnyStandardLibrary)
{
    // The uniform numbers of stochastic productions and ran() come from
    // core/random.h, not from std::uniform_real_distribution (which each
    // standard library implements its own way): this string is the one every
    // build derives.  A nested ran() draws its own number before its
    // argument's.
    const std::string text =
        "Axiom: A(1)\nA(x) --> A(x+ran(1))B(ran(ran(2))) : 1\n"
        "A(x) --> C(ran(x))A(x) : 2\n";
    EXPECT_EQ(run(text, 4, 2),
              "C(0.85023613957581)C(0.9253171001154079)A(1.821728694190027)B(1.2668254591838268)"
              "B(0.04475110335239621)");
}

TEST(LSystem, ContextSensitiveProductionsSeeAcrossBranches)
{
    // ABOP 1.8: a signal moving acropetally (from the base) through a
    // bracketed string: the left context skips lateral branches and ignores + -.
    const std::string text = "ignore: + -\nAxiom: B[+A]A[-A]A[+A]A\nB < A --> B\n";
    EXPECT_EQ(run(text, 1), "B[+B]B[-A]A[+A]A");
    EXPECT_EQ(run(text, 2), "B[+B]B[-B]B[+A]A");
    EXPECT_EQ(run(text, 3), "B[+B]B[-B]B[+B]B");
    // Right context skips lateral branches; parameters of contexts bind.
    EXPECT_EQ(run("Axiom: A(1)[B(5)]C(2)\nA(x) > C(y) --> D(x+y)\n", 1), "D(3)[B(5)]C(2)");
    EXPECT_EQ(run("Axiom: A(1)[B(5)]C(2)\nA(x) > B(y) --> D(x+y)\n", 1), "A(1)[B(5)]C(2)");
}

TEST(LSystem, UnknownSymbolsStayAndCutsRemoveTheRestOfTheBranch)
{
    EXPECT_EQ(run("Axiom: {A'L}\nA --> A\n", 3), "{A'L}");
    EXPECT_EQ(run("Axiom: F[FA[F]F]F\nA --> %\n", 1), "F[F%]F");
    EXPECT_EQ(run("Axiom: FAF[F]F\nA --> %\n", 1), "F%");
    // A cut inside a successor's own branch ends at that branch's ']'; a
    // cut at its level takes the branch's rest whatever it holds: kept
    // modules, branches, other rewrites and other cuts.
    EXPECT_EQ(run("Axiom: A[B]A\nA --> F[X%[Y]Z]W\nB --> %V\n", 1), "F[X%]W[%]F[X%]W");
    EXPECT_EQ(run("Axiom: F[BA[A]Y%X]A\nA --> F[%]G\nB --> %V\n", 1), "F[%]F[%]G");
    EXPECT_EQ(run("Axiom: A\nA --> F[&F%F]/A\n", 3), "F[&F%]/F[&F%]/F[&F%]/A");
}

TEST(LSystem, ExplodingDerivationsStopAtTheModuleLimit)
{
    const LSystem sys = parseLSystem("Axiom: F\nF --> FF\n", "grow.l");
    EXPECT_NO_THROW(derive(sys, 10, 1, 1024));
    try {
        derive(sys, 11, 1, 1024);
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(
                      "grow.l: derivation step 11 would make 2048 modules, more than the limit "
                      "of 1024"),
                  std::string::npos)
            << e.what();
    }
}

TEST(LSystem, TheWorkOfContextSearchesCountsAgainstTheBound)
{
    // Every A looks left past every earlier [A] branch for its B: the
    // searches grow as the square of the string, the derivation as the cube
    // of its steps.  Counted with the rewrites, they stop at the bound.
    const LSystem sys = parseLSystem("Axiom: BX\nX --> [A]X\nB < A --> A\n", "quad.l");
    const ModuleString s = derive(sys, 100, 1, kDefaultMaxModules, {}, 1e6);
    EXPECT_EQ(s.size(), 2u + 3u * 100u);  // B, the hundred [A], X
    // Rewrites alone: 2 + 5 + ... + 302, about 15,000 over 100 steps; the
    // searches pass about 100^3 / 6 = 170,000 modules more, and over 200
    // steps 1.3 million: past the bound, with the rewrites (60,000) far below.
    test::expectInputError([&] { derive(sys, 200, 1, kDefaultMaxModules, {}, 1e6); },
                           "quad.l: derivation step ", "cubic context searches");
    try {
        derive(sys, 200, 1, kDefaultMaxModules, {}, 1e6);
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(": its context searches and conditions, with the "
                                             "rewrites, are more than 1e+06 modules' work"),
                  std::string::npos)
            << e.what();
    }
}

TEST(LSystem, AStringThatCannotShrinkIsRefusedBeforeItsFirstStep)
{
    // No successor is empty and none cuts: every step rewrites at least the
    // string before, so 1,000 modules over 100,000 steps are 10^8 rewrites,
    // known at once (a million modules kept by A --> A ran for minutes
    // before the bound stopped it).
    const LSystem sys = parseLSystem("Axiom: " + std::string(1000, 'A') + "\nA --> A\n", "keep.l");
    int steps = 0;
    const auto counted = [&](const char*, double) { ++steps; };
    test::expectInputError(
        [&] { derive(sys, 100000, 1, kDefaultMaxModules, counted, 1e7); },
        "keep.l: 100000 steps would rewrite more than 1e+07 modules' work in all", "A --> A");
    EXPECT_EQ(steps, 0);
    // Within the bound it runs (each A --> A is three rewrites' work: the
    // module kept, the production tried and the module made); and a system
    // that may shrink (A --> %) is not refused on a guess.
    EXPECT_EQ(derive(sys, 3300, 1, kDefaultMaxModules, {}, 1e7).size(), 1000u);
    test::expectInputError([&] { derive(sys, 3400, 1, kDefaultMaxModules, counted, 1e7); },
                           "keep.l: 3400 steps would rewrite more than 1e+07", "A --> A");
    EXPECT_EQ(steps, 0);
    const LSystem cut = parseLSystem("Axiom: " + std::string(1000, 'A') + "\nA --> %\n", "cut.l");
    EXPECT_NO_THROW(derive(cut, 100000, 1, kDefaultMaxModules, {}, 1e7));
}

TEST(LSystem, ACutWithinItsSuccessorsBranchLetsNoStringShrink)
{
    // F[&F%F]/A's cut takes only the F after it, which the successor made:
    // the string grows by seven modules a step, and the steps left are
    // counted at its length each.  (100,000 steps ran 61 s before the
    // whole bound stopped them at step 23,904; pruned.l with --steps 100000
    // the same.)  Over 2,000 steps: 7 * 2,000^2 / 2 = 1.4e7 rewrites; the
    // bound is known when the string is long enough, before step 300 of
    // 2,000 (7 * 300 * 1,700 = 3.6e6 > 1e6 left then).
    const LSystem sys = parseLSystem("Axiom: A\nA --> F[&F%F]/A\n", "pruned.l");
    int steps = 0;
    const auto counted = [&](const char*, double) { ++steps; };
    test::expectInputError([&] { derive(sys, 2000, 1, kDefaultMaxModules, counted, 1e6); },
                           "pruned.l: 2000 steps would rewrite more than 1e+06",
                           "a cut within its successor's branch");
    EXPECT_GT(steps, 20);
    EXPECT_LT(steps, 300);
    // Within the bound, the string is what the cuts leave.
    EXPECT_EQ(derive(sys, 400, 1, kDefaultMaxModules, {}, 1e6).size(), 7u * 400u + 1u);
    // The same cut at the successor's level may take other modules: no
    // refusal on a guess, only when the work is done.
    const LSystem wide = parseLSystem("Axiom: A\nA --> F[&FF]/A%F\n", "wide.l");
    steps = 0;
    EXPECT_THROW(derive(wide, 2000, 1, kDefaultMaxModules, counted, 1e6), InputError);
    EXPECT_GT(steps, 300);
}

TEST(LSystem, FunctionCallsCountAsTheirWorstCase)
{
    // sin of an argument beyond 1e15 costs 50-70 ns, seven times a small
    // one's: 60 of them a module at half a rewrite a node ran 76 s within
    // the bound.  A call counts seven rewrites, in a condition too.
    const std::string sines = repeated("sin(n * 1e300)", 60, " + ");
    const std::string axiom = repeated("A(1)", 100);
    // Per step: 100 modules, each 60 calls (420), 60 products and their
    // operands (90), 59 sums (29.5), and the module kept, tried and made
    // (7): 54,650.
    const LSystem args =
        parseLSystem("Axiom: " + axiom + "\nA(n) --> A(" + sines + ")\n", "args.l");
    EXPECT_NO_THROW(derive(args, 18, 1, kDefaultMaxModules, {}, 1e6));
    EXPECT_THROW(derive(args, 19, 1, kDefaultMaxModules, {}, 1e6), InputError);
    const LSystem cond =
        parseLSystem("Axiom: " + axiom + "\nA(n) : " + sines + " < 1e9 --> A(n)\n", "cond.l");
    test::expectInputError([&] { derive(cond, 100, 1, kDefaultMaxModules, {}, 1e6); },
                           "cond.l: derivation step ", "sums of 60 sines in a condition");
}

TEST(LSystem, ModulesNoProductionMatchesAreKeptAtEveryStep)
{
    // C --> (empty) lets strings shrink, but no production matches X and
    // nothing cuts: the thousand X are kept at every step (a hundred
    // thousand ran 50 s before the bound stopped them).
    const LSystem sys = parseLSystem(
        "Axiom: " + std::string(1000, 'X') + "B(0)\nB(n) : n >= 0 --> B(n+1)\nC -->\n", "kept.l");
    int steps = 0;
    const auto counted = [&](const char*, double) { ++steps; };
    test::expectInputError([&] { derive(sys, 20000, 1, kDefaultMaxModules, counted, 1e7); },
                           "kept.l: 20000 steps would rewrite more than 1e+07", "kept X");
    EXPECT_EQ(steps, 0);
    EXPECT_EQ(derive(sys, 5000, 1, kDefaultMaxModules, {}, 1e7).back().params[0], 5000.0);
    // A cut may remove them: no refusal on a guess, only when the work is
    // done.
    const LSystem cut = parseLSystem(
        "Axiom: " + std::string(1000, 'X') + "B(0)\nB(n) : n >= 0 --> B(n+1)\nC --> %\n", "cut.l");
    EXPECT_THROW(derive(cut, 20000, 1, kDefaultMaxModules, counted, 1e7), InputError);
    EXPECT_GT(steps, 9000);
}

TEST(LSystem, EveryProductionTriedCountsItsBindings)
{
    // 3,000 stochastic productions of A(n) all apply and bind n (3,000
    // falsely conditioned ones are all tried): 33 ns each, hours within the
    // bound when only the one chosen counted.  The stochastic ones are
    // known before the first step.
    const std::string axiom = repeated("A(0)", 20),
                      stochastic = repeated("A(n) --> A(n+1) : 1\n", 3000);
    std::string conditioned;
    for (int k = 0; k < 3000; ++k) {
        conditioned += "A(n) : n < -" + std::to_string(k) + " --> A(n+1)\n";
    }
    int steps = 0;
    const auto counted = [&](const char*, double) { ++steps; };
    const LSystem sto = parseLSystem("Axiom: " + axiom + "\n" + stochastic, "sto.l");
    test::expectInputError([&] { derive(sto, 100, 1, kDefaultMaxModules, counted, 1e7); },
                           "sto.l: 100 steps would rewrite more than 1e+07", "3,000 stochastic");
    EXPECT_EQ(steps, 0);
    // 20 x 3,000 tries of 3 rewrites and conditions of 1.5: 270,000 a step.
    const LSystem cond = parseLSystem("Axiom: " + axiom + "\n" + conditioned, "cond.l");
    EXPECT_NO_THROW(derive(cond, 30, 1, kDefaultMaxModules, {}, 1e7));
    test::expectInputError([&] { derive(cond, 100, 1, kDefaultMaxModules, {}, 1e7); },
                           "cond.l: derivation step 3", "3,000 false conditions");
}

TEST(LSystem, AModuleRewrittenAtEveryStepCountsItsProductionsWork)
{
    // A(n) --> A(n+1) rewrites every A at every step whatever the string
    // becomes, and each costs its parameter's binding, evaluation and vector
    // (measured: 77 ns against 27 for A --> A): 8,000 of them over 100,000
    // steps ran past a minute inside the bound when each counted one
    // rewrite.  Now they are refused before the first step.
    const std::string axiom = repeated("A(0)", 1000);
    const LSystem sys = parseLSystem("Axiom: " + axiom + "\nA(n) --> A(n+1)\n", "count.l");
    int steps = 0;
    const auto counted = [&](const char*, double) { ++steps; };
    test::expectInputError([&] { derive(sys, 2000, 1, kDefaultMaxModules, counted, 1e7); },
                           "count.l: 2000 steps would rewrite more than 1e+07", "A(n) --> A(n+1)");
    EXPECT_EQ(steps, 0);
    EXPECT_EQ(derive(sys, 1000, 1, kDefaultMaxModules, {}, 1e7)[0].params[0], 1000.0);
    // So does a cycle of them, at its cheaper production's cost.
    const LSystem cycle =
        parseLSystem("Axiom: " + axiom + "\nA(n) --> B(n)\nB(n) --> A(n+1)\n", "cycle.l");
    test::expectInputError([&] { derive(cycle, 2000, 1, kDefaultMaxModules, counted, 1e7); },
                           "cycle.l: 2000 steps would rewrite more than 1e+07", "A --> B --> A");
    EXPECT_EQ(steps, 0);
    EXPECT_EQ(derive(cycle, 1000, 1, kDefaultMaxModules, {}, 1e7)[0].params[0], 500.0);
    // A condition may stop the rewrites: no refusal on a guess.
    const LSystem stops =
        parseLSystem("Axiom: " + axiom + "\nA(n) : n < 3 --> A(n+1)\n", "stops.l");
    EXPECT_EQ(derive(stops, 1000, 1, kDefaultMaxModules, {}, 1e7)[0].params[0], 3.0);
}

TEST(LSystem, TheWorkOfParameterExpressionsCountsAgainstTheBound)
{
    // A string that does not grow, each module's parameter a 20-term sum:
    // the rewrites alone stay far inside the bound (a million modules of
    // 19-term sums ran 45 minutes within it); the expressions' nodes count
    // half a rewrite each, before they are evaluated.
    const std::string sum = repeated("x", 20, "+");
    const std::string axiom = repeated("A(1)", 100);
    const LSystem sys =
        parseLSystem("Axiom: " + axiom + "\nA(x) --> A((" + sum + ") / 20)\n", "sums.l");
    // Per step: 100 rewrites and 100 x 41 nodes at half a rewrite, and the
    // module, parameter and vectors bound and made: 2,750 rewrites' work.
    EXPECT_NO_THROW(derive(sys, 36, 1, kDefaultMaxModules, {}, 1e5));
    EXPECT_THROW(derive(sys, 37, 1, kDefaultMaxModules, {}, 1e5), InputError);
    test::expectInputError([&] { derive(sys, 250, 1, kDefaultMaxModules, {}, 1e5); },
                           "sums.l: 250 steps would rewrite more than 100000 modules' work in all "
                           "(rewrites, context searches and parameter expressions",
                           "20-term sums for 250 steps");
}

TEST(LSystem, ExpressionsNestedBeyondTheBoundAreRefusedWithTheirLine)
{
    // Sums of 200,000 terms, 10,000 nested parentheses, 200,000 unary
    // minuses, long chains of powers: each would recurse once per term in
    // the parser, the evaluator or the tree's destruction (a crash, not an
    // error); each is refused with its line, in a #define and in a
    // production.  What people write (a sum of a hundred terms, twenty
    // parentheses) is kept.
    auto repeat = [](const std::string& piece, int n) {
        std::string out;
        for (int i = 0; i < n; ++i)
            out += piece;
        return out;
    };
    const std::string sum = "1" + repeat("+1", 200'000),
                      parens = repeat("(", 10'000) + "1" + repeat(")", 10'000),
                      minuses = repeat("-", 200'000) + "1", powers = "2" + repeat("^1", 5'000),
                      calls = repeat("sin(", 1'000) + "1" + repeat(")", 1'000);
    for (const std::string& e : {sum, parens, minuses, powers, calls}) {
        test::expectInputError(
            [&] { parseLSystem("#define D " + e + "\nAxiom: F(D)\n", "deep.l"); },
            "deep.l:1:", e.substr(0, 12));
        test::expectInputError(
            [&] { parseLSystem("#define D " + e + "\nAxiom: F(D)\n", "deep.l"); },
            "nests deeper than 200 levels", e.substr(0, 12));
        test::expectInputError(
            [&] { parseLSystem("Axiom: A(1)\nA(x) --> A(x+" + e + ")\n", "deep.l"); },
            "deep.l:2:", e.substr(0, 12));
    }
    const LSystem fine = parseLSystem("#define D " + repeat("(", 20) + "1" + repeat(")", 20) +
                                          " +" + repeat("+1", 100) + "\nAxiom: F(D)\n",
                                      "fine.l");
    ASSERT_EQ(fine.axiom.size(), 1u);
    ASSERT_EQ(fine.axiom[0].params.size(), 1u);
    EXPECT_EQ(fine.axiom[0].params[0], 101.0);
}

TEST(LSystem, ErrorsNameTheLineAndColumn)
{
    auto expectError = [](const std::string& text, const std::string& message) {
        test::expectInputError([&] { parseLSystem(text, "bad.l"); }, message, text);
    };
    expectError("Axiom: F[+F\n", "bad.l:1:12: 1 '[' without a matching ']'");
    expectError("Axiom: F]\n", "bad.l:1:9: ']' without a matching '['");
    expectError("Axiom: A\n/* ok */ A --> B /* never closed\nB --> C\n",
                "bad.l:2:18: a comment '/*' that is never closed with '*/'");
    expectError("Axiom: A\nA --> B[C\n", "bad.l:2:");
    expectError("Axiom: A(1)\nA(x) : x < --> A(x)\n", "bad.l:2:");
    expectError("Axiom: A(1)\nA(x) --> A(y)\n",
                "bad.l:2:12: 'y' is neither a parameter of the predecessor nor a #define");
    expectError("Axiom: A(1)\nA(x,y) --> A(x)\n",
                "bad.l:2:1: module A has 2 parameters here but 1 at line 1");
    expectError("Axiom: A(1)\nA(x) --> A(foo(x))\n", "unknown function 'foo'");
    expectError("Axiom: A\nA --> B : -1\n", "a probability must be positive");
    expectError("Axiom: A\nderivation lenght: 3\n",
                "bad.l:2:1: unknown line 'derivation lenght: 3'");
    expectError("A --> B\n", "bad.l: no 'Axiom:' line");
    expectError("Axiom: F(1,2)\n", "'F' takes at most one parameter");
}

// --- the turtle ---------------------------------------------------------------

void expectNear(const glm::dvec3& a, const glm::dvec3& b, const char* what)
{
    EXPECT_NEAR(a.x, b.x, 1e-12) << what;
    EXPECT_NEAR(a.y, b.y, 1e-12) << what;
    EXPECT_NEAR(a.z, b.z, 1e-12) << what;
}

Skeleton turtle(const std::string& text, int steps = 0)
{
    const LSystem sys = parseLSystem(text, "t.l");
    return interpretTurtle(sys, derive(sys, steps, 1, 100000));
}

TEST(Turtle, PlanarMovesMatchHandComputedPoints)
{
    // Up 1, turn left 90 (towards -x, seen from +z), forward 2, move 1 without
    // drawing, turn right 45, forward sqrt(2).
    const Skeleton s = turtle("angle: 90\nAxiom: F+F(2)f-(45)F(1.4142135623730951)\n");
    ASSERT_EQ(s.internodes.size(), 3u);
    expectNear(s.internodes[0].p0, {0, 0, 0}, "F0 start");
    expectNear(s.internodes[0].p1, {0, 1, 0}, "F0 end");
    expectNear(s.internodes[1].p1, {-2, 1, 0}, "F1 end");
    expectNear(s.internodes[2].p0, {-3, 1, 0}, "F2 start (after f)");
    expectNear(s.internodes[2].p1, {-4, 2, 0}, "F2 end");
    EXPECT_EQ(s.internodes[1].parent, 0);
    EXPECT_EQ(s.internodes[2].parent, 1);
}

TEST(Turtle, PitchRollBranchesAndWidth)
{
    // & pitches down towards U = -z; \ rolls, after which + turns about the new U.
    const Skeleton s = turtle("Axiom: !(0.2)F[&(90)F]!(0.1)[\\(90)+(90)F]|F\n");
    ASSERT_EQ(s.internodes.size(), 4u);
    expectNear(s.internodes[1].p1 - s.internodes[1].p0, {0, 0, -1}, "pitched down");
    // Rolled 90 about H: L = +x goes to U = -z, U to -L; + then turns H towards -L_new = ... = +z.
    expectNear(s.internodes[2].p1 - s.internodes[2].p0, {0, 0, 1}, "rolled then turned");
    expectNear(s.internodes[3].p1 - s.internodes[3].p0, {0, -1, 0}, "turned around");
    EXPECT_EQ(s.internodes[1].parent, 0);
    EXPECT_EQ(s.internodes[2].parent, 0);
    EXPECT_EQ(s.internodes[3].parent, 0);
    EXPECT_EQ(s.internodes[0].order, 0);
    EXPECT_EQ(s.internodes[1].order, 1);
    EXPECT_EQ(s.internodes[3].order, 0);
    EXPECT_DOUBLE_EQ(s.internodes[0].r0, 0.1);
    EXPECT_DOUBLE_EQ(s.internodes[2].r0, 0.05);  // the width set before '[' holds inside it
    EXPECT_DOUBLE_EQ(s.internodes[1].r0, 0.1);
    EXPECT_DOUBLE_EQ(s.internodes[3].r1, 0.05);
}

TEST(Turtle, DollarRollsTheLeftVectorToTheHorizontal)
{
    // After pitching and rolling, $ makes L horizontal (L.y = 0) and keeps H;
    // a following + then turns within the plane of H and the horizontal L.
    const Skeleton s = turtle("Axiom: &(30)/(40)F$+(90)F\n");
    ASSERT_EQ(s.internodes.size(), 2u);
    const glm::dvec3 H = s.internodes[0].p1 - s.internodes[0].p0,
                     turned = s.internodes[1].p1 - s.internodes[1].p0;
    // + by 90 gives H' = -L: horizontal, and perpendicular to H.
    EXPECT_NEAR(turned.y, 0.0, 1e-12);
    EXPECT_NEAR(glm::dot(turned, H), 0.0, 1e-12);
    // L = V x H / |V x H| with V = +y: H' = -L.
    expectNear(turned, -glm::normalize(glm::cross(glm::dvec3(0, 1, 0), H)), "H after $+");
}

TEST(Turtle, TropismBendsTheHeadingByItsDefinition)
{
    // ABOP 2.2: after each F, H turns towards T by e |H x T| about H x T.
    const Skeleton s = turtle("tropism: 1 0 0 0.3\nAxiom: FF\n");
    ASSERT_EQ(s.internodes.size(), 2u);
    expectNear(s.internodes[0].p1 - s.internodes[0].p0, {0, 1, 0}, "first F: straight");
    // |H x T| = 1 for H = +y, T = +x: H turns by 0.3 rad towards +x.
    expectNear(s.internodes[1].p1 - s.internodes[1].p0, {std::sin(0.3), std::cos(0.3), 0},
               "second F");
}

TEST(Turtle, BadLengthsAndWidthsAreRefused)
{
    EXPECT_THROW(turtle("Axiom: F(-1)\n"), InputError);
    EXPECT_THROW(turtle("Axiom: !(0)F\n"), InputError);
    EXPECT_THROW(turtle("width: 0.1\nwidth increment: 0.1\nAxiom: !F\n"), InputError);  // down to 0
}

TEST(Turtle, WidthStepsAndColourIndicesInBothForms)
{
    // ! and # without a parameter take and add the width increment (default:
    // a tenth of the initial width); with one they set the width.
    Skeleton s = turtle("width: 0.4\nAxiom: F!F!!F#F!(0.3)F#(0.2)F\n");
    ASSERT_EQ(s.internodes.size(), 6u);
    const double diameters[] = {0.4, 0.36, 0.28, 0.32, 0.3, 0.2};
    for (size_t i = 0; i < 6; ++i)
        EXPECT_NEAR(2.0 * s.internodes[i].r0, diameters[i], 1e-12) << i;
    s = turtle("width: 0.4\nwidth increment: 0.05\nAxiom: !F\n");
    EXPECT_NEAR(2.0 * s.internodes[0].r0, 0.35, 1e-12);
    // ' and ; add one to the colour index, or set it; index 0 is the bark (no
    // colour of its own); "color:" overrides the palette.
    s = turtle("color: 2 0.1 0.2 0.3\nAxiom: F'F;F;(7)F'(0)F[;(2)F]F\n");
    ASSERT_EQ(s.internodes.size(), 7u);
    const LSystem sys = parseLSystem("color: 2 0.1 0.2 0.3\nAxiom: F\n", "t.l");
    EXPECT_FALSE(s.internodes[0].colour);
    EXPECT_EQ(*s.internodes[1].colour, paletteColour(sys, 1));
    EXPECT_EQ(*s.internodes[2].colour, glm::dvec3(0.1, 0.2, 0.3));
    EXPECT_EQ(*s.internodes[3].colour, paletteColour(sys, 7));
    EXPECT_FALSE(s.internodes[4].colour);
    EXPECT_EQ(*s.internodes[5].colour, glm::dvec3(0.1, 0.2, 0.3));
    EXPECT_FALSE(s.internodes[6].colour);  // the index is part of the state ']' restores
    EXPECT_NE(paletteColour(sys, 1), paletteColour(sys, 3));
    EXPECT_THROW(turtle("Axiom: ;(2.5)F\n"), InputError);
    EXPECT_THROW(turtle("Axiom: '(-1)F\n"), InputError);
}

TEST(Turtle, PolygonsBecomeLeafBladesFittedToThem)
{
    // A 2 x 1 rectangle drawn by f moves in the turtle's H-L plane (seen from
    // +z: up 2, left 1, down 2, back): its blade runs from the start to the
    // far corner (-1, 2, 0), as wide as the farthest vertex from that
    // diagonal, across the normal +-z; the colour of its index; F inside
    // draws no internode.
    const Skeleton s = turtle("angle: 90\nAxiom: F;(4){f(2)+f(1)+F(2)+f(1)}\n");
    ASSERT_EQ(s.internodes.size(), 1u);
    ASSERT_EQ(s.organs.size(), 1u);
    const Organ& leaf = s.organs[0];
    EXPECT_EQ(leaf.kind, Organ::Kind::Leaf);
    expectNear(leaf.p0, {0, 1, 0}, "blade base: where '{' started");
    expectNear(leaf.p1, {-1, 3, 0}, "blade tip: the farthest vertex");
    EXPECT_NEAR(leaf.radius, 2.0 / std::sqrt(5.0),
                1e-12);  // the other corners' distance from the diagonal
    EXPECT_NEAR(std::abs(leaf.normal.z), 1.0, 1e-12);
    EXPECT_EQ(leaf.colour, paletteColour(parseLSystem("Axiom: F\n", "t.l"), 4));
    // '.' records vertices explicitly; G and g move without recording.
    const Skeleton dots = turtle("angle: 90\nAxiom: {.g(2).+g(1).+g(2).}\n");
    ASSERT_EQ(dots.organs.size(), 1u);
    expectNear(dots.organs[0].p1, {-1, 2, 0}, "dots: far corner");
    EXPECT_THROW(turtle("angle: 90\nAxiom: {g(2)+g(1)+g(2)}\n"),
                 InputError);  // g records nothing: one vertex
}

TEST(Turtle, ABOPsBushIsAcceptedAndEveryLeafDrawn)
{
    // ABOP figure 1.25 as printed: ! without a parameter, ' for the colour,
    // polygons for the leaves.  Every L of the derived string is one leaf.
    const LSystem sys = loadLSystem(CAMBIUM_SOURCE_DIR "/examples/lsystems/bush.l");
    const ModuleString str = derive(sys, sys.derivationLength, sys.seed, kDefaultMaxModules);
    const Skeleton s = interpretTurtle(sys, str);
    const size_t leaves = size_t(
        std::count_if(str.begin(), str.end(), [](const Module& m) { return m.name == '{'; }));
    EXPECT_GT(leaves, 1000u);
    EXPECT_EQ(s.organs.size(), leaves);
    // Each order thinner by the width increment (0.1).
    double thinnest = 1e9;
    for (const Internode& n : s.internodes)
        thinnest = std::min(thinnest, 2.0 * n.r0);
    EXPECT_NEAR(thinnest, 0.8 - 6 * 0.1, 1e-9);  // the A s of step 7 have not drawn yet
}

TEST(Turtle, WhatIsOutsideTheSupportedSubsetIsRefused)
{
    EXPECT_THROW(turtle("Axiom: F~F\n"), InputError);     // predefined surfaces
    EXPECT_THROW(turtle("Axiom: F@F\n"), InputError);     // @ commands
    EXPECT_THROW(turtle("Axiom: {f}\n"), InputError);     // fewer than 3 vertices
    EXPECT_THROW(turtle("Axiom: {ff|f}\n"), InputError);  // no area
    EXPECT_THROW(turtle("Axiom: {f+f+f\n"), InputError);  // never closed
    EXPECT_THROW(turtle("Axiom: f}\n"), InputError);
    EXPECT_THROW(turtle("Axiom: f.\n"), InputError);  // a vertex outside a polygon
    EXPECT_THROW(parseLSystem("Axiom: F,F\n", "t.l"), InputError);
    EXPECT_THROW(parseLSystem("Axiom: F\nhomomorphism\nF --> G\n", "t.l"), InputError);
    EXPECT_THROW(parseLSystem("consider: F\nAxiom: F\n", "t.l"), InputError);
    EXPECT_THROW(parseLSystem("color: 300 1 1 1\nAxiom: F\n", "t.l"), InputError);
}

}  // namespace

namespace {

using namespace cambium;

TEST(Turtle, ALeafAndAColouredBranchBakeIntoTheFieldWithTheirColours)
{
    // A green blade beside a red-indexed branch, beyond each other's
    // supports: inside each, the field is above the threshold and the colour
    // is its index's.
    const LSystem sys = parseLSystem(
        "angle: 90\nwidth: 0.2\nAxiom: F;(10)F[+(90);(4)f(4){f(2)+f(1)+f(2)+f(1)}]\n", "t.l");
    const Skeleton sk = interpretTurtle(sys, derive(sys, 0, 1, 1000));
    ASSERT_EQ(sk.organs.size(), 1u);
    BlobTree tree = buildTree(sk);
    const ReferenceEvaluator eval(tree);
    const Organ& leaf = sk.organs[0];
    const FieldSample inLeaf = eval.sample(0.5 * (leaf.p0 + leaf.p1));
    EXPECT_GT(inLeaf.value, tree.threshold());
    const glm::dvec3 green = paletteColour(sys, 4), red = paletteColour(sys, 10);
    EXPECT_LT(glm::length(inLeaf.color - green), 1e-6);
    const FieldSample inBranch = eval.sample({0.0, 1.7, 0.0});  // on the second F's axis
    EXPECT_GT(inBranch.value, tree.threshold());
    EXPECT_LT(glm::length(inBranch.color - red), 1e-6);
}

}  // namespace
