// The benchmark skeleton generator: the size asked for, a well-formed tree
// (sequential ids, children starting where their parent ends), the pipe-model
// radii and the length ratios it promises; the Mersenne Twister against
// Python's and the standard library's streams; and, when the original script
// is at hand, the text against the script's to the byte.
#include "bench/tree_generator.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/random.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace {

using namespace cambium;

/// One line of the skeleton text: the printed fields as written, and as numbers.
struct Line {
    long long id = 0, parent = 0;
    std::array<std::string, 8> text;  ///< x0 y0 z0 x1 y1 z1 r0 r1 as printed
    std::array<double, 8> value{};
    double r0() const { return value[6]; }
    double r1() const { return value[7]; }
    double length() const
    {
        return std::hypot(value[3] - value[0], value[4] - value[1], value[5] - value[2]);
    }
};

std::vector<Line> parse(const std::string& skeleton)
{
    std::vector<Line> lines;
    std::istringstream in(skeleton);
    std::string row;
    while (std::getline(in, row)) {
        if (row.empty() || row[0] == '#')
            continue;
        std::istringstream fields(row);
        Line l;
        fields >> l.id >> l.parent;
        for (size_t k = 0; k < 8; ++k) {
            fields >> l.text[k];
            l.value[k] = std::stod(l.text[k]);
        }
        EXPECT_TRUE(fields && fields.peek() == EOF) << "not ten fields: " << row;
        lines.push_back(l);
    }
    return lines;
}

std::vector<Line> generate(int internodes)
{
    TreeGeneratorOptions options;
    options.internodes = internodes;
    return parse(generateBenchSkeleton(options));
}

/// Half a unit in the sixth decimal, per printed coordinate.
constexpr double kPrint = 0.5e-6;

TEST(TreeGenerator, WritesTheInternodeCountAskedFor)
{
    for (int n : {1, 7, 1000, 20000})
        EXPECT_EQ(generate(n).size(), size_t(n)) << n;
    TreeGeneratorOptions none;
    none.internodes = 0;
    EXPECT_EQ(generateBenchSkeleton(none), "# id parent x0 y0 z0 x1 y1 z1 r0 r1\n");
}

TEST(TreeGenerator, IsATreeWhoseChildrenStartWhereTheirParentEnds)
{
    const std::vector<Line> tree = generate(20000);
    ASSERT_EQ(tree.size(), 20000u);
    EXPECT_EQ(tree[0].parent, -1);
    for (size_t i = 0; i < tree.size(); ++i) {
        ASSERT_EQ(tree[i].id, (long long)i);
        if (i == 0)
            continue;
        ASSERT_GE(tree[i].parent, 0) << "a second root at " << i;
        ASSERT_LT(tree[i].parent, tree[i].id);
        const Line& parent = tree[size_t(tree[i].parent)];
        for (size_t k = 0; k < 3; ++k)
            EXPECT_EQ(tree[i].text[k], parent.text[k + 3])
                << "internode " << i << " coordinate " << k;
    }
}

/// Where each internode sits in its family: children are queued together,
/// the apical first, so a parent's children have consecutive ids and the
/// first of them continues the parent's axis (same branch order) while the
/// rest are laterals (one order higher).
struct Lineage {
    std::vector<bool> apical;
    std::vector<int> order;
};

Lineage lineage(const std::vector<Line>& tree)
{
    Lineage l{std::vector<bool>(tree.size(), true), std::vector<int>(tree.size(), 0)};
    for (size_t i = 1; i < tree.size(); ++i) {
        l.apical[i] = tree[i - 1].parent != tree[i].parent;
        l.order[i] = l.order[size_t(tree[i].parent)] + (l.apical[i] ? 0 : 1);
    }
    return l;
}

/// Laterals per node at a branch order (the defaults: two, one from order 6).
int lateralsAt(int order)
{
    return order < 6 ? 2 : 1;
}

TEST(TreeGenerator, GrowsBreadthFirstWithTwoLateralsBelowOrderSix)
{
    const std::vector<Line> tree = generate(20000);
    const Lineage l = lineage(tree);
    int families = 0;
    for (size_t i = 1; i < tree.size();) {
        const long long parent = tree[i].parent;
        ASSERT_TRUE(i == 1 || parent > tree[i - 1].parent)
            << "parents out of breadth-first order at " << i;
        size_t end = i;
        while (end < tree.size() && tree[end].parent == parent)
            ++end;
        if (end < tree.size()) {  // only the last family may be cut short
            EXPECT_EQ(int(end - i), 1 + lateralsAt(l.order[size_t(parent)]))
                << "children of " << parent;
            ++families;
        }
        i = end;
    }
    EXPECT_GT(families, 19999 / 3) << "families of two and three cover the tree";
    EXPECT_GT(*std::max_element(l.order.begin(), l.order.end()), 6)
        << "the single-lateral orders are reached";
}

TEST(TreeGenerator, RadiiFollowThePipeModel)
{
    const std::vector<Line> tree = generate(20000);
    const Lineage l = lineage(tree);
    EXPECT_EQ(tree[0].text[6], "0.250000");
    bool thinnedToTheFloor = false;
    for (size_t i = 0; i < tree.size(); ++i) {
        const Line& n = tree[i];
        EXPECT_GE(n.r0(), 0.012);
        EXPECT_GE(n.r1(), 0.012);
        thinnedToTheFloor = thinnedToTheFloor || n.text[7] == "0.012000";
        // Thick internodes keep 55 % of their cross-section, thin ones keep
        // their radius.  The printed r0 is off by up to half a unit of the
        // sixth decimal, so close to the threshold either branch may hold.
        const double thinned = std::max(n.r0() * std::sqrt(0.55), 0.012);
        if (std::abs(n.r0() - 0.016) <= kPrint)
            EXPECT_TRUE(std::abs(n.r1() - thinned) <= 2 * kPrint ||
                        std::abs(n.r1() - n.r0()) <= 2 * kPrint);
        else
            EXPECT_NEAR(n.r1(), n.r0() > 0.016 ? thinned : n.r0(), 2 * kPrint) << "internode " << i;
        if (i == 0)
            continue;
        const Line& parent = tree[size_t(n.parent)];
        if (l.apical[i]) {
            // The apical child carries on at the radius its parent ended with.
            EXPECT_EQ(n.text[6], parent.text[7]) << "internode " << i;
        } else {
            // A lateral gets an equal part of the other 45 % of the cross-section.
            const int laterals = lateralsAt(l.order[size_t(n.parent)]);
            EXPECT_NEAR(n.r0(), std::max(parent.r0() * std::sqrt(0.45 / laterals), 0.012),
                        2 * kPrint)
                << "internode " << i;
        }
    }
    EXPECT_TRUE(thinnedToTheFloor) << "20000 internodes reach the 12 mm floor";
}

TEST(TreeGenerator, ApicalLengthsShrinkBy092AndLateralsBy07)
{
    const std::vector<Line> tree = generate(20000);
    const Lineage l = lineage(tree);
    // Each printed coordinate is off by up to half a unit, a difference of two
    // by up to one, so a length by up to sqrt(3) units; the parent's length
    // enters scaled by at most 0.92.
    const double slack = (1.0 + 0.92) * std::sqrt(3.0) * 2 * kPrint + 1e-12;
    EXPECT_NEAR(tree[0].length(), 10.0 / 12.0, slack);
    for (size_t i = 1; i < tree.size(); ++i) {
        const Line& parent = tree[size_t(tree[i].parent)];
        EXPECT_NEAR(tree[i].length(), parent.length() * (l.apical[i] ? 0.92 : 0.7), slack)
            << "internode " << i << (l.apical[i] ? " (apical)" : " (lateral)");
    }
}

TEST(TreeGenerator, RefusesNodesWithoutLaterals)
{
    TreeGeneratorOptions options;
    options.laterals = 0;
    EXPECT_THROW(generateBenchSkeleton(options), InputError);
}

TEST(Random, SeedPythonGivesPythonsRandomStream)
{
    // random.Random(1).random(), three times; random.Random(42).random();
    // random.Random(0).random() (CPython 3.11).
    Mt19937 rng;
    rng.seedPython(1);
    EXPECT_EQ(rng.random01(), 0.13436424411240122);
    EXPECT_EQ(rng.random01(), 0.8474337369372327);
    EXPECT_EQ(rng.random01(), 0.763774618976614);
    rng.seedPython(42);
    EXPECT_EQ(rng.random01(), 0.6394267984578837);
    rng.seedPython(0);
    EXPECT_EQ(rng.random01(), 0.8444218515250481);
    // random.Random(1).uniform(-0.08, 0.08), then .uniform(-10, 10).
    rng.seedPython(1);
    EXPECT_EQ(rng.uniform(-0.08, 0.08), -0.058501720942015806);
    EXPECT_EQ(rng.uniform(-10.0, 10.0), 6.9486747387446535);
}

TEST(Random, SeedGivesStdMt19937sStream)
{
    for (uint32_t seed : {5489u, 0u, 1u, 4294967295u}) {
        Mt19937 ours;
        ours.seed(seed);
        std::mt19937 theirs(seed);
        for (int i = 0; i < 2000; ++i)  // more than three twists of the state
            ASSERT_EQ(ours.next(), theirs()) << "seed " << seed << " draw " << i;
    }
    Mt19937 unseeded;
    std::mt19937 standard;
    EXPECT_EQ(unseeded.next(), standard());
}

TEST(Random, UniformRealMatchesLibstdcxx)
{
#if defined(__GLIBCXX__)
    // The functions copy libstdc++'s arithmetic; on libstdc++ the two agree
    // draw for draw, which is what makes the numbers portable elsewhere.
    for (const auto& [a, b] : {std::pair{0.0, 1.0}, std::pair{0.0, 7.3}, std::pair{-2.5, 7.3}}) {
        std::mt19937_64 ours(5), theirs(5);
        std::uniform_real_distribution<double> u(a, b);
        for (int i = 0; i < 10000; ++i) {
            const double x = uniformReal(ours, a, b);
            ASSERT_EQ(x, u(theirs)) << "draw " << i << " of [" << a << ", " << b << ")";
            ASSERT_GE(x, a);
            ASSERT_LE(x, b);
        }
    }
    std::mt19937_64 ours(11), theirs(11);
    std::uniform_real_distribution<double> canonical(0.0, 1.0);
    for (int i = 0; i < 10000; ++i) {
        const double x = uniformCanonical(ours);
        ASSERT_EQ(x, canonical(theirs)) << "draw " << i;
        ASSERT_LT(x, 1.0);
    }
#else
    GTEST_SKIP() << "the reference is libstdc++'s uniform_real_distribution";
#endif
}

/// The standard output of a shell command, or false when it did not exit 0.
bool runCommand(const std::string& command, std::string& output)
{
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe)
        return false;
    output.clear();
    char buffer[1 << 16];
    size_t n;
    while ((n = std::fread(buffer, 1, sizeof buffer, pipe)) > 0)
        output.append(buffer, n);
    return ::pclose(pipe) == 0;
}

TEST(TreeGenerator, IsTheBenchmarksTreeToTheByte)
{
    // FNV-1a of the outside reference's output (../shared/bench/gen_skeleton.py
    // --internodes N, python3 3.11) for the benchmarks' two trees: pinned, so
    // that every build measures the same workload without the script.
    const std::pair<int, std::pair<size_t, uint64_t>> trees[] = {
        {1000, {81221, 0xb93bbdffef898269ull}}, {20000, {1680941, 0x0c2c6b800fa9606cull}}};
    for (const auto& [n, expected] : trees) {
        TreeGeneratorOptions o;
        o.internodes = n;
        const std::string text = generateBenchSkeleton(o);
        EXPECT_EQ(text.size(), expected.first) << n << " internodes";
        EXPECT_EQ(fnv1a64(text), expected.second) << n << " internodes";
    }
}

TEST(TreeGenerator, MatchesTheReferenceScriptToTheByte)
{
    // The original Python generator is not part of the project; point
    // CAMBIUM_REFERENCE_GENERATOR at it to compare against it.
    const char* script = std::getenv("CAMBIUM_REFERENCE_GENERATOR");
    if (!script || !*script)
        GTEST_SKIP() << "CAMBIUM_REFERENCE_GENERATOR is not set (the path of gen_skeleton.py)";
    if (!std::filesystem::is_regular_file(script))
        GTEST_SKIP() << "CAMBIUM_REFERENCE_GENERATOR names no file: " << script;
    std::string quoted = "'";
    for (const char c : std::string(script))
        quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
    quoted += "'";
    std::string version;
    if (!runCommand("python3 --version 2>/dev/null", version))
        GTEST_SKIP() << "python3 does not run";

    for (int n : {1000, 20000}) {
        std::string reference;
        ASSERT_TRUE(
            runCommand("python3 " + quoted + " --internodes " + std::to_string(n), reference))
            << "the reference generator failed for " << n << " internodes";
        TreeGeneratorOptions options;
        options.internodes = n;
        const std::string ours = generateBenchSkeleton(options);
        ASSERT_EQ(ours.size(), reference.size()) << n << " internodes";
        const auto mismatch = std::mismatch(ours.begin(), ours.end(), reference.begin());
        EXPECT_TRUE(mismatch.first == ours.end())
            << n << " internodes: the texts differ from byte " << (mismatch.first - ours.begin());
    }
}

}  // namespace
