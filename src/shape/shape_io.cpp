// cambium — reading shape files (docs/shape-format.md).
#include "shape/shape.h"

#include "core/error.h"
#include "core/json.h"
#include "core/math.h"
#include "subdiv/multires.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

namespace cambium {

namespace {

using json = nlohmann::json;

const std::map<std::string, BaseType> kBaseTypes = {
    {"cube", BaseType::Cube},    {"sphere", BaseType::Sphere}, {"torus", BaseType::Torus},
    {"plane", BaseType::Plane},  {"fuse", BaseType::Fuse},     {"mesh", BaseType::Mesh},
    {"vdb", BaseType::LevelSet}, {"model", BaseType::Model}};
const std::map<std::string, DetailType> kDetailTypes = {{"rock", DetailType::Rock},
                                                        {"berry", DetailType::Berry},
                                                        {"tentacle", DetailType::Tentacle},
                                                        {"mushroom", DetailType::Mushroom},
                                                        {"spur", DetailType::Spur}};

template <class T>
std::vector<std::string> names(const std::map<std::string, T>& m)
{
    std::vector<std::string> out;
    for (const auto& [k, v] : m)
        out.push_back(k);
    return out;
}

class Reader : private JsonValidator {
public:
    Reader(std::string source, std::string directory)
        : JsonValidator(std::move(source)), directory_(std::move(directory))
    {
    }

    ShapeSpec read(const std::string& text) const
    {
        const json root = parseJson(text, source());
        object(root, "(top level)", "must be an object");
        required(root, "base", "", "the base shape, e.g. {\"type\": \"sphere\", \"radius\": 1}");
        checkKeys(root, "", {"name", "base", "levels", "details", "edits", "color"});
        ShapeSpec s;
        s.source = source();
        if (root.contains("name"))
            string(root["name"], "name");
        s.levels = wholeNumber(root, "levels", "", s.levels, 0, kMaxSubdivisionLevels,
                               " (OpenSubdiv's uniform refinement stops at 15)");
        s.base = readBase(root["base"], "base");
        if (root.contains("details")) {
            const json& d = root["details"];
            if (!d.is_array())
                fail("details", fmt::format("must be an array of details (got {})", jsonKind(d)));
            for (size_t i = 0; i < d.size(); ++i)
                s.details.push_back(readDetail(d[i], fmt::format("details[{}]", i), s.levels));
        }
        if (root.contains("edits")) {
            const json& e = root["edits"];
            if (!e.is_array())
                fail("edits", fmt::format("must be an array of edits (got {})", jsonKind(e)));
            for (size_t i = 0; i < e.size(); ++i)
                s.edits.push_back(readEdit(e[i], fmt::format("edits[{}]", i), s.levels));
        }
        if (root.contains("color"))
            s.color = readColor(root["color"], "color");
        return s;
    }

private:
    std::string directory_;

    int wholeNumber(const json& obj, const char* key, const std::string& path, int value, int lo,
                    int hi, const char* why = "") const
    {
        if (!obj.contains(key))
            return value;
        const std::string p = jsonPath(path, key);
        const double v = number(obj.at(key), p);
        if (v != std::floor(v))
            fail(p, fmt::format("must be a whole number (got {})", v));
        if (v < lo || v > hi)
            fail(p, fmt::format("must be from {} to {} (got {}){}", lo, hi, v, why));
        return int(v);
    }

    double numberOr(const json& obj, const char* key, const std::string& path, double value,
                    double lo, double hi) const
    {
        if (!obj.contains(key))
            return value;
        return number(obj.at(key), jsonPath(path, key), lo, hi);
    }

    glm::dvec3 point(const json& j, const std::string& path) const
    {
        const json& a = array(j, path, 3, "must be a point [x, y, z]");
        return {number(a[0], path + "[0]"), number(a[1], path + "[1]"), number(a[2], path + "[2]")};
    }

    glm::dvec3 colour(const json& j, const std::string& path) const
    {
        const json& a = array(j, path, 3, "must be a colour [r, g, b]");
        glm::dvec3 c;
        for (int k = 0; k < 3; ++k)
            c[k] = number(a[size_t(k)], fmt::format("{}[{}]", path, k), 0.0, 1.0);
        return c;
    }

    std::string file(const json& obj, const std::string& path, const char* key = "file") const
    {
        const std::string f = string(required(obj, key, path), jsonPath(path, key));
        if (f.empty())
            fail(jsonPath(path, key), "must name a file");
        const std::filesystem::path p(f);
        const std::string full = p.is_absolute() || directory_.empty()
                                     ? f
                                     : (std::filesystem::path(directory_) / p).string();
        try {
            checkInputFile(full, "base file");
        } catch (const InputError& e) {
            fail(jsonPath(path, key), e.what());
        }
        return full;
    }

    BaseSpec readBase(const json& j, const std::string& path) const
    {
        object(j, path, "must be an object such as {\"type\": \"sphere\", \"radius\": 1}");
        const std::string type = string(required(j, "type", path), jsonPath(path, "type"));
        const auto it = kBaseTypes.find(type);
        if (it == kBaseTypes.end())
            fail(jsonPath(path, "type"),
                 fmt::format("unknown base '{}'{}; known: {}", type,
                             didYouMean(type, names(kBaseTypes)), joinWords(names(kBaseTypes))));
        BaseSpec b;
        b.type = it->second;
        const double big = 1e6;
        switch (b.type) {
            case BaseType::Cube:
                checkKeys(j, path, {"type", "size"});
                b.size = numberOr(j, "size", path, b.size, 1e-6, big);
                break;
            case BaseType::Sphere:
                checkKeys(j, path, {"type", "radius", "cells"});
                b.radius = numberOr(j, "radius", path, b.radius, 1e-6, big);
                b.sphereCells = wholeNumber(j, "cells", path, b.sphereCells, 1, 256);
                break;
            case BaseType::Torus:
                checkKeys(j, path, {"type", "major", "minor", "around", "tube"});
                b.major = numberOr(j, "major", path, b.major, 1e-6, big);
                b.minor = numberOr(j, "minor", path, b.minor, 1e-6, big);
                if (!(b.minor < b.major))
                    fail(jsonPath(path, "minor"),
                         fmt::format("must be less than major ({} >= {}): the torus would pass "
                                     "through its axis",
                                     b.minor, b.major));
                b.around = wholeNumber(j, "around", path, b.around, 3, 1024);
                b.tube = wholeNumber(j, "tube", path, b.tube, 3, 1024);
                break;
            case BaseType::Plane:
                checkKeys(j, path, {"type", "size", "cells"});
                b.size = numberOr(j, "size", path, b.size, 1e-6, big);
                b.cells = wholeNumber(j, "cells", path, b.cells, 1, 1024);
                break;
            case BaseType::Fuse:
                checkKeys(j, path, {"type", "length", "radius", "terms", "around", "rings"});
                b.length = numberOr(j, "length", path, b.length, 1e-6, big);
                b.radius = numberOr(j, "radius", path, b.radius, 1e-6, big);
                b.terms = wholeNumber(j, "terms", path, b.terms, 1, 2,
                                      ": with more terms the profile turns negative near its tip");
                b.around = wholeNumber(j, "around", path, b.around, 3, 1024);
                b.rings = wholeNumber(j, "rings", path, b.rings, 2, 1024);
                break;
            case BaseType::Mesh:
                checkKeys(j, path,
                          {"type", "file", "analyse", "voxel_size", "fine_voxel_size", "control"});
                b.file = file(j, path);
                if (j.contains("analyse"))
                    b.analyse = boolean(j["analyse"], jsonPath(path, "analyse"));
                b.coarseVoxelSize = numberOr(j, "voxel_size", path, 0.0, 1e-4, big);
                b.fineVoxelSize = numberOr(j, "fine_voxel_size", path, 0.0, 1e-4, big);
                if (j.contains("control"))
                    b.control = file(j, path, "control");
                if (!b.analyse &&
                    (b.coarseVoxelSize > 0.0 || b.fineVoxelSize > 0.0 || !b.control.empty()))
                    fail(jsonPath(path, "analyse"),
                         "voxel_size, fine_voxel_size and control are for an analysed mesh: "
                         "add \"analyse\": true");
                break;
            case BaseType::LevelSet:
                checkKeys(j, path, {"type", "file", "voxel_size", "control"});
                b.file = file(j, path);
                b.coarseVoxelSize = numberOr(j, "voxel_size", path, 0.0, 1e-4, big);
                if (j.contains("control"))
                    b.control = file(j, path, "control");
                break;
            case BaseType::Model:
                checkKeys(j, path,
                          {"type", "file", "voxel_size", "fine_voxel_size", "year", "control"});
                if (j.contains("control"))
                    b.control = file(j, path, "control");
                b.file = file(j, path);
                b.coarseVoxelSize = numberOr(j, "voxel_size", path, 0.0, 1e-4, big);
                b.fineVoxelSize = numberOr(j, "fine_voxel_size", path, 0.0, 1e-4, big);
                b.year = numberOr(j, "year", path, 0.0, 0.0, 1000.0);
                break;
        }
        return b;
    }

    std::vector<int> levelList(const json& obj, const std::string& path, std::vector<int> value,
                               int shapeLevels) const
    {
        if (!obj.contains("levels"))
            return value;
        const std::string p = jsonPath(path, "levels");
        const json& a = obj["levels"];
        if (!a.is_array() || a.empty())
            fail(p, fmt::format("must be a non-empty array of levels, e.g. [1, 3] (got {})",
                                jsonKind(a)));
        std::vector<int> out;
        for (size_t i = 0; i < a.size(); ++i) {
            const std::string pi = fmt::format("{}[{}]", p, i);
            const double v = number(a[i], pi);
            if (v != std::floor(v) || v < 1)
                fail(pi, fmt::format("must be a level from 1 (got {})", v));
            if (v > shapeLevels)
                fail(pi,
                     fmt::format("level {} is finer than the shape's {} levels", v, shapeLevels));
            if (!out.empty() && int(v) <= out.back())
                fail(pi, "the levels must be listed in increasing order");
            out.push_back(int(v));
        }
        return out;
    }

    static std::vector<int> range(int from, int to)
    {
        std::vector<int> out;
        for (int l = from; l <= to; ++l)
            out.push_back(l);
        return out;
    }

    void readSeeds(const json& j, const std::string& path, DetailSpec& d) const
    {
        if (j.contains("at")) {
            const json& a = j["at"];
            const std::string p = jsonPath(path, "at");
            if (!a.is_array() || a.empty())
                fail(p, "must be a non-empty array of points [[x, y, z], ...]");
            for (size_t i = 0; i < a.size(); ++i)
                d.at.push_back(point(a[i], fmt::format("{}[{}]", p, i)));
        }
        if (j.contains("spacing"))
            d.spacing = number(j["spacing"], jsonPath(path, "spacing"), 1e-6, 1e6);
        if (d.at.empty() && d.spacing == 0.0)
            fail(path,
                 "needs seeds: \"at\" (points on the surface) or \"spacing\" (a "
                 "Poisson-disk set over the whole surface)");
        if (!d.at.empty() && d.spacing > 0.0)
            fail(jsonPath(path, "spacing"), "give \"at\" or \"spacing\", not both");
    }

    DetailSpec readDetail(const json& j, const std::string& path, int shapeLevels) const
    {
        object(j, path, "must be an object such as {\"type\": \"rock\", \"amplitude\": 0.05}");
        const std::string type = string(required(j, "type", path), jsonPath(path, "type"));
        const auto it = kDetailTypes.find(type);
        if (it == kDetailTypes.end())
            fail(jsonPath(path, "type"), fmt::format("unknown detail '{}'{}; known: {}", type,
                                                     didYouMean(type, names(kDetailTypes)),
                                                     joinWords(names(kDetailTypes))));
        DetailSpec d;
        d.type = it->second;
        d.path = path;
        const int L = shapeLevels;
        if (L < 1)
            fail(path, "details need at least one subdivision level (\"levels\" is 0)");
        d.seed = uint32_t(numberOr(j, "seed", path, 0, 0, 4294967295.0));
        d.scalar = numberOr(j, "scalar", path, d.scalar, -1e6, 1e6);
        const double big = 1e6;
        switch (d.type) {
            case DetailType::Rock:
                checkKeys(j, path,
                          {"type", "levels", "seed", "scalar", "amplitude", "frequency", "form"});
                d.levels = levelList(j, path, range(1, L), L);
                d.amplitude = numberOr(j, "amplitude", path, d.amplitude, 0.0, big);
                d.frequency = numberOr(j, "frequency", path, d.frequency, 1e-6, big);
                if (j.contains("form")) {
                    const std::string f = string(j["form"], jsonPath(path, "form"));
                    if (f != "noise" && f != "control-points")
                        fail(jsonPath(path, "form"),
                             fmt::format("must be \"noise\" (one pass) or \"control-points\" (a "
                                         "random value per control point) (got '{}')",
                                         f));
                    d.perControlPoint = f == "control-points";
                }
                break;
            case DetailType::Berry:
                checkKeys(
                    j, path,
                    {"type", "levels", "seed", "scalar", "radius", "spacing", "at", "children"});
                d.levels = levelList(j, path, range(1, std::min(L, 3)), L);
                d.radius = numberOr(j, "radius", path, d.radius, 1e-6, big);
                d.children = wholeNumber(j, "children", path, d.children, 0, 64);
                if (std::pow(double(std::max(d.children, 1)), double(d.levels.size() - 1)) > 4096.0)
                    fail(jsonPath(path, "children"),
                         fmt::format("{} children a seed over {} levels make {:.3g} seeds of each "
                                     "first one (at most 4096): fewer children or levels",
                                     d.children, d.levels.size(),
                                     std::pow(double(d.children), double(d.levels.size() - 1))));
                if (!j.contains("at") && !j.contains("spacing"))
                    d.spacing = 2.0 * d.radius;
                readSeeds(j, path, d);
                break;
            case DetailType::Tentacle:
                checkKeys(j, path,
                          {"type", "levels", "seed", "scalar", "length", "angle", "spacing", "at"});
                d.levels = levelList(j, path, range(1, std::min(L, 5)), L);
                d.length = numberOr(j, "length", path, d.length, 0.0, big);
                d.angle = numberOr(j, "angle", path, 0.0, -1e6, 1e6) * kDegree;
                readSeeds(j, path, d);
                break;
            case DetailType::Mushroom:
                checkKeys(
                    j, path,
                    {"type", "levels", "seed", "scalar", "radius", "height", "spacing", "at"});
                d.levels = levelList(j, path, range(1, L), L);
                d.radius = numberOr(j, "radius", path, d.radius, 1e-6, big);
                d.height = numberOr(j, "height", path, d.height, 0.0, big);
                readSeeds(j, path, d);
                break;
            case DetailType::Spur:
                checkKeys(j, path,
                          {"type", "levels", "seed", "scalar", "radius", "height", "spacing", "at",
                           "placement"});
                d.levels = levelList(j, path, {1}, L);
                d.radius = numberOr(j, "radius", path, d.radius, 1e-6, big);
                d.height = numberOr(j, "height", path, d.height, -big, big);
                readSeeds(j, path, d);
                if (j.contains("placement")) {
                    const std::string p = string(j["placement"], jsonPath(path, "placement"));
                    if (p != "control-points" && p != "chart")
                        fail(jsonPath(path, "placement"),
                             fmt::format("must be \"control-points\" or \"chart\" (got '{}')", p));
                    d.placement = p == "chart" ? Placement::Chart : Placement::ControlPoints;
                }
                break;
        }
        return d;
    }

    EditSpec readEdit(const json& j, const std::string& path, int shapeLevels) const
    {
        object(j, path,
               "must be an object such as {\"at\": [0, 0, 1], \"radius\": 0.2, \"gain\": 0}");
        checkKeys(j, path, {"at", "radius", "gain", "levels", "distance"});
        EditSpec e;
        e.path = path;
        e.at = point(required(j, "at", path), jsonPath(path, "at"));
        e.radius = number(required(j, "radius", path), jsonPath(path, "radius"), 1e-9, 1e6);
        e.gain = number(required(j, "gain", path), jsonPath(path, "gain"), -100.0, 100.0);
        e.levels = levelList(j, path, range(1, shapeLevels), shapeLevels);
        if (e.levels.empty())
            fail(path, "an edit needs at least one subdivision level (\"levels\" is 0)");
        if (j.contains("distance")) {
            const std::string d = string(j["distance"], jsonPath(path, "distance"));
            if (d != "metric" && d != "topological")
                fail(jsonPath(path, "distance"),
                     fmt::format("must be \"metric\" or \"topological\" (got '{}')", d));
            e.topological = d == "topological";
        }
        return e;
    }

    ColorSpec readColor(const json& j, const std::string& path) const
    {
        ColorSpec c;
        if (j.is_array()) {
            c.color = colour(j, path);
            return c;
        }
        object(j, path,
               "must be [r, g, b] or a ramp {\"scalar\": [lo, hi], \"low\": [r, g, b], "
               "\"high\": [r, g, b]}");
        checkKeys(j, path, {"scalar", "low", "high"});
        c.ramp = true;
        const json& s = array(required(j, "scalar", path), jsonPath(path, "scalar"), 2,
                              "must be the scalar range [lo, hi]");
        c.low = number(s[0], jsonPath(path, "scalar") + "[0]");
        c.high = number(s[1], jsonPath(path, "scalar") + "[1]");
        if (!(c.high > c.low))
            fail(jsonPath(path, "scalar"), "the range must be increasing");
        c.lowColor = colour(required(j, "low", path), jsonPath(path, "low"));
        c.highColor = colour(required(j, "high", path), jsonPath(path, "high"));
        return c;
    }
};

}  // namespace

ShapeSpec parseShape(const std::string& text, const std::string& source,
                     const std::string& directory)
{
    return Reader(source, directory).read(text);
}

ShapeSpec readShapeFile(const std::string& path)
{
    const std::string text = readTextFile(path, "shape file");
    return parseShape(text, path, std::filesystem::path(path).parent_path().string());
}

bool looksLikeShapeFile(const std::string& path)
{
    try {
        const json root = parseJson(readTextFile(path, "shape file"), path);
        return root.is_object() && root.contains("base");
    } catch (const InputError&) {
        return false;
    }
}

}  // namespace cambium
