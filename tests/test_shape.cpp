// Shape synthesis (paper 004): shape files, each detail's defining property,
// placement, local edits, captured bases, and the command.
#include "bake/mesh_levelset.h"
#include "io/vdb.h"
#include "cli_util.h"
#include "shape/capture.h"
#include "shape/details.h"
#include "shape/shape.h"
#include "shape/synthesis.h"
#include "test_util.h"
#include "use/mesh.h"

#include "core/math.h"
#include "core/random.h"

#include <openvdb/tools/Diagnostics.h>
#include <openvdb/tools/ChangeBackground.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

using namespace cambium;

namespace {

ShapeSpec shape(const std::string& text)
{
    return parseShape(text, "test.json");
}

/// The InputError message of parsing `text`, or "" when it parses.
std::string refusal(const std::string& text)
{
    try {
        ShapeSurface s(shape(text));
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

double rms(const std::vector<glm::dvec3>& d)
{
    double s = 0.0;
    for (const auto& v : d)
        s += v.z * v.z;
    return std::sqrt(s / double(d.size()));
}

}  // namespace

TEST(ShapeFile, AcceptsTheIssueExamples)
{
    ShapeSurface cube(shape(R"({"base": {"type": "cube", "size": 2}, "levels": 6})"));
    cube.synthesize();
    EXPECT_EQ(cube.levels(), 6);
    EXPECT_EQ(cube.surface().finest().vertexCount(), 6u * 4096u + 2u);
    ShapeSurface rock(shape(R"({"base": {"type": "sphere", "radius": 1}, "levels": 6,
        "details": [{"type": "rock", "amplitude": 0.08, "seed": 3}]})"));
    rock.synthesize();
    // Within the rock's bound (sum of 0.08 2^-k) of the unit sphere.
    for (const auto& p : rock.surface().finest().points)
        ASSERT_NEAR(glm::length(p), 1.0, 0.17);
}

TEST(ShapeFile, LevelsGivenApartAreReadAsTheFilesOwn)
{
    // --levels N reads the file as if it said "levels": N: the details'
    // default levels follow it (a rock at every level from 1).
    const std::string three = R"({"base": {"type": "sphere"}, "levels": 3,
                                  "details": [{"type": "rock", "amplitude": 0.03}]})";
    std::string five = three;
    five.replace(five.find("\"levels\": 3"), 11, "\"levels\": 5");
    for (int levels : {2, 5}) {
        const ShapeSpec given = parseShape(three, "three.json", "", 0.0, levels);
        const ShapeSpec own = parseShape(levels == 5 ? five : three, "own.json", "", 0.0, -1);
        EXPECT_EQ(given.levels, levels);
        if (levels == 5) {
            EXPECT_EQ(given.details.at(0).levels, own.details.at(0).levels);
        }
        EXPECT_EQ(given.details.at(0).levels.back(), levels);
    }
}

TEST(ShapeFile, BadInputIsNamed)
{
    auto says = [](const std::string& text, const std::string& words) {
        const std::string e = refusal(text);
        EXPECT_NE(e.find(words), std::string::npos) << "message: '" << e << "' for " << text;
    };
    says(R"({"base": {"type": "cube"}, "levels": 16})",
         "test.json: levels: must be from 0 to 15 (got 16)");
    says(R"({"levels": 3})", "test.json: base: missing");
    says(R"({"base": {"type": "cub"}})", "unknown base 'cub' (did you mean 'cube'?)");
    says(R"({"base": {"type": "sphere", "radius": -1}})", "base.radius: must be between");
    says(R"({"base": {"type": "sphere", "raduis": 1}})",
         "base.raduis: unknown field (did you mean 'radius'?)");
    says(R"({"base": {"type": "torus", "major": 1, "minor": 2}})",
         "base.minor: must be less than major");
    says(R"({"base": {"type": "mesh", "file": "/nonexistent/m.obj"}})",
         "base.file: /nonexistent/m.obj");
    says(
        R"({"base": {"type": "cube"}, "levels": 3, "details": [{"type": "rock", "levels": [2, 4]}]})",
        "details[0].levels[1]: level 4 is finer than the shape's 3 levels");
    says(R"({"base": {"type": "cube"}, "details": [{"type": "berry", "at": []}]})",
         "details[0].at: must be a non-empty array");
    says(R"({"base": {"type": "cube"}, "details": [{"type": "tentacle"}]})",
         "details[0]: needs seeds");
    says(R"({"base": {"type": "cube"}, "details": [{"type": "rock", "amplitude": "big"}]})",
         "details[0].amplitude: must be a number (got a string)");
    says(R"({"base": {"type": "cube"}, "edits": [{"at": [0, 0, 1], "radius": 0.2}]})",
         "edits[0].gain: missing");
    says(R"({"base": {"type": "cube"}, "color": [1, 2, 0]})", "color[1]: must be between 0 and 1");
    says(R"({"base": {"type": "fuse", "terms": 3}})", "base.terms: must be from 1 to 2");
    // A base mesh that is not a 2-manifold.
    const std::string dir = ::testing::TempDir() + "/shape_bad";
    std::filesystem::create_directories(dir);
    std::ofstream(dir + "/fin.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
                                       "f 1 2 3\nf 2 1 4\nf 1 2 5\n";
    says(R"({"base": {"type": "mesh", "file": ")" + dir + R"(/fin.obj"}})", "not a 2-manifold");
    // Points named as the file numbers them: OBJ from 1, PLY from 0.
    const std::string tetra =
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 5 5 5\n"
        "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n";
    std::ofstream(dir + "/spare.obj") << tetra;
    says(R"({"base": {"type": "mesh", "file": ")" + dir + R"(/spare.obj"}})",
         "spare.obj: point 5 is used by no face");
    std::ofstream(dir + "/spare.ply")
        << "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
           "property float z\nelement face 4\nproperty list uchar int vertex_indices\n"
           "end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n5 5 5\n3 0 2 1\n3 0 1 3\n3 1 2 3\n"
           "3 0 3 2\n";
    says(R"({"base": {"type": "mesh", "file": ")" + dir + R"(/spare.ply"}})",
         "spare.ply: point 4 is used by no face");
    // A model base that is the shape file itself (read as a scene, it was
    // told "base: unknown field").
    std::ofstream(dir + "/self.json") << R"({"base": {"type": "model", "file": "self.json"}})";
    test::expectInputError([&] { readShapeFile(dir + "/self.json"); },
                           "self.json: base.file: is this shape file itself", "self base");
}

TEST(ShapeDetails, RockIsOneOverFAndTheSameForTheSameSeed)
{
    const std::string text = R"({"base": {"type": "sphere", "radius": 1}, "levels": 7,
        "details": [{"type": "rock", "amplitude": 0.05, "seed": 11, "levels": [3, 4, 5, 6, 7]}]})";
    ShapeSurface a(shape(text)), b(shape(text));
    a.synthesize();
    b.synthesize();
    EXPECT_TRUE(a.surface().finest().points == b.surface().finest().points);
    // Each level's rock detail (the level's details minus the sphere's own)
    // has half the previous level's size: the measured ratio of RMS near 2.
    std::vector<double> size;
    for (int l = 3; l <= 7; ++l) {
        std::vector<glm::dvec3> rock = a.surface().level(l).detail;
        for (size_t v = 0; v < rock.size(); ++v)
            rock[v] -= a.baseDetail(l)[v];
        size.push_back(rms(rock));
    }
    for (size_t k = 1; k < size.size(); ++k)
        EXPECT_NEAR(size[k - 1] / size[k], 2.0, 0.25) << "level " << 3 + k;
    EXPECT_EQ(a.surface().level(2).detail, a.baseDetail(2));  // outside its levels: nothing
    // Another seed, another rock.
    ShapeSurface c(shape(R"({"base": {"type": "sphere", "radius": 1}, "levels": 7,
        "details": [{"type": "rock", "amplitude": 0.05, "seed": 12, "levels": [3, 4, 5, 6, 7]}]})"));
    c.synthesize();
    EXPECT_FALSE(a.surface().finest().points == c.surface().finest().points);
    test::report("RMS per level 3-7: {:.4g} {:.4g} {:.4g} {:.4g} {:.4g}", size[0], size[1], size[2],
                 size[3], size[4]);
}

TEST(ShapeDetails, RockIsVolumetricTheSameAtTheSamePointOnTwoMeshings)
{
    // F(p, level) depends on the point only: on a cube and on a sphere, each
    // vertex's rock detail is the function at its subdivided point, and two
    // meshings that share a point share its value.
    for (const char* base :
         {R"({"type": "cube", "size": 2})", R"({"type": "sphere", "radius": 1})"}) {
        ShapeSurface s(shape(std::string(R"({"base": )") + base + R"(, "levels": 4,
            "details": [{"type": "rock", "amplitude": 0.1, "frequency": 3, "seed": 4}]})"));
        s.synthesize();
        for (int l = 1; l <= 4; ++l) {
            const SubdivLevel& lv = s.surface().level(l);
            const std::vector<glm::dvec3>& own = s.baseDetail(l);
            for (size_t v = 0; v < lv.vertexCount(); v += 7) {
                const double want = rockValue(lv.subdivided[v], l - 1, 0.1, 3.0, 4);
                ASSERT_NEAR(lv.detail[v].z - (own.empty() ? 0.0 : own[v].z), want, 1e-15);
            }
        }
    }
    const glm::dvec3 p(0.3, -0.2, 0.9);
    EXPECT_EQ(rockValue(p, 2, 0.1, 3.0, 4), rockValue(p, 2, 0.1, 3.0, 4));
    EXPECT_NE(rockValue(p, 2, 0.1, 3.0, 4), rockValue(p, 3, 0.1, 3.0, 4));
    for (int k = 0; k < 5; ++k)  // bounded by the level's amplitude
        for (double x = -1; x <= 1; x += 0.01)
            ASSERT_LE(std::fabs(rockValue({x, 0.37 * x, 0.5}, k, 0.1, 3.0, 4)),
                      std::ldexp(0.1, -k) + 1e-15);
    // The two-pass form: one value per control point and level.
    EXPECT_EQ(rockControlValue(17, 3, 1, 0.1, 9), rockControlValue(17, 3, 1, 0.1, 9));
    EXPECT_LE(std::fabs(rockControlValue(17, 3, 1, 0.1, 9)), 0.05);
}

TEST(ShapeDetails, BerryDomesHaveHeightRAtTheSeedAndNoneBeyondR)
{
    EXPECT_DOUBLE_EQ(domeHeight(0.0, 0.3), 0.3);
    EXPECT_DOUBLE_EQ(domeHeight(0.3, 0.3), 0.0);
    EXPECT_DOUBLE_EQ(domeHeight(0.5, 0.3), 0.0);
    EXPECT_NEAR(domeHeight(0.18, 0.3), 0.24, 1e-15);  // sqrt(0.09 - 0.0324)
    // On a plane, one seed at the centre: the dome is the detail itself.
    ShapeSurface s(shape(R"({"base": {"type": "plane", "size": 2, "cells": 4}, "levels": 3,
        "details": [{"type": "berry", "radius": 0.4, "at": [[0, 0, 0]], "levels": [2], "children": 0}]})"));
    s.synthesize();
    const SubdivLevel& lv = s.surface().level(2);
    const int seed = nearestVertex(lv.subdivided, {0, 0, 0});
    EXPECT_DOUBLE_EQ(lv.detail[size_t(seed)].z, 0.4);
    for (size_t v = 0; v < lv.vertexCount(); ++v) {
        const double r = glm::length(lv.subdivided[v] - lv.subdivided[size_t(seed)]);
        ASSERT_DOUBLE_EQ(lv.detail[v].z, domeHeight(r, 0.4));
    }
}

TEST(ShapeDetails, APointTreeFindsTheNearestPointAScanFinds)
{
    // Points on a sphere, some repeated (ties: the lowest index), queried
    // on it, off it by far more than their spacing (a berry's children, a
    // dome's radius out) and from afar; `within` finds none beyond it.
    std::vector<glm::dvec3> pts;
    uint64_t stream = 11;
    for (int i = 0; i < 4000; ++i) {
        const double z = 2.0 * splitMix01(stream) - 1.0, a = 2.0 * kPi * splitMix01(stream);
        const double r = std::sqrt(1.0 - z * z);
        pts.emplace_back(r * std::cos(a), r * std::sin(a), z);
    }
    for (int i = 0; i < 200; ++i)
        pts.push_back(pts[size_t(17 * i)]);
    const PointTree tree(pts);
    for (int i = 0; i < 3000; ++i) {
        const glm::dvec3 p =
            pts[size_t(i)] * (i % 3 == 0   ? 1.0
                              : i % 3 == 1 ? 1.3
                                           : 40.0) +
            glm::dvec3(splitMix01(stream), splitMix01(stream), splitMix01(stream)) * 1e-3;
        const int scan = nearestVertex(pts, p);
        ASSERT_EQ(tree.nearest(p), scan) << i;
        const double d = glm::length(pts[size_t(scan)] - p);
        ASSERT_EQ(tree.nearest(p, d * 1.0001), scan) << i;
        ASSERT_EQ(tree.nearest(p, d * 0.9999), -1) << i;
    }
    EXPECT_EQ(PointTree({}).nearest({0, 0, 0}), -1);
}

TEST(ShapeDetails, BerryGenerationsBeyondTheirBoundAreRefusedByPath)
{
    // Every vertex of level 5 a seed (a spacing far below the edges), 64
    // children each over three levels: 25 million domes at the third.
    ShapeSurface s(shape(R"({"base": {"type": "sphere", "radius": 1}, "levels": 7,
        "details": [{"type": "berry", "radius": 0.2, "spacing": 0.0001, "children": 64,
                     "levels": [5, 6, 7]}]})"));
    test::expectInputError([&] { s.synthesize(); },
                           "test.json: details[0]: 393344 seeds of 64 children each make 2.52e+07 "
                           "domes at the berry's level 3, more than the 1e+07",
                           "a berry of 25 million domes");
}

TEST(ShapeDetails, TentacleFollowsThePseudoCode)
{
    const double L = 0.05, theta = 0.3;
    for (int l = 1; l <= 6; ++l) {
        const glm::dvec3 d = tentacleDetail(L, theta, l);
        const double sign = l % 2 == 0 ? -1.0 : 1.0;
        EXPECT_DOUBLE_EQ(d.z, sign * L * l) << "magnitude = reference length x level, alternating";
        EXPECT_DOUBLE_EQ(d.x, sign * L * l * std::sin(theta + kPi / 3 * l));
        EXPECT_DOUBLE_EQ(d.y, sign * L * l * std::cos(theta + kPi / 3 * l));
    }
    ShapeSurface s(shape(R"({"base": {"type": "sphere", "radius": 1}, "levels": 6,
        "details": [{"type": "tentacle", "length": 0.05, "angle": 10, "at": [[0, 0, 1]],
                     "levels": [2, 3, 4]}]})"));
    s.synthesize();
    const int seed = nearestVertex(s.surface().level(2).subdivided, {0, 0, 1});
    for (int l = 1; l <= 6; ++l) {
        const SubdivLevel& lv = s.surface().level(l);
        const std::vector<glm::dvec3>& own = s.baseDetail(l);
        size_t changed = 0;
        for (size_t v = 0; v < lv.vertexCount(); ++v)
            changed += lv.detail[v] != own[v];
        if (l < 2 || l > 4) {
            EXPECT_EQ(changed, 0u) << "level " << l << " is outside its range";
        } else {
            EXPECT_EQ(changed, 1u);  // the seed, the same vertex index at every level
            const glm::dvec3 d = lv.detail[size_t(seed)] - own[size_t(seed)];
            const glm::dvec3 want = tentacleDetail(0.05, 10 * kDegree, l);
            EXPECT_NEAR(glm::length(d - want), 0.0, 1e-15);
        }
    }
}

TEST(ShapeDetails, PoissonDiskSeedsAreSpacedAndMaximal)
{
    ShapeSurface s(shape(R"({"base": {"type": "sphere", "radius": 1}, "levels": 5})"));
    s.synthesize();
    const auto& pts = s.surface().level(5).subdivided;
    const double spacing = 0.2;
    const std::vector<int> seeds = poissonDisk(pts, spacing, 3);
    for (size_t i = 0; i < seeds.size(); ++i)
        for (size_t j = 0; j < i; ++j)
            ASSERT_GE(glm::length(pts[size_t(seeds[i])] - pts[size_t(seeds[j])]), spacing);
    double farthest = 0.0;  // every point within the spacing of a seed: maximal
    for (const auto& p : pts) {
        double nearest = 1e9;
        for (int k : seeds)
            nearest = std::min(nearest, glm::length(p - pts[size_t(k)]));
        farthest = std::max(farthest, nearest);
    }
    EXPECT_LT(farthest, spacing);
    EXPECT_NE(poissonDisk(pts, spacing, 4), seeds);
    test::report("{} seeds at spacing {}; every point within {:.4f} of one", seeds.size(), spacing,
                 farthest);
}

TEST(ShapeEdits, GainOneChangesNothingAndNoGainReachesBeyondItsRadius)
{
    const std::string base = R"({"base": {"type": "sphere", "radius": 1}, "levels": 5,
        "details": [{"type": "rock", "amplitude": 0.05, "seed": 1}])";
    ShapeSurface plain(shape(base + "}"));
    plain.synthesize();
    ShapeSurface one(shape(base + R"(, "edits": [{"at": [0, 0, 1], "radius": 0.5, "gain": 1}]})"));
    one.synthesize();
    EXPECT_TRUE(one.surface().finest().points == plain.surface().finest().points);
    // Details of the edited level change only within its radius (its Q, from
    // the coarser levels, is the same): over the surface, so within the
    // straight-line radius too.
    for (const char* distance : {"metric", "topological"})
        for (double gain : {0.0, 3.0})
            for (int l : {3, 4}) {
                ShapeSurface e(shape(base +
                                     R"(, "edits": [{"at": [0, 0, 1], "radius": 0.5, "gain": )" +
                                     std::to_string(gain) + R"(, "levels": [)" + std::to_string(l) +
                                     R"(], "distance": ")" + distance + "\"}]}"));
                e.synthesize();
                const SubdivLevel& a = plain.surface().level(l);
                const SubdivLevel& b = e.surface().level(l);
                size_t inside = 0;
                for (size_t v = 0; v < a.vertexCount(); ++v) {
                    ASSERT_EQ(a.subdivided[v], b.subdivided[v]);
                    if (glm::length(a.subdivided[v] - glm::dvec3(0, 0, 1)) >= 0.5)
                        ASSERT_EQ(a.detail[v], b.detail[v]) << distance << " gain " << gain;
                    else
                        inside += a.detail[v] != b.detail[v];
                }
                EXPECT_GT(inside, 10u);
            }
    // The drop-off: 1 at the point, 0 with zero slope at the radius (C1).
    EXPECT_DOUBLE_EQ(editDropOff(0.0), 1.0);
    EXPECT_DOUBLE_EQ(editDropOff(1.0), 0.0);
    EXPECT_DOUBLE_EQ(editDropOff(1.5), 0.0);
    for (double e : {1e-2, 1e-3, 1e-4})  // k(1 - e) = 3 e^2 - 2 e^3: no kink at the border
        EXPECT_NEAR(editDropOff(1.0 - e), 3 * e * e - 2 * e * e * e, 1e-15);
}

TEST(ShapePlacement, AChartKeepsADomeRoundOnAStretchedMesh)
{
    // A plane stretched 3:1 in x.  The same spur placed at the control points
    // (rings of edges) comes out three times as long in x as in y; placed in
    // the seed's chart (tangent-plane distances) it stays round.
    auto footprint = [](const char* placement) {
        ShapeSpec spec =
            shape(std::string(R"({"base": {"type": "plane", "size": 2, "cells": 8}, "levels": 4,
            "details": [{"type": "spur", "radius": 1.2, "height": 0.2, "at": [[0, 0, 0]],
                         "levels": [3], "placement": ")") +
                  placement + "\"}]}");
        BaseShape base = makeBase(spec.base, spec.source, Device::Cpu);
        for (auto& p : base.mesh.points)
            p.x *= 3.0;
        ShapeSurface s(spec, -1, base);
        s.synthesize();
        const SubdivLevel& lv = s.surface().level(3);
        double x = 0.0, y = 0.0;
        for (size_t v = 0; v < lv.vertexCount(); ++v)
            if (lv.detail[v].z > 1e-9) {
                x = std::max(x, std::fabs(lv.subdivided[v].x));
                y = std::max(y, std::fabs(lv.subdivided[v].y));
            }
        return x / y;
    };
    const double control = footprint("control-points"), chart = footprint("chart");
    EXPECT_GT(control, 2.0);
    EXPECT_NEAR(chart, 1.0, 0.3);
    test::report("footprint x/y on a 3:1 stretched plane: control points {:.3f}, chart {:.3f}",
                 control, chart);
}

TEST(ShapePlacement, MushroomOnAPlaneDoesNotFold)
{
    // The profile through the seed (the vertices on y = 0 of the flat plane,
    // in their original order) must be a simple curve.
    const std::string text = R"({"base": {"type": "plane", "size": 2, "cells": 8}, "levels": 6,
        "details": [{"type": "mushroom", "radius": 0.5, "height": 0.6, "at": [[0, 0, 0]]}]})";
    ShapeSurface flat(shape(R"({"base": {"type": "plane", "size": 2, "cells": 8}, "levels": 6})"));
    flat.synthesize();
    ShapeSurface m(shape(text));
    m.synthesize();
    const auto& before = flat.surface().finest().points;
    const auto& after = m.surface().finest().points;
    std::vector<size_t> line;
    for (size_t v = 0; v < before.size(); ++v)
        if (std::fabs(before[v].y) < 1e-12)
            line.push_back(v);
    std::sort(line.begin(), line.end(),
              [&](size_t a, size_t b) { return before[a].x < before[b].x; });
    ASSERT_GT(line.size(), 500u);
    double top = 0.0, widest = 0.0;
    for (size_t v : line) {
        ASSERT_NEAR(after[v].y, 0.0, 1e-9);
        top = std::max(top, after[v].z);
    }
    auto cross = [](glm::dvec2 a, glm::dvec2 b, glm::dvec2 c, glm::dvec2 d) {
        auto orient = [](glm::dvec2 p, glm::dvec2 q, glm::dvec2 r) {
            return (q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x);
        };
        return orient(a, b, c) * orient(a, b, d) < 0 && orient(c, d, a) * orient(c, d, b) < 0;
    };
    size_t crossings = 0;
    for (size_t i = 0; i + 1 < line.size(); ++i)
        for (size_t j = i + 2; j + 1 < line.size(); ++j)
            crossings += cross(
                {after[line[i]].x, after[line[i]].z}, {after[line[i + 1]].x, after[line[i + 1]].z},
                {after[line[j]].x, after[line[j]].z}, {after[line[j + 1]].x, after[line[j + 1]].z});
    EXPECT_EQ(crossings, 0u);
    // A mushroom: taller than its stem is wide, its cap wider than its stem.
    for (size_t v : line)
        if (after[v].z > 0.7 * top)
            widest = std::max(widest, std::fabs(after[v].x));
    double stem = 1e9;
    for (size_t v : line)
        if (after[v].z > 0.2 * top && after[v].z < 0.4 * top)
            stem = std::min(stem, std::fabs(after[v].x));
    EXPECT_GT(top, 0.3);
    EXPECT_GT(widest, stem * 1.2);
    test::report("mushroom: height {:.3f}, cap half-width {:.3f}, stem half-width {:.3f}", top,
                 widest, stem);
}

TEST(ShapeCapture, AnalysedBaseKeepsTheFineMeshTopology)
{
    // A torus and a sphere as fine meshes, baked, then captured: the base's
    // Euler characteristic is the fine mesh's, and analysis puts each
    // level's points on the fine surface.
    for (const char* text :
         {R"({"base": {"type": "torus", "major": 1, "minor": 0.4}, "levels": 4})",
          R"({"base": {"type": "sphere", "radius": 1}, "levels": 4})"}) {
        ShapeSurface fine(shape(text));
        fine.synthesize();
        const TriangleMesh mesh = fine.mesh();
        const long chiFine =
            checkControlMesh(
                [&] {
                    ControlMesh c;
                    for (const auto& p : mesh.points)
                        c.points.push_back({p.x(), p.y(), p.z()});
                    c.faceSizes.assign(mesh.polygons.sizes.begin(), mesh.polygons.sizes.end());
                    c.faceVerts.assign(mesh.polygons.corners.begin(), mesh.polygons.corners.end());
                    return c;
                }(),
                "fine")
                .eulerCharacteristic();
        MeshBakeOptions opt;
        opt.voxelSize = 0.01;
        const BakedGrids g = bakeMeshLevelSet(mesh, opt, "fine");
        const BaseShape base = captureLevelSet(g.surface, 0.15, "captured");
        const long chiBase = checkControlMesh(base.mesh, "base").eulerCharacteristic();
        EXPECT_EQ(chiBase, chiFine);
        MultiresSurface s(base.mesh, 3, "captured");
        s.analyse(base.target);
        openvdb::tools::GridSampler<openvdb::FloatGrid, openvdb::tools::BoxSampler> at(*g.surface);
        double worst = 0.0;
        for (const auto& p : s.finest().points)
            worst = std::max(worst, std::fabs(double(at.wsSample(openvdb::Vec3d(p.x, p.y, p.z)))));
        EXPECT_LT(worst, 1e-3 * opt.voxelSize);
        test::report(
            "captured base: {} faces, Euler characteristic {}; level 3 within {:.3g} of "
            "the fine surface",
            base.mesh.faceCount(), chiBase, worst);
    }
}

TEST(ShapeCommand, WritesMeshesAndLevelSetsAndRefusesBadInputFirst)
{
    const std::string dir = ::testing::TempDir() + "/shape_cli";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    std::ofstream(dir + "/rock.json") << R"({"base": {"type": "sphere", "radius": 1}, "levels": 4,
        "details": [{"type": "rock", "amplitude": 0.08, "seed": 3}]})";
    auto r = test::run("shape " + dir + "/rock.json -o " + dir + "/rock.obj");
    ASSERT_EQ(r.status, 0) << r.err;
    std::ifstream obj(dir + "/rock.obj");
    std::string all((std::istreambuf_iterator<char>(obj)), {});
    EXPECT_NE(all.find("\nf 1//1 "), std::string::npos);  // quads kept: four corners
    EXPECT_EQ(std::count(all.begin(), all.end(), '\n') > 1536, true);
    r = test::run("shape " + dir + "/rock.json -o " + dir + "/rock.vdb --voxel-size 0.02");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.out.find("note: "), std::string::npos) << r.out;
    // A voxel the size of the rock: said, as bake says of thin primitives.
    r = test::run("shape " + dir + "/rock.json -o " + dir + "/coarse.vdb --voxel-size 0.5");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("voxels of 0.5: it bakes as a few voxel-sized blocks"), std::string::npos)
        << r.out;
    r = test::run("info " + dir + "/rock.json");
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("level 4: 1,538 vertices, 1,536 faces"), std::string::npos) << r.out;
    r = test::run("mesh " + dir + "/rock.vdb -o " + dir + "/remesh.ply");
    EXPECT_EQ(r.status, 0) << r.err;

    // Refused before anything is written.
    std::ofstream(dir + "/wrong.json") << R"({"base": {"type": "sphere"}, "levels": 16})";
    r = test::run("shape " + dir + "/wrong.json -o " + dir + "/bad.vdb");
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(r.err.find("levels: must be from 0 to 15"), std::string::npos) << r.err;
    r = test::run("shape " + dir + "/missing.json -o " + dir + "/bad.vdb");
    EXPECT_EQ(r.status, 2);
    r = test::run("shape " + dir + "/rock.json -o " + dir + "/bad.stl");
    EXPECT_EQ(r.status, 2);
    r = test::run("shape " + dir + "/rock.json -o " + dir + "/bad.vdb --voxel-size 0.00001");
    EXPECT_EQ(r.status, 2) << r.out;
    r = test::run("shape " + dir + "/rock.json -o " + dir + "/bad.vdb --voxel-size 2e9");
    EXPECT_EQ(r.status, 2) << r.out;  // the band's limits as bake's
    EXPECT_NE(r.err.find("--voxel-size must be a number from 0.0001 to 1e9 (got 2000000000)"),
              std::string::npos)
        << r.err;
    r = test::run("shape " + dir + "/rock.json -o " + dir + "/bad.vdb --levels 12");
    EXPECT_EQ(r.status, 2) << r.out;  // 6 x 4^12 x 330 bytes: more than this machine has
    std::ofstream(dir + "/plane.json") << R"({"base": {"type": "plane"}, "levels": 2})";
    r = test::run("shape " + dir + "/plane.json -o " + dir + "/bad.vdb");
    EXPECT_EQ(r.status, 2);
    EXPECT_NE(r.err.find("the surface is open"), std::string::npos) << r.err;
    for (const auto& e : std::filesystem::directory_iterator(dir))
        EXPECT_EQ(e.path().filename().string().rfind("bad", 0), std::string::npos)
            << e.path() << " was written";
}

TEST(ShapeDetails, RockAmplitudesThatWouldFoldAPlaneAreRefused)
{
    // Each form of rock on a plane: an amplitude that folds it is refused
    // with about the largest that does not (found on a patch of the plane);
    // somewhat less leaves the plane a height field (no quad turned over
    // seen from above).
    const std::string plane = R"({"base": {"type": "plane", "size": 2, "cells": 4}, "levels": 6, )";
    for (const char* form : {"noise", "control-points"}) {
        const std::string big =
            plane + R"("details": [{"type": "rock", "amplitude": 0.5, "frequency": 4, "form": ")" +
            form + "\"}]}";
        const std::string e = refusal(big);
        ASSERT_NE(e.find("folds the surface onto itself on a plane"), std::string::npos) << e;
        const size_t at = e.find("at most about ");
        ASSERT_NE(at, std::string::npos);
        const double safe = std::stod(e.substr(at + 14));
        EXPECT_GT(safe, 0.0);
        EXPECT_LT(safe, 0.5);
        // Any amplitude that folds is told about the same largest one (1000
        // was told "at most about 0").
        const std::string huge = refusal(
            plane + R"("details": [{"type": "rock", "amplitude": 1000, "frequency": 4, "form": ")" +
            form + "\"}]}");
        const size_t hugeAt = huge.find("at most about ");
        ASSERT_NE(hugeAt, std::string::npos) << huge;
        EXPECT_NEAR(std::stod(huge.substr(hugeAt + 14)), safe, 0.1 * safe) << huge;
        ShapeSurface s(shape(plane + R"("details": [{"type": "rock", "amplitude": )" +
                             std::to_string(0.7 * safe) + R"(, "frequency": 4, "form": ")" + form +
                             "\"}]}"));
        s.synthesize();
        const SubdivLevel& f = s.surface().finest();
        size_t flipped = 0;
        for (size_t q = 0; q < f.faceCount(); ++q) {
            const int* c = f.faceVerts.data() + f.faceStart[q];
            const glm::dvec3 a = f.points[size_t(c[0])], b = f.points[size_t(c[1])],
                             cc = f.points[size_t(c[2])], d = f.points[size_t(c[3])];
            flipped += (cc.x - a.x) * (d.y - b.y) - (cc.y - a.y) * (d.x - b.x) <= 0.0;
        }
        EXPECT_EQ(flipped, 0u) << form;
        test::report("{}: largest amplitude at frequency 4 on a plane of 0.5-long edges: {}", form,
                     safe);
    }
}

TEST(ShapeCapture, ALevelSetOfAnyBackgroundIsCapturedAsAnother)
{
    // The coarse surface was resampled with the fine one's band width in
    // voxels: a sphere whose background (its outside value) was 1000 made a
    // band of 20,000 voxels and ran past a minute into the memory limit
    // (sweep 11).  Any background gives the same base.
    openvdb::FloatGrid::Ptr sphere =
        openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.0f, openvdb::Vec3f(0.0f), 0.05f);
    const BaseShape usual = captureLevelSet(sphere, 0.1, "usual");
    for (float background : {1000.0f, 1e30f}) {
        openvdb::FloatGrid::Ptr wide = sphere->deepCopy();
        openvdb::tools::changeLevelSetBackground(wide->tree(), background);
        const BaseShape captured = captureLevelSet(wide, 0.1, "wide");
        EXPECT_EQ(captured.mesh.points.size(), usual.mesh.points.size()) << background;
        EXPECT_EQ(captured.mesh.faceVerts, usual.mesh.faceVerts) << background;
    }
}

TEST(ShapeCapture, AFineMeshAnalysedOntoAGivenControlMesh)
{
    // A fine sphere written as an OBJ, analysed onto a given control mesh
    // (the sphere's first level: 26 points, 24 quads, within the fine
    // surface's band): every finer level's points land on the fine surface.
    const std::string dir = ::testing::TempDir() + "/shape_capture";
    std::filesystem::create_directories(dir);
    ShapeSurface fine(shape(R"({"base": {"type": "sphere", "radius": 1}, "levels": 5})"));
    fine.synthesize();
    writeMesh(fine.mesh(), dir + "/fine.obj");
    writeMesh(levelMesh(fine.surface().level(1)), dir + "/control.obj");
    const ShapeSpec spec =
        parseShape(R"({"base": {"type": "mesh", "file": "fine.obj", "analyse": true,
        "control": "control.obj", "fine_voxel_size": 0.02}, "levels": 3})",
                   "captured.json", dir);
    ShapeSurface s(spec, -1, Device::Cpu);
    s.synthesize();
    EXPECT_EQ(s.surface().level(0).vertexCount(), 26u);  // the control mesh
    double worst = 0.0;
    for (const auto& p : s.surface().finest().points)
        worst = std::max(worst, std::fabs(glm::length(p) - 1.0));
    EXPECT_LT(worst, 2e-3);  // the fine mesh is within about 1e-3 of the sphere
    const std::string e = refusal(R"({"base": {"type": "mesh", "file": ")" + dir +
                                  R"(/fine.obj", "voxel_size": 0.1}})");
    EXPECT_NE(e.find("add \"analyse\": true"), std::string::npos) << e;
    // A control mesh nowhere near the surface (moved 100 away: it was
    // synthesised there as it was, exit 0) is refused.
    {
        TriangleMesh moved = readMesh(dir + "/control.obj");
        for (auto& p : moved.points)
            p += openvdb::Vec3s(100.0f, 0.0f, 0.0f);
        writeMesh(moved, dir + "/far.obj");
    }
    test::expectInputError(
        [&] {
            ShapeSurface away(
                parseShape(R"({"base": {"type": "mesh", "file": "fine.obj", "analyse": true,
                "control": "far.obj", "fine_voxel_size": 0.02}, "levels": 2})",
                           "away.json", dir),
                -1, Device::Cpu);
        },
        "far.obj has no point within the band of the surface it is analysed onto",
        "a control mesh 100 away");
    // A base voxel size of a few voxels across meshes a blob that no level
    // brings back (a unit cube at 0.6 kept a hundredth of its volume).
    test::expectInputError(
        [&] {
            ShapeSurface coarse(
                parseShape(R"({"base": {"type": "mesh", "file": "fine.obj", "analyse": true,
                "voxel_size": 0.5, "fine_voxel_size": 0.05}, "levels": 2})",
                           "blob.json", dir),
                -1, Device::Cpu);
        },
        "the base voxel_size 0.5 spans 4 voxels across the surface's extent 2: at most 0.25 (8 "
        "voxels across) captures its shape",
        "a base of 4 voxels across");
    // A fine surface coarser than the default base's 48th: the base takes
    // twice its voxels (it was refused for a voxel_size the file never set),
    // and one too coarse for 8 of those across is named as the surface's.
    ShapeSurface twice(parseShape(R"({"base": {"type": "mesh", "file": "fine.obj", "analyse": true,
        "fine_voxel_size": 0.1}, "levels": 2})",
                                  "twice.json", dir),
                       -1, Device::Cpu);
    twice.synthesize();
    EXPECT_NEAR(meshArea(twice.mesh()), 4.0 * kPi, 0.1);
    test::expectInputError(
        [&] {
            ShapeSurface coarse(
                parseShape(R"({"base": {"type": "mesh", "file": "fine.obj", "analyse": true,
                "fine_voxel_size": 0.2}, "levels": 2})",
                           "coarse.json", dir),
                -1, Device::Cpu);
        },
        "the surface's voxels (0.2) are too coarse for its extent 2",
        "a fine surface too coarse for a base");
    test::report(
        "a level-5 sphere mesh analysed onto its level 1: level 3 within {:.2g} of the sphere",
        worst);
}

TEST(ShapeAnimation, KeyframesInterpolateAndHoldBeyondTheirEnds)
{
    const std::string text = R"({"base": {"type": "sphere"}, "levels": 2, "details": [
        {"type": "rock", "amplitude": {"keys": [[10, 0.02], [20, 0.06]]},
         "frequency": {"keys": [[0, 1], [10, 2], [20, 1.5]], "interpolation": "smooth"}}]})";
    auto at = [&](double t) { return parseShape(text, "t.json", "", t).details[0]; };
    EXPECT_EQ(at(0).amplitude, 0.02);   // held before the first key
    EXPECT_EQ(at(25).amplitude, 0.06);  // and after the last
    EXPECT_NEAR(at(15).amplitude, 0.04, 1e-15);
    EXPECT_NEAR(at(12.5).amplitude, 0.03, 1e-15);
    EXPECT_EQ(at(10).frequency, 2.0);
    EXPECT_GT(at(5).frequency, 1.0);
    EXPECT_LE(at(15).frequency, 2.0);  // monotone: no overshoot past the keys
    EXPECT_GE(at(15).frequency, 1.5);
    EXPECT_TRUE(parseShape(text, "t.json").animated);

    auto refused = [](const std::string& t, const std::string& words) {
        try {
            parseShape(t, "t.json");
            ADD_FAILURE() << "accepted " << t;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
        }
    };
    refused(R"({"base": {"type": "sphere", "radius": {"keys": [[0, 1], [9, 2]]}}})",
            "t.json: base.radius: the base and the levels cannot change with time");
    refused(R"({"base": {"type": "sphere"}, "details": [{"type": "rock",
               "amplitude": {"keys": [[2, 1], [1, 2]]}}]})",
            "details[0].amplitude.keys[1][0]: the keys' times must increase");
    refused(R"({"base": {"type": "sphere"}, "details": [{"type": "rock",
               "amplitude": {"keys": [[0, -1], [1, 2]]}}]})",
            "details[0].amplitude: must be between 0");
}

TEST(ShapeAnimation, ASequenceFrameIsTheSingleBakeAtItsTimeAndStillFramesAreIdentical)
{
    const std::string dir = ::testing::TempDir() + "/shape_anim";
    std::filesystem::remove_all(dir);
    std::filesystem::create_directories(dir);
    std::ofstream(dir + "/grow.json") << R"({"base": {"type": "sphere", "radius": 1}, "levels": 4,
        "details": [{"type": "tentacle", "spacing": 0.8, "seed": 2, "levels": [1, 2, 3],
                     "length": {"keys": [[1, 0.01], [3, 0.08]]}, "angle": {"keys": [[1, 0], [3, 90]]}}],
        "blend": {"a": {"details": [{"type": "rock", "amplitude": 0.03}]}, "b": {},
                  "alpha": {"type": "plane", "normal": [0, 0, 1], "point": [0, 0, {"keys": [[1, -1], [3, 1]]}]},
                  "width": 0.5}})";
    const std::string opts = " --voxel-size 0.03 --device cpu";
    auto r = test::run("shape " + dir + "/grow.json --frames 1-4 -o " + dir + "/g.####.vdb" + opts);
    ASSERT_EQ(r.status, 0) << r.err;
    r = test::run("shape " + dir + "/grow.json --time 2 -o " + dir + "/single.vdb" + opts);
    ASSERT_EQ(r.status, 0) << r.err;
    openvdb::initialize();
    auto grids = [&](const std::string& name) { return readLevelSet(dir + "/" + name); };
    const LevelSetGrids two = grids("g.0002.vdb"), single = grids("single.vdb");
    test::expectIdentical(*two.surface, *single.surface, "frame 2 vs a single bake at time 2");
    test::expectIdentical(*two.color, *single.color, "Cd of frame 2 vs the single bake");
    // Frames 3 and 4: every key is past its last: the same shape.
    test::expectIdentical(*grids("g.0003.vdb").surface, *grids("g.0004.vdb").surface,
                          "frames 3 and 4");
    // Frames 1 and 2 differ (the tentacles grow).
    EXPECT_NE(grids("g.0001.vdb").surface->activeVoxelCount(), two.surface->activeVoxelCount());
    // The sequence writer's metadata and --resume.
    EXPECT_FALSE(readFileStamp(dir + "/g.0001.vdb").key.empty());
    r = test::run("shape " + dir + "/grow.json --frames 1-4 -o " + dir + "/g.####.vdb --resume" +
                  opts);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("frame 4: " + dir + "/g.0004.vdb finished before"), std::string::npos)
        << r.out;
    // Frames of another colour extent are another bake's (they were kept).
    r = test::run("shape " + dir + "/grow.json --frames 1-4 -o " + dir +
                  "/g.####.vdb --resume --colour none" + opts);
    EXPECT_EQ(r.status, 2) << r.out;
    EXPECT_NE(r.err.find("exists from another bake"), std::string::npos) << r.err;
    // A sequence is refused before work without a pattern, with a mesh.
    r = test::run("shape " + dir + "/grow.json --frames 1-4 -o " + dir + "/bad.vdb" + opts);
    EXPECT_EQ(r.status, 2);
    r = test::run("shape " + dir + "/grow.json --frames 1-4 -o " + dir + "/bad.####.obj");
    EXPECT_EQ(r.status, 2);
    EXPECT_FALSE(std::filesystem::exists(dir + "/bad.vdb"));
}
