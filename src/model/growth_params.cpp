// cambium — growth parameter files.
#include "model/growth_params.h"

#include "core/error.h"
#include "core/json.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sys/stat.h>
#include <map>

namespace cambium {

namespace {

using json = nlohmann::json;

class Reader {
public:
    explicit Reader(std::string source) : source_(std::move(source)) {}

    [[noreturn]] void fail(const std::string& path, const std::string& what) const
    {
        throw InputError(fmt::format("{}: {}: {}", source_, path, what));
    }

    double number(const json& obj, const char* key, double value, double lo, double hi)
    {
        if (!obj.contains(key))
            return value;
        const json& v = obj.at(key);
        if (!v.is_number())
            fail(key, "must be a number");
        const double x = v.get<double>();
        if (!(x >= lo && x <= hi))
            fail(key, fmt::format("must be between {} and {} (got {})", lo, hi, x));
        return x;
    }

    glm::dvec3 colour(const json& obj, const char* key, glm::dvec3 value)
    {
        if (!obj.contains(key))
            return value;
        const json& v = obj.at(key);
        if (!v.is_array() || v.size() != 3)
            fail(key, "must be [r, g, b]");
        glm::dvec3 c;
        for (int k = 0; k < 3; ++k) {
            if (!v[size_t(k)].is_number() || !(v[size_t(k)].get<double>() >= 0.0 && v[size_t(k)].get<double>() <= 1.0))
                fail(fmt::format("{}[{}]", key, k), "must be a number from 0 to 1");
            c[k] = v[size_t(k)].get<double>();
        }
        return c;
    }

    GrowthParameters read(const std::string& text)
    {
        const json root = parseJson(text, source_);
        if (!root.is_object())
            throw InputError(fmt::format("{}: expected a JSON object", source_));
        static const char* keys[] = {"name",
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
        if (!root.contains("curves") || !root["curves"].is_object())
            fail("curves", "missing: an object with the graphically defined functions (is this a growth "
                           "parameter file? docs/growth-format.md)");
        for (const auto& [key, value] : root.items())
            if (std::find(std::begin(keys), std::end(keys), key) == std::end(keys))
                fail(key, "unknown key (docs/growth-format.md lists them)");
        GrowthParameters p;
        if (root.contains("name")) {
            if (!root["name"].is_string())
                fail("name", "must be a string");
            p.name = root["name"].get<std::string>();
        }
        const double years = number(root, "years", p.years, 1, 1000);
        if (years != std::floor(years))
            fail("years", fmt::format("must be a whole number (got {})", years));
        p.years = int(years);
        p.seed = uint64_t(number(root, "seed", double(p.seed), 0, 9e15));
        p.trunkLength = number(root, "trunk_length", p.trunkLength, 1e-6, 1e6);
        p.minShootLength = number(root, "min_shoot_length", p.minShootLength, 0, 1e6);
        p.maxBranchLength = number(root, "max_branch_length", p.maxBranchLength, 1e-6, 1e6);
        p.maxShootLength = number(root, "max_shoot_length", p.maxShootLength, 1e-6, 1e6);
        p.minScale = number(root, "min_scale", p.minScale, 0, 1e3);
        p.phyllotaxis = number(root, "phyllotaxis", p.phyllotaxis, 0, 360);
        p.longestSeparation = number(root, "longest_separation", p.longestSeparation, 0, 180);
        p.orientationNoise = number(root, "orientation_noise", p.orientationNoise, 0, 90);
        p.branchingAngle = number(root, "branching_angle", p.branchingAngle, 0, 180);
        p.baseRadius = number(root, "base_radius", p.baseRadius, 1e-9, 1e6);
        p.tipRadius = number(root, "tip_radius", p.tipRadius, 1e-9, 1e6);
        if (!(p.tipRadius <= p.baseRadius))
            fail("tip_radius", fmt::format("must not exceed base_radius ({} > {})", p.tipRadius, p.baseRadius));
        p.thickening = number(root, "thickening", p.thickening, 0, 2);
        p.growingSeason = number(root, "growing_season", p.growingSeason, 0.05, 1);
        p.shootSpread = number(root, "shoot_spread", p.shootSpread, 0, 0.99);
        p.budRadius = number(root, "bud_radius", p.budRadius, 0, 1e6);
        p.scarRing = number(root, "scar_ring", p.scarRing, 0, 2);
        p.scarYears = number(root, "scar_years", p.scarYears, 0, 1000);
        p.ridgeYears = number(root, "ridge_years", p.ridgeYears, 0, 1000);
        p.ridgeRadius = number(root, "ridge_radius", p.ridgeRadius, 0.5, 100);
        p.leafFall = number(root, "leaf_fall", p.leafFall, 0, 1);
        p.maxInternodes = number(root, "max_internodes", p.maxInternodes, 1, 1e9);
        if (root.contains("leaves")) {
            if (!root["leaves"].is_boolean())
                fail("leaves", "must be true or false");
            p.leaves = root["leaves"].get<bool>();
        }
        p.bark = colour(root, "bark", p.bark);
        p.leaf = colour(root, "leaf", p.leaf);

        const json& curves = root["curves"];
        const std::map<std::string, Curve*> named = {
            {"Gh", &p.Gh},   {"Gs1", &p.Gs1}, {"Gs2", &p.Gs2}, {"Go1", &p.Go1},
            {"Go2", &p.Go2}, {"Gbs", &p.Gbs}, {"Ga", &p.Ga},   {"Gm", &p.Gm},
            {"Gl", &p.Gl},   {"Gss", &p.Gss}, {"internode_growth", &p.internodeGrowth},
            {"leaf_growth", &p.leafGrowth},   {"bud_growth", &p.budGrowth}};
        for (const auto& [key, value] : curves.items())
            if (!named.count(key))
                fail("curves." + key, "unknown curve (docs/growth-format.md lists them)");
        for (const auto& [key, curve] : named) {
            if (!curves.contains(key))
                fail("curves." + key, "missing");
            try {
                *curve = curveFromJson(curves.at(key), "curves." + key);
            } catch (const InputError& e) {
                throw InputError(fmt::format("{}: {}", source_, e.what()));
            }
        }
        // Ranges the model relies on.
        auto within = [&](const Curve& c, const char* key, double lo, double hi) {
            for (const auto& [x, y] : c.points())
                if (!(y >= lo && y <= hi))
                    fail(fmt::format("curves.{}", key),
                         fmt::format("values must be between {} and {} (a point has {})", lo, hi, y));
        };
        within(p.Gh, "Gh", 0, 1);
        within(p.Gs1, "Gs1", 0, 10);
        within(p.Gs2, "Gs2", 0, 10);
        within(p.Go1, "Go1", -180, 180);
        within(p.Go2, "Go2", -180, 180);
        within(p.Gbs, "Gbs", 0, 10);
        within(p.Ga, "Ga", 0, 1000);
        within(p.Gm, "Gm", 1, 1000);
        within(p.Gl, "Gl", 0, 1e3);
        within(p.Gss, "Gss", 0, 10);
        within(p.internodeGrowth, "internode_growth", 0, 1);
        within(p.leafGrowth, "leaf_growth", 0, 1);
        within(p.budGrowth, "bud_growth", 0, 1);
        // An organ starts from nothing and ends its year at its full size:
        // otherwise it would pop in, or the lengths at year ends would not be
        // eq. 7's.
        for (const auto& [c, key] : {std::pair{&p.internodeGrowth, "internode_growth"},
                                     std::pair{&p.leafGrowth, "leaf_growth"}, std::pair{&p.budGrowth, "bud_growth"}})
            if (c->points().front().second != 0.0 || c->points().back().second != 1.0)
                fail(fmt::format("curves.{}", key),
                     fmt::format("must start at 0 and end at 1 (fraction of full size; it goes from {} to {})",
                                 c->points().front().second, c->points().back().second));
        return p;
    }

private:
    std::string source_;
};

}  // namespace

GrowthParameters parseGrowthParameters(const std::string& text, const std::string& source)
{
    return Reader(source).read(text);
}

GrowthParameters loadGrowthParameters(const std::string& path)
{
    return parseGrowthParameters(readTextFile(path, "growth parameter file"), path);
}

double timeOfLife(const GrowthParameters& p, std::optional<double> t, const std::string& source,
                  const std::string& option)
{
    if (!t)
        return double(p.years);
    if (!(*t >= 0.0 && *t <= p.years))
        throw InputError(fmt::format("{}: {} must be between 0 and {} years, the tree's life (got {})", source, option,
                                     p.years, *t));
    return *t;
}

bool isGrowthParameterFile(const std::string& path)
{
    if (path.size() < 5 || path.compare(path.size() - 5, 5, ".json") != 0)
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
