// cambium — reading shape files (docs/shape-format.md).
#include "shape/shape.h"

#include "core/error.h"
#include "core/files.h"
#include "core/json.h"
#include "core/math.h"
#include "model/curve.h"
#include "subdiv/multires.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
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

    ShapeSpec read(const std::string& text, double time, int levels) const
    {
        bool animated = false;
        const json root = atTime(parseJson(text, source()), "", time, animated);
        object(root, "(top level)", "must be an object");
        required(root, "base", "", "the base shape, e.g. {\"type\": \"sphere\", \"radius\": 1}");
        checkKeys(root, "",
                  {"name", "base", "levels", "details", "edits", "blend", "shader", "color"});
        ShapeSpec s;
        s.source = source();
        s.time = time;
        s.animated = animated;
        if (root.contains("name"))
            string(root["name"], "name");
        s.levels = wholeNumber(root, "levels", "", s.levels, 0, kMaxSubdivisionLevels,
                               " (OpenSubdiv's uniform refinement stops at 15)");
        // (--levels: the details' default levels follow it, as they follow
        // the file's; they kept the file's, and a coarser --levels was
        // refused over a key the file does not have)
        if (levels >= 0)
            s.levels = levels;
        s.base = readBase(root["base"], "base");
        s.details = details(root, "", s.levels);
        s.edits = edits(root, "", s.levels);
        if (root.contains("blend"))
            s.blend = readBlend(root["blend"], "blend", s.levels);
        if (root.contains("shader"))
            s.shader = readShader(root["shader"], "shader");
        if (root.contains("color"))
            s.color = readColor(root["color"], "color");
        if (!s.color.sides.empty() && !s.blend.enabled)
            fail("color", "colours of sides \"a\" and \"b\" need a blend");
        if (s.shader.enabled && root.contains("color"))
            fail("color", "a shape with a shader takes its colours from the shader's palettes");
        return s;
    }

private:
    std::string directory_;

    /// `j` with every keyframed number replaced by its value at `time`.
    json atTime(const json& j, const std::string& path, double time, bool& animated) const
    {
        if (j.is_array()) {
            json out = json::array();
            for (size_t i = 0; i < j.size(); ++i)
                out.push_back(atTime(j[i], fmt::format("{}[{}]", path, i), time, animated));
            return out;
        }
        if (!j.is_object())
            return j;
        if (!j.contains("keys")) {
            json out = json::object();
            for (const auto& [k, v] : j.items())
                out[k] = atTime(v, jsonPath(path, k), time, animated);
            return out;
        }
        // {"keys": [[t, v], ...], "interpolation": ...}
        if (path == "levels" || path.rfind("base", 0) == 0)
            fail(path,
                 "the base and the levels cannot change with time (the refinement is built "
                 "once for a whole sequence); keyframe the details, the blend or the shader");
        checkKeys(j, path, {"keys", "interpolation"});
        const std::string kp = jsonPath(path, "keys");
        const json& keys = j["keys"];
        if (!keys.is_array() || keys.empty())
            fail(kp, "must be a non-empty array of keys [[time, value], ...]");
        std::vector<std::pair<double, double>> points;
        for (size_t i = 0; i < keys.size(); ++i) {
            const std::string p = fmt::format("{}[{}]", kp, i);
            const json& key = array(keys[i], p, 2, "must be a key [time, value]");
            // (times within kFarthestCoordinate: their span stays finite)
            points.emplace_back(
                number(key[0], p + "[0]", -kFarthestCoordinate, kFarthestCoordinate),
                number(key[1], p + "[1]"));
            if (i > 0 && !(points[i].first > points[i - 1].first))
                fail(p + "[0]", "the keys' times must increase");
        }
        Curve::Interpolation interpolation = Curve::Interpolation::Linear;
        if (j.contains("interpolation")) {
            interpolation = choice(j["interpolation"], jsonPath(path, "interpolation"),
                                   {"linear", "smooth"}) == 1
                                ? Curve::Interpolation::Smooth
                                : Curve::Interpolation::Linear;
        }
        animated = true;
        if (points.size() == 1)
            return points[0].second;
        // A curve on [0, 1] over the keys' span (the Hermite slopes scale with it).
        const double t0 = points.front().first, span = points.back().first - t0;
        for (auto& [t, v] : points)
            t = (t - t0) / span;
        points.back().first = 1.0;
        const Curve curve(points, interpolation, source() + ": " + kp);
        return curve(std::clamp((time - t0) / span, 0.0, 1.0));
    }

    /// A "seed": a whole number from 0 to 2^32 - 1 (0 where absent; 1.5 was
    /// read as 1 without a word).
    uint32_t seedOf(const json& j, const std::string& path) const
    {
        const double v = numberOr(j, "seed", path, 0, 0, 4294967295.0);
        if (v != std::floor(v))
            fail(jsonPath(path, "seed"), fmt::format("must be a whole number (got {})", v));
        return uint32_t(v);
    }

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

    std::string file(const json& obj, const std::string& path, const char* key = "file",
                     const char* what = "base file") const
    {
        return inputFile(required(obj, key, path), jsonPath(path, key), directory_, what);
    }

    /// Member "type" of the object `j` as one of `kinds`: "PATH.type: unknown
    /// NOUN 'X' (did you mean ...); known: ..." otherwise.
    template <class T>
    T typeOf(const json& j, const std::string& path, const std::map<std::string, T>& kinds,
             const char* noun) const
    {
        const std::string type = string(required(j, "type", path), jsonPath(path, "type"));
        const auto it = kinds.find(type);
        if (it == kinds.end())
            fail(jsonPath(path, "type"),
                 fmt::format("unknown {} '{}'{}; known: {}", noun, type,
                             didYouMean(type, names(kinds)), joinWords(names(kinds))));
        return it->second;
    }

    BaseSpec readBase(const json& j, const std::string& path) const
    {
        object(j, path, "must be an object such as {\"type\": \"sphere\", \"radius\": 1}");
        BaseSpec b;
        b.type = typeOf(j, path, kBaseTypes, "base");
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
                if (sameFile(b.file, source()))
                    fail(jsonPath(path, "file"),
                         "is this shape file itself: a model base is a scene, L-system or "
                         "growth file");
                b.coarseVoxelSize = numberOr(j, "voxel_size", path, 0.0, 1e-4, big);
                b.fineVoxelSize = numberOr(j, "fine_voxel_size", path, 0.0, 1e-4, big);
                b.year = numberOr(j, "year", path, -1.0, 0.0, 1000.0);  // (absent: the last)
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
        DetailSpec d;
        d.type = typeOf(j, path, kDetailTypes, "detail");
        d.path = path;
        const int L = shapeLevels;
        if (L < 1)
            fail(path, "details need at least one subdivision level (\"levels\" is 0)");
        d.seed = seedOf(j, path);
        d.scalar = numberOr(j, "scalar", path, d.scalar, -1e6, 1e6);
        d.displace = numberOr(j, "displace", path, d.displace, -1e6, 1e6);
        const double big = 1e6;
        switch (d.type) {
            case DetailType::Rock:
                checkKeys(j, path,
                          {"type", "levels", "seed", "scalar", "displace", "amplitude", "frequency",
                           "form"});
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
                checkKeys(j, path,
                          {"type", "levels", "seed", "scalar", "displace", "radius", "spacing",
                           "at", "children"});
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
                          {"type", "levels", "seed", "scalar", "displace", "length", "angle",
                           "spacing", "at"});
                d.levels = levelList(j, path, range(1, std::min(L, 5)), L);
                d.length = numberOr(j, "length", path, d.length, 0.0, big);
                d.angle = numberOr(j, "angle", path, 0.0, -1e6, 1e6) * kDegree;
                readSeeds(j, path, d);
                break;
            case DetailType::Mushroom:
                checkKeys(j, path,
                          {"type", "levels", "seed", "scalar", "displace", "radius", "height",
                           "spacing", "at"});
                d.levels = levelList(j, path, range(1, L), L);
                d.radius = numberOr(j, "radius", path, d.radius, 1e-6, big);
                d.height = numberOr(j, "height", path, d.height, 0.0, big);
                readSeeds(j, path, d);
                break;
            case DetailType::Spur:
                checkKeys(j, path,
                          {"type", "levels", "seed", "scalar", "displace", "radius", "height",
                           "spacing", "at", "placement"});
                d.levels = levelList(j, path, {1}, L);
                d.radius = numberOr(j, "radius", path, d.radius, 1e-6, big);
                d.height = numberOr(j, "height", path, d.height, -big, big);
                readSeeds(j, path, d);
                if (j.contains("placement")) {
                    d.placement = choice(j["placement"], jsonPath(path, "placement"),
                                         {"control-points", "chart"}) == 1
                                      ? Placement::Chart
                                      : Placement::ControlPoints;
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
            e.topological =
                choice(j["distance"], jsonPath(path, "distance"), {"metric", "topological"}) == 1;
        }
        return e;
    }

    template <class T>
    std::vector<T> list(const json& obj, const char* key, const std::string& path, const char* what,
                        const std::function<T(const json&, const std::string&)>& one) const
    {
        std::vector<T> out;
        if (!obj.contains(key))
            return out;
        const std::string p = jsonPath(path, key);
        const json& a = obj[key];
        if (!a.is_array())
            fail(p, fmt::format("must be an array of {} (got {})", what, jsonKind(a)));
        for (size_t i = 0; i < a.size(); ++i)
            out.push_back(one(a[i], fmt::format("{}[{}]", p, i)));
        return out;
    }

    std::vector<DetailSpec> details(const json& obj, const std::string& path, int levels) const
    {
        return list<DetailSpec>(
            obj, "details", path, "details",
            [&](const json& j, const std::string& p) { return readDetail(j, p, levels); });
    }

    std::vector<EditSpec> edits(const json& obj, const std::string& path, int levels) const
    {
        return list<EditSpec>(
            obj, "edits", path, "edits",
            [&](const json& j, const std::string& p) { return readEdit(j, p, levels); });
    }

    BlendSide readSide(const json& j, const std::string& path, int levels) const
    {
        object(j, path,
               "must be a shape's details on the shared base, e.g. {\"details\": [{\"type\": "
               "\"rock\"}]}");
        checkKeys(j, path, {"details", "edits", "base_detail"});
        BlendSide side;
        if (j.contains("base_detail"))
            side.baseDetail = boolean(j["base_detail"], jsonPath(path, "base_detail"));
        side.details = details(j, path, levels);
        side.edits = edits(j, path, levels);
        return side;
    }

    BlendSpec readBlend(const json& j, const std::string& path, int levels) const
    {
        object(j, path,
               "must be an object {\"a\": {...}, \"b\": {...}, \"alpha\": {...}, "
               "\"width\": W}");
        checkKeys(j, path, {"a", "b", "alpha", "width", "transition"});
        BlendSpec b;
        b.enabled = true;
        b.a = readSide(required(j, "a", path), jsonPath(path, "a"), levels);
        b.b = readSide(required(j, "b", path), jsonPath(path, "b"), levels);
        b.alpha = readAlpha(required(j, "alpha", path), jsonPath(path, "alpha"));
        b.width = numberOr(j, "width", path, 0.0, 0.0, 1e6);
        if (j.contains("transition")) {
            const std::string t = string(j["transition"], jsonPath(path, "transition"));
            if (t != "per-level" && t != "constant")
                fail(jsonPath(path, "transition"),
                     fmt::format("must be \"per-level\" (width / 2^(level-1): sharp at fine "
                                 "levels) or \"constant\" (the same width at every level: a "
                                 "soft blend) (got '{}')",
                                 t));
            b.constantWidth = t == "constant";
        }
        return b;
    }

    AlphaSpec readAlpha(const json& j, const std::string& path) const
    {
        static const std::map<std::string, AlphaType> kinds = {
            {"constant", AlphaType::Constant}, {"plane", AlphaType::Plane},
            {"sphere", AlphaType::Sphere},     {"noise", AlphaType::Noise},
            {"strokes", AlphaType::Strokes},   {"painted", AlphaType::Painted},
            {"multiply", AlphaType::Multiply}, {"screen", AlphaType::Screen},
            {"max", AlphaType::Max},           {"min", AlphaType::Min},
            {"invert", AlphaType::Invert}};
        object(j, path,
               "must be an alpha signal such as {\"type\": \"plane\", \"normal\": [1, 2, 0]}");
        AlphaSpec a;
        a.type = typeOf(j, path, kinds, "alpha signal");
        a.path = path;
        switch (a.type) {
            case AlphaType::Constant:
                checkKeys(j, path, {"type", "value"});
                a.value = number(required(j, "value", path), jsonPath(path, "value"), 0.0, 1.0);
                break;
            case AlphaType::Plane: {
                checkKeys(j, path, {"type", "normal", "point"});
                const glm::dvec3 n = point(required(j, "normal", path), jsonPath(path, "normal"));
                if (!(glm::length(n) > 0.0))
                    fail(jsonPath(path, "normal"), "must not be zero");
                a.normal = glm::normalize(n);
                if (j.contains("point"))
                    a.point = point(j["point"], jsonPath(path, "point"));
                break;
            }
            case AlphaType::Sphere:
                checkKeys(j, path, {"type", "center", "radius"});
                if (j.contains("center"))
                    a.point = point(j["center"], jsonPath(path, "center"));
                a.radius = number(required(j, "radius", path), jsonPath(path, "radius"), 0.0, 1e6);
                break;
            case AlphaType::Noise:
                checkKeys(j, path, {"type", "frequency", "threshold", "seed"});
                a.frequency = numberOr(j, "frequency", path, a.frequency, 1e-6, 1e6);
                a.threshold = numberOr(j, "threshold", path, 0.0, -1.0, 1.0);
                a.seed = seedOf(j, path);
                break;
            case AlphaType::Strokes: {
                checkKeys(j, path, {"type", "strokes", "file", "background"});
                a.background = numberOr(j, "background", path, 0.0, 0.0, 1.0);
                if (j.contains("strokes") == j.contains("file"))
                    fail(path,
                         "give the strokes inline (\"strokes\": [...]) or in a JSON file "
                         "(\"file\"), one of the two");
                json strokes;
                std::string where = jsonPath(path, "strokes");
                if (j.contains("file")) {
                    const std::string f = file(j, path, "file", "strokes file");
                    strokes = parseJson(readTextFile(f, "strokes file"), f);
                    where = f;
                    a.file = f;
                } else {
                    strokes = j["strokes"];
                }
                if (!strokes.is_array() || strokes.empty())
                    fail(where,
                         "must be a non-empty array of strokes [{\"at\": [x, y, z], "
                         "\"radius\": r, \"value\": v}, ...]");
                for (size_t i = 0; i < strokes.size(); ++i) {
                    const std::string p = fmt::format("{}[{}]", where, i);
                    const json& st = strokes[i];
                    object(st, p,
                           "must be a stroke {\"at\": [x, y, z], \"radius\": r, \"value\": v}");
                    checkKeys(st, p, {"at", "radius", "value"});
                    Stroke k;
                    k.at = point(required(st, "at", p), jsonPath(p, "at"));
                    k.radius = number(required(st, "radius", p), jsonPath(p, "radius"), 1e-9, 1e6);
                    k.value = numberOr(st, "value", p, 1.0, 0.0, 1.0);
                    a.strokes.push_back(k);
                }
                break;
            }
            case AlphaType::Painted:
                checkKeys(j, path, {"type", "file"});
                a.file = file(j, path, "file", "painted alpha file");
                break;
            case AlphaType::Multiply:
            case AlphaType::Screen:
            case AlphaType::Max:
            case AlphaType::Min:
            case AlphaType::Invert: {
                checkKeys(j, path, {"type", "of"});
                const json& of = required(j, "of", path);
                const std::string p = jsonPath(path, "of");
                const size_t want = a.type == AlphaType::Invert ? 1 : 0;
                if (!of.is_array() || of.empty() || (want && of.size() != want))
                    fail(p, want ? "must be an array of one alpha signal"
                                 : "must be a non-empty array of alpha signals");
                for (size_t i = 0; i < of.size(); ++i)
                    a.of.push_back(readAlpha(of[i], fmt::format("{}[{}]", p, i)));
                break;
            }
        }
        return a;
    }

    ShaderSpec::Palette readPalette(const json& j, const std::string& path,
                                    ShaderSpec::Palette p) const
    {
        object(j, path,
               "must be a palette {\"deep\", \"shallow\", \"lowland\", \"mountain\", \"snow\"}");
        checkKeys(j, path, {"deep", "shallow", "lowland", "mountain", "snow"});
        auto c = [&](const char* key, glm::dvec3& out) {
            if (j.contains(key))
                out = colour(j[key], jsonPath(path, key));
        };
        c("deep", p.deep);
        c("shallow", p.shallow);
        c("lowland", p.lowland);
        c("mountain", p.mountain);
        c("snow", p.snow);
        return p;
    }

    ShaderSpec readShader(const json& j, const std::string& path) const
    {
        object(j, path, "must be a shader such as {\"type\": \"terrain\", \"sea_level\": 0}");
        const std::string type = string(required(j, "type", path), jsonPath(path, "type"));
        if (type != "terrain")
            fail(jsonPath(path, "type"), fmt::format("unknown shader '{}'; known: terrain", type));
        checkKeys(j, path, {"type", "sea_level", "snow_line", "relief", "depth", "a", "b"});
        ShaderSpec sh;
        sh.enabled = true;
        sh.seaLevel = numberOr(j, "sea_level", path, sh.seaLevel, -1e6, 1e6);
        sh.snowLine = numberOr(j, "snow_line", path, sh.snowLine, -1e6, 1e6);
        if (!(sh.snowLine > sh.seaLevel))
            fail(jsonPath(path, "snow_line"),
                 fmt::format("must be above the sea level ({} <= {})", sh.snowLine, sh.seaLevel));
        sh.relief = numberOr(j, "relief", path, sh.relief, -1e6, 1e6);
        sh.depth = numberOr(j, "depth", path, sh.depth, 1e-9, 1e6);
        if (j.contains("a"))
            sh.a = readPalette(j["a"], jsonPath(path, "a"), sh.a);
        sh.b = j.contains("b") ? readPalette(j["b"], jsonPath(path, "b"), sh.b) : sh.a;
        return sh;
    }

    ColorSpec readColor(const json& j, const std::string& path) const
    {
        ColorSpec c;
        if (j.is_array()) {
            c.color = colour(j, path);
            return c;
        }
        object(j, path,
               "must be [r, g, b], a ramp {\"scalar\": [lo, hi], \"low\": [r, g, b], "
               "\"high\": [r, g, b]} or a blend's two sides {\"a\": COLOR, \"b\": COLOR}");
        if (j.contains("a") || j.contains("b")) {
            checkKeys(j, path, {"a", "b"});
            c.sides.push_back(readColor(required(j, "a", path), jsonPath(path, "a")));
            c.sides.push_back(readColor(required(j, "b", path), jsonPath(path, "b")));
            return c;
        }
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
                     const std::string& directory, double time, int levels)
{
    return Reader(source, directory).read(text, time, levels);
}

ShapeSpec readShapeFile(const std::string& path, double time, int levels)
{
    const std::string text = readTextFile(path, "shape file");
    return parseShape(text, path, std::filesystem::path(path).parent_path().string(), time, levels);
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
