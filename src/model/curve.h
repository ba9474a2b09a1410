// cambium — graphically defined functions G on [0, 1] (paper 000 section 4):
// editable curves given by control points, interpolated piecewise linearly or
// smoothly, as the growth model's positional information.
#pragma once

#include <nlohmann/json_fwd.hpp>

#include <string>
#include <utility>
#include <vector>

namespace cambium {

class Curve {
public:
    enum class Interpolation { Linear, Smooth };

    Curve() = default;
    /// Control points (x, y), x strictly increasing from 0 to 1, y finite.
    /// InputError (naming `where`) otherwise.
    Curve(std::vector<std::pair<double, double>> points, Interpolation interpolation,
          const std::string& where);

    /// A constant function.
    static Curve constant(double y);

    /// G(x), x clamped to [0, 1].  Linear: the polyline through the points.
    /// Smooth: monotone cubic Hermite (Fritsch-Carlson): C1, through every
    /// point, and never beyond the values of the points it lies between (no
    /// overshoot, so a curve drawn between 0 and 1 stays there).
    double operator()(double x) const;

    const std::vector<std::pair<double, double>>& points() const { return points_; }
    Interpolation interpolation() const { return interpolation_; }

private:
    std::vector<std::pair<double, double>> points_{{0.0, 0.0}, {1.0, 0.0}};
    std::vector<double> slopes_;  ///< Hermite tangents at the points (smooth)
    Interpolation interpolation_ = Interpolation::Linear;
};

/// Reads a curve from JSON: a number (a constant), an array of [x, y] pairs
/// (linear), or {"points": [[x, y], ...], "interpolation": "linear"|"smooth"}.
/// InputError naming `path` (a JSON path such as "curves.Gh") otherwise.
Curve curveFromJson(const nlohmann::json& j, const std::string& path);

}  // namespace cambium
