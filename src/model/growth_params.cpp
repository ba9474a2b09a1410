// cambium — growth parameter files.
#include "model/growth_params.h"

#include "core/error.h"
#include "core/files.h"
#include "core/json.h"
#include "core/math.h"

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sys/stat.h>
#include <map>

namespace cambium {

namespace {

using json = nlohmann::json;

/// The top-level keys of a parameter file (docs/growth-format.md).
const std::vector<std::string>& topLevelKeys()
{
    static const std::vector<std::string> keys = {"name",
                                                  "years",
                                                  "seed",
                                                  "trunk_length",
                                                  "min_shoot_length",
                                                  "max_branch_length",
                                                  "max_shoot_length",
                                                  "min_scale",
                                                  "phyllotaxis",
                                                  "longest_separation",
                                                  "orientation_noise",
                                                  "branching_angle",
                                                  "base_radius",
                                                  "tip_radius",
                                                  "thickening",
                                                  "growing_season",
                                                  "shoot_spread",
                                                  "bud_radius",
                                                  "scar_ring",
                                                  "scar_years",
                                                  "ridge_years",
                                                  "ridge_radius",
                                                  "leaf_fall",
                                                  "max_internodes",
                                                  "leaves",
                                                  "bark",
                                                  "leaf",
                                                  "curves"};
    return keys;
}

/// Reads a parameter file with the shared JSON checks; the lists of keys
/// and curves are too long to spell out in a message: the unknown ones
/// point to docs/growth-format.md.
class Reader : private JsonValidator {
    std::string directory_;  ///< relative files (the bark photo) are taken from here

public:
    explicit Reader(std::string source)
        : JsonValidator(source), directory_(std::filesystem::path(source).parent_path().string())
    {
    }

    GrowthParameters read(const std::string& text) const
    {
        const json root = parseJson(text, source());
        object(root, "(top level)", "must be an object");
        if (!root.contains("curves") || !root["curves"].is_object())
            fail("curves",
                 "missing: an object with the graphically defined functions (is this a growth "
                 "parameter file? docs/growth-format.md)");
        checkKeys(root, "", topLevelKeys(), "key", "docs/growth-format.md");
        GrowthParameters p;
        readScalars(root, p);
        readCurves(root["curves"], p);
        checkCurveRanges(p);
        return p;
    }

private:
    /// obj[key] in [lo, hi], or `value` when it is absent.
    double numberOr(const json& obj, const char* key, double value, double lo, double hi,
                    const std::string& path = "") const
    {
        if (!obj.contains(key))
            return value;
        return number(obj.at(key), jsonPath(path, key), lo, hi);
    }

    glm::dvec3 colour(const json& obj, const char* key, glm::dvec3 value,
                      const std::string& path = "") const
    {
        if (!obj.contains(key))
            return value;
        const std::string p = jsonPath(path, key);
        const json& v = array(obj.at(key), p, 3, "must be [r, g, b]");
        glm::dvec3 c;
        for (int k = 0; k < 3; ++k) {
            if (!v[size_t(k)].is_number() ||
                !(v[size_t(k)].get<double>() >= 0.0 && v[size_t(k)].get<double>() <= 1.0))
                fail(fmt::format("{}[{}]", p, k), "must be a number from 0 to 1");
            c[k] = v[size_t(k)].get<double>();
        }
        return c;
    }

    /// The species' scalars, the flags and the colours, in the file's documented order.
    void readScalars(const json& root, GrowthParameters& p) const
    {
        if (root.contains("name"))
            p.name = string(root["name"], "name");
        const double years = numberOr(root, "years", p.years, 1, 1000);
        if (years != std::floor(years))
            fail("years", fmt::format("must be a whole number (got {})", years));
        p.years = int(years);
        const double seed = numberOr(root, "seed", double(p.seed), 0, double(kMaxSeed));
        if (seed != std::floor(seed))
            fail("seed", fmt::format("must be a whole number (got {})", seed));
        p.seed = uint64_t(seed);
        p.trunkLength = numberOr(root, "trunk_length", p.trunkLength, 1e-6, 1e6);
        p.minShootLength = numberOr(root, "min_shoot_length", p.minShootLength, 0, 1e6);
        p.maxBranchLength = numberOr(root, "max_branch_length", p.maxBranchLength, 1e-6, 1e6);
        p.maxShootLength = numberOr(root, "max_shoot_length", p.maxShootLength, 1e-6, 1e6);
        p.minScale = numberOr(root, "min_scale", p.minScale, 0, 1e3);
        p.phyllotaxis = numberOr(root, "phyllotaxis", p.phyllotaxis, 0, 360);
        p.longestSeparation = numberOr(root, "longest_separation", p.longestSeparation, 0, 180);
        p.orientationNoise = numberOr(root, "orientation_noise", p.orientationNoise, 0, 90);
        p.branchingAngle = numberOr(root, "branching_angle", p.branchingAngle, 0, 180);
        p.baseRadius = numberOr(root, "base_radius", p.baseRadius, 1e-9, 1e6);
        p.tipRadius = numberOr(root, "tip_radius", p.tipRadius, 1e-9, 1e6);
        if (!(p.tipRadius <= p.baseRadius))
            fail("tip_radius",
                 fmt::format("must not exceed base_radius ({} > {})", p.tipRadius, p.baseRadius));
        p.thickening = numberOr(root, "thickening", p.thickening, 0, 2);
        p.growingSeason = numberOr(root, "growing_season", p.growingSeason, 0.05, 1);
        p.shootSpread = numberOr(root, "shoot_spread", p.shootSpread, 0, 0.99);
        p.budRadius = numberOr(root, "bud_radius", p.budRadius, 0, 1e6);
        p.scarRing = numberOr(root, "scar_ring", p.scarRing, 0, 2);
        p.scarYears = numberOr(root, "scar_years", p.scarYears, 0, 1000);
        p.ridgeYears = numberOr(root, "ridge_years", p.ridgeYears, 0, 1000);
        p.ridgeRadius = numberOr(root, "ridge_radius", p.ridgeRadius, 0.5, 100);
        p.leafFall = numberOr(root, "leaf_fall", p.leafFall, 0, 1);
        p.maxInternodes = numberOr(root, "max_internodes", p.maxInternodes, 1, 1e9);
        if (root.contains("leaves"))
            p.leaves = boolean(root["leaves"], "leaves");
        if (root.contains("bark") && root["bark"].is_object())
            readBark(root["bark"], p);
        else
            p.bark = colour(root, "bark", p.bark);
        p.leaf = colour(root, "leaf", p.leaf);
    }

    /// The bark section: its colour and its furrows (docs/bark.md).
    void readBark(const json& j, GrowthParameters& p) const
    {
        checkKeys(j, "bark",
                  {"color", "depth", "max_depth", "start_age", "full_age", "around", "along",
                   "seed", "photo", "colouring"});
        if (j.contains("photo"))
            p.barkPhoto = inputFile(j["photo"], "bark.photo", directory_, "bark photo");
        if (j.contains("colouring"))
            p.barkCoherent = choice(j["colouring"], "bark.colouring", kBarkColourings) == 0;
        p.bark = colour(j, "color", p.bark, "bark");
        BarkDetail& b = p.barkDetail;
        b.depth = numberOr(j, "depth", b.depth, 0.0, 0.28, "bark");
        b.maxDepth = numberOr(j, "max_depth", b.maxDepth, 0.0, 1e3, "bark");
        b.startAge = numberOr(j, "start_age", b.startAge, 0.0, 1e3, "bark");
        b.fullAge = numberOr(j, "full_age", b.fullAge, 0.0, 1e3, "bark");
        if (!(b.fullAge > b.startAge))
            fail("bark.full_age",
                 fmt::format("must exceed start_age ({} <= {})", b.fullAge, b.startAge));
        b.around = numberOr(j, "around", b.around, 1.0, 512.0, "bark");
        if (b.around != std::floor(b.around))
            fail("bark.around", fmt::format("must be a whole number (got {})", b.around));
        b.along = numberOr(j, "along", b.along, 0.0, 1e4, "bark");
        const double seed = numberOr(j, "seed", double(b.seed), 0.0, double(kMaxSeed), "bark");
        if (seed != std::floor(seed))
            fail("bark.seed", fmt::format("must be a whole number (got {})", seed));
        b.seed = uint64_t(seed);
    }

    /// The graphically defined functions: every one, and no other.
    void readCurves(const json& curves, GrowthParameters& p) const
    {
        std::vector<std::string> names;
        for (const GrowthCurve& c : growthCurves())
            names.push_back(c.key);
        checkKeys(curves, "curves", names, "curve", "docs/growth-format.md");
        for (const GrowthCurve& c : growthCurves()) {
            required(curves, c.key, "curves");
            try {
                p.*c.member = curveFromJson(curves.at(c.key), std::string("curves.") + c.key);
            } catch (const InputError& e) {
                throw InputError(fmt::format("{}: {}", source(), e.what()));
            }
        }
    }

    /// The ranges of curve values the model relies on.
    void checkCurveRanges(const GrowthParameters& p) const
    {
        for (const GrowthCurve& c : growthCurves())
            for (const auto& [x, y] : (p.*c.member).points())
                if (!(y >= c.lo && y <= c.hi))
                    fail(fmt::format("curves.{}", c.key),
                         fmt::format("values must be between {} and {} (a point has {})", c.lo,
                                     c.hi, y));
        // An organ starts from nothing and ends its year at its full size:
        // otherwise it would pop in, or the lengths at year ends would not be
        // eq. 7's.
        for (const auto& [c, key] :
             {std::pair{&p.internodeGrowth, "internode_growth"},
              std::pair{&p.leafGrowth, "leaf_growth"}, std::pair{&p.budGrowth, "bud_growth"}})
            if (c->points().front().second != 0.0 || c->points().back().second != 1.0)
                fail(fmt::format("curves.{}", key),
                     fmt::format("must start at 0 and end at 1 (fraction of full size; it goes "
                                 "from {} to {})",
                                 c->points().front().second, c->points().back().second));
    }
};

}  // namespace

GrowthParameters parseGrowthParameters(const std::string& text, const std::string& source)
{
    GrowthParameters p = Reader(source).read(text);
    p.source = source;
    return p;
}

GrowthParameters loadGrowthParameters(const std::string& path)
{
    return parseGrowthParameters(readTextFile(path, "growth parameter file"), path);
}

void checkGrowthYears(const std::vector<int>& years, const GrowthParameters& p,
                      const std::string& source)
{
    if (years.empty())
        throw InputError("--years: give at least one year");
    for (int y : years)
        if (y < 1 || y > p.years)
            throw InputError(fmt::format("--years: {} is not a year of the tree of {} (1 to {})", y,
                                         source, p.years));
}

double timeOfLife(const GrowthParameters& p, std::optional<double> t, const std::string& source,
                  const std::string& option)
{
    if (!t)
        return double(p.years);
    if (!(*t >= 0.0 && *t <= p.years))
        throw InputError(
            fmt::format("{}: {} must be between 0 and {} years, the tree's life (got {})", source,
                        option, p.years, *t));
    return *t;
}

const std::vector<GrowthCurve>& growthCurves()
{
    using P = GrowthParameters;
    static const std::vector<GrowthCurve> curves = {
        {"Gh", &P::Gh, 0, 1},
        {"Gs1", &P::Gs1, 0, 10},
        {"Gs2", &P::Gs2, 0, 10},
        {"Go1", &P::Go1, -180, 180},
        {"Go2", &P::Go2, -180, 180},
        {"Gbs", &P::Gbs, 0, 10},
        {"Ga", &P::Ga, 0, 1000},
        {"Gm", &P::Gm, 1, 1000},
        {"Gl", &P::Gl, 0, 1e3},
        {"Gss", &P::Gss, 0, 10},
        {"internode_growth", &P::internodeGrowth, 0, 1},
        {"leaf_growth", &P::leafGrowth, 0, 1},
        {"bud_growth", &P::budGrowth, 0, 1},
    };
    return curves;
}

std::string withCurvePoints(const std::string& text, const std::string& source,
                            const std::string& key,
                            const std::vector<std::pair<double, double>>& points)
{
    const auto known = std::find_if(growthCurves().begin(), growthCurves().end(),
                                    [&](const GrowthCurve& c) { return key == c.key; });
    if (known == growthCurves().end())
        throw InputError(fmt::format("curves.{}: no such curve{}", key, [&] {
            std::vector<std::string> names;
            for (const GrowthCurve& c : growthCurves())
                names.push_back(c.key);
            return didYouMean(key, names);
        }()));
    // The file as it is must read: an edit of a broken file would hide its
    // problem.
    const json root = parseJson(text, source);
    if (!root.is_object() || !root.contains("curves") || !root["curves"].is_object() ||
        !root["curves"].contains(key))
        throw InputError(fmt::format("{}: curves.{}: missing", source, key));
    // Only the points' text changes: the rest of the file, its comments and
    // layout stay as they were.  (A curve given as a number or an array of
    // points becomes an array of points: linear, as it was.)
    std::vector<std::string> path = {"curves", key};
    if (root["curves"][key].is_object())
        path.push_back("points");
    const auto span = jsonValueSpan(text, path);
    if (!span)
        throw InputError(fmt::format("{}: {}: missing", source, fmt::join(path, ".")));
    std::string array = "[";
    for (size_t i = 0; i < points.size(); ++i)
        array += fmt::format("{}[{}, {}]", i ? ", " : "", points[i].first, points[i].second);
    array += "]";
    std::string edited = text.substr(0, span->first) + array + text.substr(span->second);
    parseGrowthParameters(edited, source);  // the reader's own checks, every one
    return edited;
}

bool isGrowthParameterFile(const std::string& path)
{
    if (fileExtension(path) != "json")
        return false;
    struct stat st;
    if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode))
        return false;  // the model reader names what it is
    std::ifstream in(path);
    if (!in)
        return false;
    const json root = json::parse(in, nullptr, /*allow_exceptions=*/false);
    return root.is_object() && root.contains("curves");
}

}  // namespace cambium
