// The JSON scene format: good scenes load, every malformed scene gets one
// message naming the file, the JSON path of the bad node and the problem.
#include "blobtree/scene_io.h"
#include "blobtree/stats.h"
#include "core/error.h"

#include <gtest/gtest.h>

#include <filesystem>

namespace {

using namespace cambium;

std::string errorOf(const std::string& text)
{
    try {
        parseScene(text, "bad.json");
    } catch (const InputError& e) {
        return e.what();
    }
    return "(no error)";
}

TEST(SceneIo, ReadsTheIssueExample)
{
    const BlobTree tree = parseScene(R"({ "threshold": 0.5,
      "root": { "type": "blend", "children": [
          { "type": "sphere", "center": [0, 0, 0], "radius": 1.0 },
          { "type": "cone", "p0": [0, 0, 0], "p1": [0, 2, 0], "r0": 0.3, "r1": 0.1, "color": [0.4, 0.3, 0.2] } ] } })",
                                     "example.json");
    const TreeStats s = computeStats(tree);
    EXPECT_EQ(s.primitives, 2u);
    EXPECT_EQ(s.operators, 1u);
    EXPECT_EQ(s.countByType.at(NodeType::SPHERE), 1u);
    EXPECT_EQ(s.countByType.at(NodeType::CONE), 1u);
    EXPECT_EQ(s.depth, 2);
    EXPECT_EQ(tree.node(1).shade, glm::dvec3(0.4, 0.3, 0.2));
    // Supports: sphere radius 1 -> 2; the cone reaches 2 r0 = 0.6 past its tip.
    EXPECT_NEAR(s.bounds.lo.x, -2.0, 1e-12);
    EXPECT_NEAR(s.bounds.hi.y, 2.6, 1e-12);
}

TEST(SceneIo, EveryBundledExampleLoads)
{
    int n = 0;
    for (const auto& e : std::filesystem::directory_iterator(CAMBIUM_SOURCE_DIR "/examples"))
        if (e.path().extension() == ".json") {
            SCOPED_TRACE(e.path().string());
            const BlobTree tree = loadScene(e.path().string());
            EXPECT_FALSE(computeStats(tree).bounds.empty());
            ++n;
        }
    EXPECT_GE(n, 3);
}

struct BadCase {
    const char* text;
    const char* expected;  // substring of the message
};

class MalformedScene : public ::testing::TestWithParam<BadCase> {};

TEST_P(MalformedScene, GetsAMessageWithThePathAndTheProblem)
{
    const std::string message = errorOf(GetParam().text);
    EXPECT_NE(message.find("bad.json"), std::string::npos) << message;
    EXPECT_NE(message.find(GetParam().expected), std::string::npos) << message;
}

#define CONE(extra) \
    R"({"type": "cone", "p0": [0,0,0], "p1": [0,1,0], "r0": 0.3, "r1": 0.1)" extra "}"

INSTANTIATE_TEST_SUITE_P(
    Cases, MalformedScene,
    ::testing::Values(
        BadCase{
            R"({"root": {"type": "blend", "children": [{"type": "sphere", "center": [0,0,0], "radius": 1},
                 {"type": "cone", "p0": [0,0,0], "p1": [0,2,0], "r0": -0.3, "r1": 0.1}]}})",
            "root.children[1].r0: must be greater than 0 (got -0.3)"},
        BadCase{
            R"({"root": {"type": "blend", "children": [{"type": "cone", "p0": [0,0,0], "p1": [0,2,0], "r1": 0.1}]}})",
            "root.children[0].r0: missing"},
        BadCase{
            R"({"root": {"type": "blend", "children": [{"type": "sphere", "center": [0,0,0], "radius": 0}]}})",
            "root.children[0].radius: must be greater than 0 (got 0)"},
        BadCase{R"({"root": {"type": "blnd", "children": []}})",
                "root.type: unknown node type 'blnd' (did you mean 'blend'?)"},
        BadCase{R"({"root": {"type": "sphere", "center": [0, NaN, 0], "radius": 1}})",
                "JSON syntax error: parse error at line 1, column"},
        BadCase{R"({"root": {"type": "sphere", "center": [0, 1e999, 0], "radius": 1}})",
                "JSON syntax error: number overflow parsing '1e999' at line 1, column 43"},
        BadCase{R"({"root": {"type": "sphere", "center": [0, 0], "radius": 1}})",
                "root.center: must be an array of 3 numbers (got an array of 2)"},
        BadCase{R"({"root": {"type": "sphere", "center": [0, 0, 0], "radius": "1"}})",
                "root.radius: must be a number (got a string)"},
        BadCase{R"({"root": {"type": "sphere", "center": [0, 0, 0], "radius": 1, "radus": 2}})",
                "root.radus: unknown field (did you mean 'radius'?)"},
        BadCase{R"({"root": {"type": "sphere", "center": [0, 0, 0], "radius": 1, "weight": 0}})",
                "root.weight: must not be 0"},
        BadCase{
            R"({"threshold": 1.5, "root": {"type": "sphere", "center": [0, 0, 0], "radius": 1}})",
            "threshold: must be between 0 and 1"},
        BadCase{R"({"root": {"type": "blend", "children": []}})", "root.children: is empty"},
        BadCase{R"({"root": {"type": "union"}})", "root.children: missing"},
        BadCase{
            R"({"root": {"type": "bend", "p0": [0,0,0], "p1": [0,1,0], "direction": [1,0,0], "angle": 20,
                 "children": [)" CONE("") "," CONE("") "]}}",
            "root.children: a 'bend' warps exactly one child (got 2)"},
        BadCase{
            R"({"root": {"type": "bend", "p0": [0,0,0], "p1": [0,1,0], "direction": [0,2,0], "angle": 20,
                 "children": [)" CONE("") "]}}",
            "root.direction: must not be zero or parallel"},
        BadCase{
            R"({"root": {"type": "bend", "p0": [0,0,0], "p1": [0,1,0], "direction": [1,0,0], "angle": 200,
                 "children": [)" CONE("") "]}}",
            "root.angle: must be less than 180 degrees"},
        BadCase{R"({"root": {"type": "pcm", "width": 0.8, "children": [)" CONE("") "]}}",
                "root.width: must not exceed the threshold 0.5"},
        BadCase{R"({"root": {"type": "pcm", "attenuation": 1, "children": [)" CONE("") "]}}",
                "root.attenuation: must be greater than 1"},
        BadCase{R"({"root": {"type": "ricci", "n": 0.5, "children": [)" CONE("") "]}}",
                "root.n: must be at least 1"},
        BadCase{R"({"root": {"type": "better_blend", "k": 0.6, "children": [)" CONE("") "]}}",
                "root.k: must be in [0, 0.5)"},
        BadCase{R"({"root": {"type": "gbb", "children": [)" CONE("") "]}}", "root.bound: missing"},
        BadCase{R"({"root": {"type": "gbb", "bound": )" CONE(
                    "") R"(, "b1": {"type": "cone"}, "children": [)" CONE("") "]}}",
                "root.b1.type: 'cone' cannot blend"},
        BadCase{R"({"root": {"type": "gbb", "bound": )" CONE(
                    "") R"(, "b1": {"type": "pcm", "width": -1}, "children": [)" CONE("") "]}}",
                "root.b1.width: must be greater than 0"},
        BadCase{R"({"root": {"type": "transform", "scale": 0, "children": [)" CONE("") "]}}",
                "root.scale: must not be 0"},
        BadCase{
            R"({"root": {"type": "transform", "matrix": [[1,0,0,0],[0,1,0,0],[0,0,0,0],[0,0,0,1]], "children": [)" CONE(
                "") "]}}",
            "root.matrix: is singular"},
        // A scale whose determinant overflows is named as the scale it is
        // (it was "root.matrix: is singular").
        BadCase{R"({"root": {"type": "transform", "scale": 1e300, "children": [)" CONE("") "]}}",
                "root.scale: 1e+300 is beyond the scales cambium bakes (1e-15 to 1e+15)"},
        BadCase{
            R"({"root": {"type": "transform", "matrix": [[1,0,0,1e20],[0,1,0,0],[0,0,1,0],[0,0,0,1]], "children": [)" CONE(
                "") "]}}",
            "root.matrix: has an entry 1e+20, beyond the 1e+15 cambium bakes"},
        // A cone of no length has no axis, and no one radius: refused (a
        // capsule of no length is a sphere and stays).
        BadCase{R"({"root": {"type": "cone", "p0": [1,2,3], "p1": [1,2,3], "r0": 0.3, "r1": 0.1}})",
                "root.p1: is equal to p0: a cone needs a length"},
        BadCase{
            R"({"root": {"type": "convolution_segment", "p0": [0,0,0], "p1": [0,0,0], "r0": 0.1, "r1": 0.1}})",
            "root.p1: is equal to p0"},
        BadCase{
            R"({"root": {"type": "convolution_segment", "p0": [0,0,0], "p1": [0,1,0], "r0": 0.1, "r1": 0.1, "support": 0.15}})",
            "root.support: must be at least twice the largest radius"},
        BadCase{
            R"({"root": {"type": "taper", "origin": [0,0,0], "axis": [0,1,0], "length": 1, "scale0": 1, "scale1": -2,
                 "children": [)" CONE("") "]}}",
            "root.scale1: must be greater than 0"},
        BadCase{R"({"root": {"type": "blend", "children": [{"type": "blend", "children": [)" CONE(
                    R"(, "color": [2, 0, 0])") "]}]}}",
                "root.children[0].children[0].color: must be three numbers in [0, 1]"},
        BadCase{R"([1, 2, 3])", "(top level): must be an object"},
        BadCase{R"({"root": 5})", "root: must be an object with a \"type\""},
        BadCase{R"({"threshold": 0.5})", "root: missing"},
        BadCase{R"({"root": {"type": "sphere", "center": [0,0,0], "radius": 1})",
                "JSON syntax error"}));

TEST(SceneIo, OperatorDefaultsFitALowThreshold)
{
    // Width 0.25 and k 0.3 would be out of range at T = 0.2: the defaults follow T.
    const BlobTree tree = parseScene(R"({"threshold": 0.2, "root": {"type": "blend", "children": [
        {"type": "pcm", "children": [)" CONE("") "]}, " R"({"type": "better_blend", "children": [)" CONE("") "]}]}}",
                                     "low.json");
    EXPECT_LE(tree.node(1).combiner().width, 0.2);
    EXPECT_LT(tree.node(3).combiner().k, 0.2);
}

TEST(SceneIo, AGbbsDefaultPcmSideFitsALowThreshold)
{
    // (b1, unwritten, took width 0.25 at T = 0.2: "root.b1.width: must not
    // exceed the threshold")
    const BlobTree tree = parseScene(R"({"threshold": 0.2, "root": {"type": "gbb",
        "bound": {"type": "sphere", "center": [0.4, 0, 0], "radius": 0.3}, "children": [
        {"type": "sphere", "center": [0, 0, 0], "radius": 0.5},
        {"type": "sphere", "center": [0.8, 0, 0], "radius": 0.5}]}})",
                                     "gbb.json");
    EXPECT_LE(tree.node(tree.root()).gbb().b1.width, 0.2);
}

TEST(SceneIo, ARotationAxisOfAnyFiniteLengthIsItsDirection)
{
    // (an axis of [1e300, 1e300, 0] overflowed its length: "root.matrix:
    // must have finite entries", naming a matrix no one wrote)
    auto forward = [](const char* axis) {
        const BlobTree tree = parseScene(
            std::string(R"({"root": {"type": "transform", "rotate": {"axis": )") + axis +
                R"(, "angle": 90}, "children": [{"type": "sphere", "center": [0, 0, 0], "radius": 1}]}})",
            "rotate.json");
        const auto& m = std::get<TransformParams>(tree.node(tree.root()).params).forward;
        return std::vector<double>(std::begin(m), std::end(m));
    };
    const std::vector<double> huge = forward("[1e300, 1e300, 0]"), unit = forward("[1, 1, 0]");
    for (size_t i = 0; i < unit.size(); ++i)
        EXPECT_NEAR(huge[i], unit[i], 1e-15) << i;
}

TEST(SceneIo, MissingFileIsNamed)
{
    try {
        loadScene("/nonexistent/scene.json");
        FAIL();
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("/nonexistent/scene.json: cannot read"),
                  std::string::npos);
    }
}

}  // namespace
