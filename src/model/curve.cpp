// cambium — graphically defined functions.
#include "model/curve.h"

#include "core/error.h"
#include "core/json.h"

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>

namespace cambium {

Curve::Curve(std::vector<std::pair<double, double>> points, Interpolation interpolation,
             const std::string& where)
    : points_(std::move(points)), interpolation_(interpolation)
{
    if (points_.size() < 2)
        throw InputError(
            fmt::format("{}: a curve needs at least two points (got {})", where, points_.size()));
    for (size_t i = 0; i < points_.size(); ++i) {
        const auto [x, y] = points_[i];
        if (!std::isfinite(x) || !std::isfinite(y))
            throw InputError(fmt::format("{}: point {} is not finite ({}, {})", where, i, x, y));
        if (i > 0 && !(x > points_[i - 1].first))
            throw InputError(
                fmt::format("{}: the x of point {} ({}) must exceed the previous one ({})", where,
                            i, x, points_[i - 1].first));
    }
    if (points_.front().first != 0.0 || points_.back().first != 1.0)
        throw InputError(fmt::format("{}: the points must span x from 0 to 1 (they span {} to {})",
                                     where, points_.front().first, points_.back().first));
    if (interpolation_ == Interpolation::Smooth) {
        // Fritsch-Carlson: secants, averaged tangents, then limited so that
        // every piece stays monotone between its end values.
        const size_t n = points_.size();
        std::vector<double> secant(n - 1);
        for (size_t i = 0; i + 1 < n; ++i)
            secant[i] = (points_[i + 1].second - points_[i].second) /
                        (points_[i + 1].first - points_[i].first);
        slopes_.assign(n, 0.0);
        slopes_[0] = secant[0];
        slopes_[n - 1] = secant[n - 2];
        for (size_t i = 1; i + 1 < n; ++i)
            slopes_[i] = secant[i - 1] * secant[i] <= 0.0 ? 0.0 : 0.5 * (secant[i - 1] + secant[i]);
        for (size_t i = 0; i + 1 < n; ++i) {
            if (secant[i] == 0.0) {
                slopes_[i] = slopes_[i + 1] = 0.0;
                continue;
            }
            const double a = slopes_[i] / secant[i], b = slopes_[i + 1] / secant[i];
            const double r = a * a + b * b;
            if (r > 9.0) {
                const double t = 3.0 / std::sqrt(r);
                slopes_[i] = t * a * secant[i];
                slopes_[i + 1] = t * b * secant[i];
            }
        }
    }
}

Curve Curve::constant(double y)
{
    Curve c;
    c.points_ = {{0.0, y}, {1.0, y}};
    return c;
}

double Curve::operator()(double x) const
{
    x = std::clamp(x, 0.0, 1.0);
    const auto it =
        std::upper_bound(points_.begin(), points_.end(), x,
                         [](double v, const std::pair<double, double>& p) { return v < p.first; });
    const size_t i = std::min<size_t>(size_t(std::max<ptrdiff_t>(it - points_.begin(), 1)) - 1,
                                      points_.size() - 2);
    const auto [x0, y0] = points_[i];
    const auto [x1, y1] = points_[i + 1];
    const double h = x1 - x0, t = (x - x0) / h;
    if (interpolation_ == Interpolation::Linear)
        return y0 + t * (y1 - y0);
    const double t2 = t * t, t3 = t2 * t;
    return (2 * t3 - 3 * t2 + 1) * y0 + (t3 - 2 * t2 + t) * h * slopes_[i] +
           (-2 * t3 + 3 * t2) * y1 + (t3 - t2) * h * slopes_[i + 1];
}

Curve curveFromJson(const nlohmann::json& j, const std::string& path)
{
    if (j.is_number())
        return Curve::constant(j.get<double>());
    const nlohmann::json* points = &j;
    std::string pointsPath = path;
    Curve::Interpolation interpolation = Curve::Interpolation::Linear;
    if (j.is_object()) {
        for (const auto& [key, value] : j.items())
            if (key != "points" && key != "interpolation")
                throw InputError(
                    fmt::format("{}: unknown key{} (a curve has points and interpolation)",
                                jsonPath(path, key), didYouMean(key, {"points", "interpolation"})));
        if (!j.contains("points"))
            throw InputError(fmt::format("{}.points: missing", path));
        points = &j.at("points");
        pointsPath = path + ".points";
        if (j.contains("interpolation")) {
            const auto& v = j.at("interpolation");
            if (!v.is_string() || (v != "linear" && v != "smooth"))
                throw InputError(
                    fmt::format("{}.interpolation: must be \"linear\" or \"smooth\"", path));
            interpolation =
                v == "smooth" ? Curve::Interpolation::Smooth : Curve::Interpolation::Linear;
        }
    }
    if (!points->is_array())
        throw InputError(fmt::format(
            "{}: expected a number, an array of [x, y] points or an object with points", path));
    std::vector<std::pair<double, double>> pts;
    for (size_t i = 0; i < points->size(); ++i) {
        const auto& p = (*points)[i];
        if (!p.is_array() || p.size() != 2 || !p[0].is_number() || !p[1].is_number())
            throw InputError(fmt::format("{}[{}]: expected [x, y]", pointsPath, i));
        pts.emplace_back(p[0].get<double>(), p[1].get<double>());
    }
    return Curve(std::move(pts), interpolation, pointsPath);
}

}  // namespace cambium
