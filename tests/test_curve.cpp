// Graphically defined functions: through their points, linear or smooth
// without overshoot and C1, clamped outside [0, 1], refused with their JSON
// path when malformed; the growth parameter files that hold them.
#include "model/curve.h"
#include "model/growth_params.h"

#include "core/error.h"
#include "core/json.h"
#include "test_util.h"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <fstream>
#include <functional>
#include <iterator>
#include <sstream>

namespace {

using namespace cambium;
using json = nlohmann::json;

TEST(Curve, LinearIsThePolyline)
{
    const Curve c = curveFromJson(json::parse("[[0, 0], [0.25, 1], [1, 0.5]]"), "G");
    EXPECT_DOUBLE_EQ(c(0.0), 0.0);
    EXPECT_DOUBLE_EQ(c(0.25), 1.0);
    EXPECT_DOUBLE_EQ(c(1.0), 0.5);
    EXPECT_DOUBLE_EQ(c(0.125), 0.5);
    EXPECT_DOUBLE_EQ(c(0.625), 0.75);
    EXPECT_DOUBLE_EQ(c(-3.0), 0.0);  // clamped to the domain
    EXPECT_DOUBLE_EQ(c(7.0), 0.5);
    EXPECT_DOUBLE_EQ(curveFromJson(json(0.3), "G")(0.7), 0.3);  // a number is a constant
}

TEST(Curve, SmoothPassesThroughItsPointsWithoutOvershootAndIsC1)
{
    const json j = json::parse(R"({"points": [[0, 0], [0.2, 0.1], [0.3, 0.9], [0.7, 1.0], [1, 0.2]],
                                   "interpolation": "smooth"})");
    const Curve c = curveFromJson(j, "G");
    for (const auto& [x, y] : c.points())
        EXPECT_NEAR(c(x), y, 1e-12);
    const auto& p = c.points();
    for (size_t i = 0; i + 1 < p.size(); ++i) {
        const double lo = std::min(p[i].second, p[i + 1].second),
                     hi = std::max(p[i].second, p[i + 1].second);
        for (int k = 0; k <= 1000; ++k) {
            const double x = p[i].first + (p[i + 1].first - p[i].first) * k / 1000.0;
            ASSERT_GE(c(x), lo - 1e-12) << "x " << x;
            ASSERT_LE(c(x), hi + 1e-12) << "x " << x;
        }
    }
    // C1: one-sided slopes agree at the interior points.
    const double e = 1e-6;
    for (size_t i = 1; i + 1 < p.size(); ++i) {
        const double x = p[i].first;
        const double left = (c(x) - c(x - e)) / e, right = (c(x + e) - c(x)) / e;
        EXPECT_NEAR(left, right, 1e-3 * std::max(1.0, std::abs(left))) << "at x " << x;
    }
    // The linear curve through the same points has corners there.
    const Curve lin = curveFromJson(j["points"], "G");
    EXPECT_GT(std::abs((lin(0.3) - lin(0.3 - e)) / e - (lin(0.3 + e) - lin(0.3)) / e), 1.0);
}

TEST(Curve, MalformedCurvesAreNamedByTheirPath)
{
    auto expectError = [](const char* text, const std::string& message) {
        test::expectInputError([&] { curveFromJson(json::parse(text), "curves.Gh"); }, message,
                               text);
    };
    expectError("[[0, 0]]", "curves.Gh: a curve needs at least two points");
    expectError("[[0, 0], [0.5, 1], [0.5, 2], [1, 0]]",
                "curves.Gh: the x of point 2 (0.5) must exceed");
    expectError("[[0.1, 0], [1, 1]]", "curves.Gh: the points must span x from 0 to 1");
    expectError("[[0, 0], [1]]", "curves.Gh[1]: expected [x, y]");
    expectError(R"({"points": [[0, 0], [1, "a"]]})", "curves.Gh.points[1]: expected [x, y]");
    expectError(R"({"points": [[0, 0], [1, 1]], "interpolation": "cubic"})",
                "curves.Gh.interpolation: must be \"linear\" or \"smooth\"");
    expectError(R"({"points": [[0, 0], [1, 1]], "smoothing": 1})",
                "curves.Gh.smoothing: unknown key (a curve has");
    expectError(R"({"pionts": [[0, 0], [1, 1]]})",
                "curves.Gh.pionts: unknown key (did you mean 'points'?)");
    expectError(R"({"interpolation": "smooth"})", "curves.Gh.points: missing");
    expectError("\"up\"", "curves.Gh: expected a number, an array of [x, y] points");
}

TEST(GrowthParameters, TheBundledPopulusReads)
{
    const GrowthParameters p =
        loadGrowthParameters(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json");
    EXPECT_EQ(p.years, 27);
    EXPECT_DOUBLE_EQ(p.phyllotaxis, 137.5);
    EXPECT_DOUBLE_EQ(p.longestSeparation, 40.0);
    EXPECT_EQ(p.Gh.interpolation(), Curve::Interpolation::Smooth);
    EXPECT_NEAR(p.Gh(1.0), 1.0, 1e-12);
    EXPECT_GT(p.Ga(1.0), p.Ga(0.0));  // long branches live longer
    EXPECT_LT(p.Go2(0.0), 0.0);       // long branches first bend down: the S curve
    EXPECT_GT(p.Go2(1.0), 0.0);
}

TEST(GrowthParameters, MalformedFilesAreNamedByFileAndPath)
{
    std::string good;
    {
        std::ifstream in(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json");
        std::stringstream s;
        s << in.rdbuf();
        good = s.str();
    }
    auto edited = [&](const std::function<void(json&)>& edit) {
        json j = json::parse(good);
        edit(j);
        return j.dump();
    };
    auto expectError = [](const std::string& text, const std::string& message) {
        test::expectInputError([&] { parseGrowthParameters(text, "tree.json"); }, message, message);
    };
    expectError("{", "tree.json: JSON syntax error: parse error at line 1, column 2");
    expectError("{\"years\": 3, \"years\": 4}", "tree.json: duplicate key 'years'");
    expectError(edited([](json& j) { j["yaers"] = 3; }), "tree.json: yaers: unknown key");
    expectError(edited([](json& j) { j["years"] = 2.5; }),
                "tree.json: years: must be a whole number");
    expectError(edited([](json& j) { j["years"] = 0; }),
                "tree.json: years: must be between 1 and 1000");
    expectError(edited([](json& j) { j["tip_radius"] = 1.0; }),
                "tree.json: tip_radius: must not exceed base_radius");
    expectError(edited([](json& j) {
                    j["bark"] = json::array({1, 2});
                }),
                "tree.json: bark: must be [r, g, b]");
    expectError(edited([](json& j) { j["curves"].erase("Gm"); }), "tree.json: curves.Gm: missing");
    expectError(edited([](json& j) { j["curves"]["Gx"] = 1; }),
                "tree.json: curves.Gx: unknown curve");
    expectError(edited([](json& j) { j["curves"]["Gh"] = json::parse("[[0, 0], [1, 2]]"); }),
                "tree.json: curves.Gh: values must be between 0 and 1");
    expectError(edited([](json& j) { j["curves"]["Gs1"] = json::parse("[[0, 0], [0.9, 1]]"); }),
                "tree.json: curves.Gs1: the points must span x from 0 to 1");
    expectError(edited([](json& j) { j.erase("curves"); }), "tree.json: curves: missing");
    EXPECT_THROW(loadGrowthParameters("/nonexistent/tree.json"), InputError);
}

}  // namespace

TEST(GrowthParameters, ACurveEditChangesOnlyItsPointsAndIsCheckedByTheReader)
{
    std::ifstream in(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json");
    std::stringstream buffer;
    buffer << in.rdbuf();
    // A comment, and a curve given as a plain array, that the edit keeps.
    std::string text = buffer.str();
    text.insert(text.find("\"curves\""), "// tuned by hand: \"Gh\": [[0, 1]]\n  ");
    const std::string gm = "\"Gm\": {\"points\": [[0, 2], [1, 12]], \"interpolation\": \"linear\"}";
    ASSERT_NE(text.find(gm), std::string::npos);
    text.replace(text.find(gm), gm.size(), "\"Gm\": [[0, 2], /* few */ [1, 12]]");
    const std::vector<std::pair<double, double>> points = {{0, 0.1}, {0.5, 0.55}, {1, 0.9}};
    const std::string edited = withCurvePoints(text, "tree.json", "Gh", points);
    // Only the points' text differs.
    const std::string before = R"([[0, 0.04], [0.3, 0.45], [0.6, 0.8], [1, 1]])";
    const std::string after = "[[0, 0.1], [0.5, 0.55], [1, 0.9]]";
    std::string expected = text;
    expected.replace(expected.find(before), before.size(), after);
    EXPECT_EQ(edited, expected);
    const GrowthParameters p = parseGrowthParameters(edited, "tree.json");
    EXPECT_EQ(p.Gh.points(), points);
    EXPECT_EQ(p.Gh.interpolation(), Curve::Interpolation::Smooth);
    // A plain array stays one (linear), its comment replaced with it.
    const std::string gmEdited = withCurvePoints(text, "tree.json", "Gm", {{0, 3}, {1, 9}});
    EXPECT_NE(gmEdited.find("\"Gm\": [[0, 3], [1, 9]]"), std::string::npos);
    EXPECT_DOUBLE_EQ(parseGrowthParameters(gmEdited, "tree.json").Gm(0.5), 6.0);
    // Refused, naming the file and the path: out of range, x not increasing,
    // not spanning [0, 1], no such curve, a file that does not read.
    const struct {
        std::string key;
        std::vector<std::pair<double, double>> points;
        std::string text, expected;
    } bad[] = {
        {"Gh", {{0, 0}, {1, 1.5}}, text, "curves.Gh: values must be between 0 and 1"},
        {"Gh",
         {{0, 0}, {0.6, 0.5}, {0.4, 0.6}, {1, 1}},
         text,
         "curves.Gh.points: the x of point 2"},
        {"Gs1", {{0.1, 0}, {1, 1}}, text, "curves.Gs1.points: the points must span x from 0 to 1"},
        {"Gx", {{0, 0}, {1, 1}}, text, "curves.Gx: no such curve (did you mean 'Gh'?)"},
        {"Gh", {{0, 0}, {1, 1}}, text.substr(0, text.size() / 2), "tree.json: JSON syntax error"},
    };
    for (const auto& b : bad) {
        try {
            withCurvePoints(b.text, "tree.json", b.key, b.points);
            ADD_FAILURE() << b.expected;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(b.expected), std::string::npos) << e.what();
        }
    }
}

TEST(Json, AValueSpanSkipsStringsAndCommentsThatLookLikeKeys)
{
    const std::string text = R"({"a": "{\"b\": 1}", /* "b": 2 */ // "b": 3
  "c": {"d": [1, {"e": 2}], "b": {"x": -4.5e1 } }, "b": [ 5 ]})";
    auto spanText = [&](const std::vector<std::string>& keys) {
        const auto span = jsonValueSpan(text, keys);
        return span ? text.substr(span->first, span->second - span->first) : "(none)";
    };
    EXPECT_EQ(spanText({"b"}), "[ 5 ]");
    EXPECT_EQ(spanText({"c", "b"}), "{\"x\": -4.5e1 }");
    EXPECT_EQ(spanText({"c", "b", "x"}), "-4.5e1");
    EXPECT_EQ(spanText({"a"}), R"("{\"b\": 1}")");
    EXPECT_EQ(spanText({"c", "e"}), "(none)");
    EXPECT_EQ(spanText({"a", "b"}), "(none)");
    // Keys as the parser reads them (escapes, quotes inside), comments
    // between a key and its colon, empty objects, a value that is no object.
    const std::string keys = R"({"q\"b": 1, "\u0062" /* c */ : {}, "e": {"f": []}, "s": "x"})";
    auto span = [&](const std::vector<std::string>& path) {
        const auto at = jsonValueSpan(keys, path);
        return at ? keys.substr(at->first, at->second - at->first) : "(none)";
    };
    EXPECT_EQ(span({"q\"b"}), "1");
    EXPECT_EQ(span({"b"}), "{}");
    EXPECT_EQ(span({"b", "x"}), "(none)");
    EXPECT_EQ(span({"e", "f"}), "[]");
    EXPECT_EQ(span({"s", "x"}), "(none)");
    EXPECT_EQ(jsonValueSpan("[1, 2]", {"a"}), std::nullopt);
    EXPECT_EQ(jsonValueSpan("{}", {"a"}), std::nullopt);
    // A growth file whose curve's key is written with an escape is edited
    // where the parser reads it.
    std::ifstream in(CAMBIUM_SOURCE_DIR "/examples/populus/populus.json");
    std::string growth((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t gh = growth.find("\"Gh\"");
    ASSERT_NE(gh, std::string::npos);
    growth.replace(gh, 4, "\"G\\u0068\"");
    const std::string edited = withCurvePoints(growth, "tree.json", "Gh", {{0, 0.2}, {1, 1}});
    EXPECT_DOUBLE_EQ(parseGrowthParameters(edited, "tree.json").Gh(0.0), 0.2);
}
