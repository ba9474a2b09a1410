// Multi-scale blending (paper 004, section 6): the ends of the alpha, a shape
// blended with itself, the hard switch, each level's transition width, the
// alpha signals, and the post-blend shader's closed forms.
#include "core/error.h"
#include "io/mesh_file.h"
#include "shape/blend.h"
#include "shape/details.h"
#include "shape/shape.h"
#include "shape/synthesis.h"
#include "test_util.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

using namespace cambium;

namespace {

const char* kBase = R"("base": {"type": "sphere", "radius": 1, "cells": 2}, "levels": 5)";
const char* kRockA = R"({"type": "rock", "amplitude": 0.06, "frequency": 2, "seed": 3})";
const char* kRockB =
    R"({"type": "rock", "amplitude": 0.04, "frequency": 5, "seed": 8, "form": "control-points"})";

ShapeSpec shape(const std::string& text)
{
    return parseShape("{" + text + "}", "test.json");
}

/// A shape blending kRockA (side a) with kRockB (side b) under `alpha`.
std::string blend(const std::string& alpha, double width,
                  const std::string& transition = "per-level")
{
    return std::string(kBase) + R"(, "blend": {"a": {"details": [)" + kRockA +
           R"(]}, "b": {"details": [)" + kRockB + R"(]}, "alpha": )" + alpha + R"(, "width": )" +
           std::to_string(width) + R"(, "transition": ")" + transition + "\"}";
}

std::vector<glm::dvec3> finest(const std::string& text)
{
    ShapeSurface s(shape(text));
    s.synthesize();
    return s.surface().finest().points;
}

/// Each side's details recomputed on a copy of level l of a synthesised blend.
std::vector<glm::dvec3> sideDetail(const ShapeSurface& s, int l, const char* detail)
{
    SubdivLevel copy = s.surface().level(l);
    copy.detail = s.baseDetail(l);  // the sphere's fit to its exact surface
    if (copy.detail.empty())
        copy.detail.assign(copy.vertexCount(), glm::dvec3(0.0));
    std::fill(copy.scalarDetail.begin(), copy.scalarDetail.end(), 0.0);
    const ShapeSpec one = shape(std::string(kBase) + R"(, "details": [)" + detail + "]");
    auto d = makeDetail(one.details[0]);
    // A rock's levels start at 1; apply every level up to l in order (the
    // rock is stateless, only level l writes).
    d->apply(l, copy, Adjacency(copy));
    return copy.detail;
}

const char* kPlane = R"({"type": "plane", "normal": [1, 2, 0], "point": [0.1, 0, 0]})";

double planeDistance(const glm::dvec3& p)
{
    return glm::dot(p - glm::dvec3(0.1, 0, 0), glm::normalize(glm::dvec3(1, 2, 0)));
}

}  // namespace

TEST(Blend, AlphaOneGivesAAndAlphaZeroGivesBExactly)
{
    const auto a = finest(std::string(kBase) + R"(, "details": [)" + kRockA + "]");
    const auto b = finest(std::string(kBase) + R"(, "details": [)" + kRockB + "]");
    EXPECT_EQ(finest(blend(R"({"type": "constant", "value": 1})", 0.5)), a);
    EXPECT_EQ(finest(blend(R"({"type": "constant", "value": 0})", 0.5)), b);
    EXPECT_NE(a, b);
}

TEST(Blend, AShapeBlendedWithItselfIsItself)
{
    const std::string self = std::string(kBase) + R"(, "blend": {"a": {"details": [)" + kRockA +
                             R"(]}, "b": {"details": [)" + kRockA + R"(]}, "alpha": )" + kPlane +
                             R"(, "width": 0.7})";
    EXPECT_EQ(finest(self), finest(std::string(kBase) + R"(, "details": [)" + kRockA + "]"));
}

TEST(Blend, EachLevelIsTheLinearCombinationOfBothSidesDetails)
{
    for (double width : {0.0, 0.6}) {
        ShapeSurface s(shape(blend(kPlane, width)));
        s.synthesize();
        size_t mixed = 0;
        for (int l = 1; l <= s.levels(); ++l) {
            const SubdivLevel& lv = s.surface().level(l);
            const auto dA = sideDetail(s, l, kRockA), dB = sideDetail(s, l, kRockB);
            const double w = width / std::ldexp(1.0, l - 1);
            for (size_t v = 0; v < lv.vertexCount(); ++v) {
                const double alpha = s.alpha(l)[v];
                ASSERT_EQ(alpha, transitionWeight(planeDistance(lv.subdivided[v]), w));
                ASSERT_EQ(lv.detail[v], blendValue(dA[v], dB[v], alpha)) << "level " << l;
                if (width == 0.0) {  // c -> 0: a hard switch, each side's own details
                    ASSERT_EQ(lv.detail[v], planeDistance(lv.subdivided[v]) > 0 ? dA[v] : dB[v]);
                }
                mixed += alpha > 0.0 && alpha < 1.0;
            }
        }
        if (width == 0.0)
            EXPECT_EQ(mixed, 0u);
        else
            EXPECT_GT(mixed, 100u);
    }
}

TEST(Blend, TransitionWidthHalvesPerLevelOrStaysConstant)
{
    const double c = 0.8;
    for (const char* transition : {"per-level", "constant"}) {
        ShapeSurface s(shape(blend(kPlane, c, transition)));
        s.synthesize();
        for (int l = 1; l <= s.levels(); ++l) {
            const SubdivLevel& lv = s.surface().level(l);
            const double expected =
                std::string(transition) == "constant" ? c : c / std::ldexp(1.0, l - 1);
            // The band: the vertices whose weight is strictly between 0 and 1.
            double lo = 1e9, hi = -1e9;
            for (size_t v = 0; v < lv.vertexCount(); ++v)
                if (s.alpha(l)[v] > 0.0 && s.alpha(l)[v] < 1.0) {
                    const double d = planeDistance(lv.subdivided[v]);
                    lo = std::min(lo, d), hi = std::max(hi, d);
                }
            const double measured = hi - lo;
            test::report("transition {} level {}: {:.4f} (expected {:.4f}, edge {:.4f})",
                         transition, l, measured, expected, lv.meanEdgeLength);
            EXPECT_LE(measured, expected);
            EXPECT_GE(measured, expected - 3.0 * lv.meanEdgeLength) << "level " << l;
            EXPECT_NEAR(0.5 * (hi + lo), 0.0, 2.0 * lv.meanEdgeLength);
        }
    }
}

TEST(Blend, StrokesAndPaintedAlphas)
{
    AlphaSpec strokes;
    strokes.type = AlphaType::Strokes;
    strokes.background = 0.25;
    strokes.strokes = {{glm::dvec3(0, 0, 1), 0.3, 1.0}, {glm::dvec3(0, 0, 1.2), 0.1, 0.0}};
    const AlphaSignal signal(strokes, "test.json");
    EXPECT_EQ(signal.at(glm::dvec3(0, 0, -1), 0.1), 0.25);  // beyond every stroke
    EXPECT_EQ(signal.at(glm::dvec3(0, 0, 1.2), 0.1), 0.0);  // the later stroke's centre
    EXPECT_EQ(signal.at(glm::dvec3(0, 0, 0.99), 0.1), 0.25 + 0.75 * editDropOff(0.01 / 0.3));
    // Compositing.
    AlphaSpec inv;
    inv.type = AlphaType::Invert;
    inv.of = {strokes};
    EXPECT_EQ(AlphaSignal(inv, "t").at(glm::dvec3(0, 0, -1), 0.1), 0.75);
    AlphaSpec product;
    product.type = AlphaType::Multiply;
    product.of = {strokes, inv};
    EXPECT_DOUBLE_EQ(AlphaSignal(product, "t").at(glm::dvec3(0, 0, -1), 0.1), 0.25 * 0.75);

    // A painted PLY (as a painter writes: uchar alpha with the colour):
    // each point takes its nearest painted vertex's alpha.
    const std::string dir = ::testing::TempDir() + "/blend_painted";
    std::filesystem::create_directories(dir);
    {
        std::ofstream ply(dir + "/paint.ply");
        ply << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
               "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
               "property uchar alpha\nelement face 1\nproperty list uchar int vertex_indices\n"
               "end_header\n0 0 1 9 9 9 255\n0 0 -1 9 9 9 0\n1 0 0 9 9 9 51\n3 0 1 2\n";
        std::ofstream(dir + "/plain.ply")
            << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
               "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
               "end_header\n0 0 1\n0 0 -1\n1 0 0\n3 0 1 2\n";
    }
    AlphaSpec painted;
    painted.type = AlphaType::Painted;
    painted.path = "blend.alpha";
    painted.file = dir + "/paint.ply";
    const AlphaSignal p(painted, "test.json");
    EXPECT_EQ(p.at(glm::dvec3(0.1, 0, 0.9), 0.0), 1.0);
    EXPECT_EQ(p.at(glm::dvec3(0, 0.1, -0.8), 0.0), 0.0);
    EXPECT_NEAR(p.at(glm::dvec3(0.9, 0, 0.1), 0.0), 0.2, 1e-6);
    painted.file = dir + "/plain.ply";
    try {
        AlphaSignal bad(painted, "test.json");
        ADD_FAILURE() << "a PLY without alpha was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("plain.ply has no vertex alpha"), std::string::npos)
            << e.what();
    }
    // Through a shape: a painted blend matches the painted sides.
    ShapeSurface s(shape(std::string(kBase) + R"(, "blend": {"a": {"details": [)" + kRockA +
                         R"(]}, "b": {"details": []}, "alpha": {"type": "painted", "file": ")" +
                         dir + R"(/paint.ply"}})"));
    s.synthesize();
    const SubdivLevel& f = s.surface().finest();
    for (size_t v = 0; v < f.vertexCount(); v += 97)
        ASSERT_EQ(s.alpha(s.levels())[v], p.at(f.subdivided[v], 0.0));
}

TEST(Blend, BadBlendsAreNamed)
{
    auto says = [](const std::string& text, const std::string& words) {
        std::string e;
        try {
            ShapeSurface s(shape(text));
        } catch (const InputError& x) {
            e = x.what();
        }
        EXPECT_NE(e.find(words), std::string::npos) << "message: '" << e << "' for " << text;
    };
    says(std::string(kBase) + R"(, "blend": {"a": {}, "b": {}, "alpha": {"type": "plain"}})",
         "blend.alpha.type: unknown alpha signal 'plain' (did you mean 'plane'?)");
    says(std::string(kBase) + R"(, "blend": {"a": {}, "alpha": {"type": "constant", "value": 1}})",
         "blend.b: missing");
    says(std::string(kBase) +
             R"(, "blend": {"a": {}, "b": {}, "alpha": {"type": "plane", "normal": [0, 0, 0]}})",
         "blend.alpha.normal: must not be zero");
    says(
        std::string(kBase) +
            R"(, "blend": {"a": {}, "b": {"details": [{"type": "rock", "levels": [9]}]}, "alpha": {"type": "constant", "value": 1}})",
        "blend.b.details[0].levels[0]: level 9 is finer than the shape's 5 levels");
    says(
        std::string(kBase) +
            R"(, "blend": {"a": {}, "b": {}, "alpha": {"type": "strokes", "strokes": [{"at": [0, 0, 1]}]}})",
        "blend.alpha.strokes[0].radius: missing");
    says(
        std::string(kBase) +
            R"(, "blend": {"a": {}, "b": {}, "alpha": {"type": "painted", "file": "/nonexistent/p.ply"}})",
        "blend.alpha.file: /nonexistent/p.ply");
    says(std::string(kBase) +
             R"(, "shader": {"type": "terrain", "sea_level": 0.2, "snow_line": 0.1})",
         "shader.snow_line: must be above the sea level");
    says(std::string(kBase) + R"(, "color": {"a": [1, 0, 0], "b": [0, 1, 0]})",
         "colours of sides \"a\" and \"b\" need a blend");
}

TEST(Shader, ThresholdsAreClosedForms)
{
    ShaderSpec sh;
    sh.enabled = true;
    sh.seaLevel = 0.02, sh.snowLine = 0.1, sh.relief = 0.5, sh.depth = 0.04;
    sh.b.snow = {0.1, 0.9, 0.1};
    // Oceans flattened to the sea level, deep to shallow over `depth`.
    EXPECT_EQ(shade(sh, -0.3, 1.0).height, 0.5 * 0.02);
    EXPECT_EQ(shade(sh, 0.01, 1.0).height, 0.5 * 0.02);
    EXPECT_EQ(shade(sh, -0.3, 1.0).color, sh.a.deep);
    EXPECT_EQ(shade(sh, 0.02 - 1e-12, 1.0).color.z,
              (sh.a.deep + (sh.a.shallow - sh.a.deep) * (1.0 - 1e-12 / 0.04)).z);
    // Land: relief times the scalar; lowland to mountain, then snow.
    EXPECT_EQ(shade(sh, 0.06, 1.0).height, 0.5 * 0.06);
    const glm::dvec3 mid = shade(sh, 0.06, 1.0).color;
    EXPECT_NEAR(glm::length(mid - 0.5 * (sh.a.lowland + sh.a.mountain)), 0.0, 1e-12);
    EXPECT_EQ(shade(sh, 0.1, 1.0).color, sh.a.snow);
    // The blend parameter picks the palette.
    EXPECT_EQ(shade(sh, 0.5, 0.0).color, sh.b.snow);
    EXPECT_EQ(shade(sh, 0.5, 0.25).color, sh.b.snow + 0.25 * (sh.a.snow - sh.b.snow));
}

TEST(Shader, OnAShapeHeightsFollowTheScalarAndColoursTheBlendParameter)
{
    const std::string text =
        std::string(kBase) +
        R"(, "blend": {"a": {"details": [{"type": "rock", "amplitude": 0.1, "seed": 3, "displace": 0}]},
                      "b": {"details": [{"type": "rock", "amplitude": 0.1, "seed": 9, "displace": 0}]},
                      "alpha": )" +
        kPlane + R"(, "width": 0.5},
           "shader": {"type": "terrain", "sea_level": 0.0, "snow_line": 0.03, "relief": 0.3,
                      "b": {"snow": [1, 0, 0], "lowland": [0, 0, 1]}})";
    ShapeSurface s(shape(text));
    s.synthesize();
    const SubdivLevel& f = s.surface().finest();
    const TriangleMesh m = s.mesh();
    const std::vector<double> beta = s.blendParameter();
    size_t sea = 0, snowA = 0, snowB = 0;
    double farA = 0.0, farB = 0.0;
    size_t nA = 0, nB = 0;
    for (size_t v = 0; v < f.vertexCount(); ++v) {
        // displace 0: the synthesised surface is the smooth sphere's subdivision.
        const glm::dvec3 n = glm::normalize(f.points[v]);
        const glm::dvec3 p(m.points[v][0], m.points[v][1], m.points[v][2]);
        const double lift = glm::dot(p - f.points[v], n);
        ASSERT_NEAR(lift, 0.3 * std::max(f.scalar[v], 0.0), 2e-3 * 0.3 + 1e-6);
        sea += f.scalar[v] < 0.0;
        // Every colour is the shader's of the point's scalar and blend parameter.
        const glm::dvec3 c = shade(s.spec().shader, f.scalar[v], beta[v]).color;
        ASSERT_EQ(m.colors[v], openvdb::math::Vec3s(float(c.x), float(c.y), float(c.z)));
        ASSERT_GE(beta[v], 0.0);
        ASSERT_LE(beta[v], 1.0);
        const double d = planeDistance(f.points[v]);
        if (d > 0.5)
            farA += beta[v], ++nA, snowA += beta[v] > 0.999 && f.scalar[v] >= 0.03;
        if (d < -0.5)
            farB += beta[v], ++nB, snowB += beta[v] < 0.001 && f.scalar[v] >= 0.03;
    }
    test::report("mean blend parameter far on A's side {:.5f}, on B's {:.5f}", farA / double(nA),
                 farB / double(nB));
    EXPECT_GT(farA / double(nA), 0.99);
    EXPECT_LT(farB / double(nB), 0.01);
    EXPECT_GT(sea, f.vertexCount() / 10);
    EXPECT_GT(snowA, 10u);
    EXPECT_GT(snowB, 10u);
}
