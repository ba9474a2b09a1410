// cambium — multi-scale blending of two shapes' details (paper 004, section
// 6, after Burt's multiresolution spline): alpha signals, the transition of
// each level, the linear combination of detail coefficients, and the
// post-blend shader (section 6.3).
#pragma once

#include "shape/details.h"
#include "shape/shape.h"
#include "subdiv/multires.h"

#include <glm/glm.hpp>

#include <memory>
#include <vector>

namespace cambium {

/// The weight of a signed value s across a transition of width w: 0 for
/// s <= -w/2, 1 for s >= w/2, 3u^2 - 2u^3 (u = s/w + 1/2) between; a hard
/// switch for w = 0 (1/2 on the dividing surface itself).
double transitionWeight(double s, double width);

/// The transition width of level l (>= 1): c / 2^(l-1), or c at every level.
double transitionWidth(const BlendSpec& blend, int level);

/// b + alpha (a - b), exact at the ends: a for alpha 1, b for alpha 0, and a
/// when a == b.
inline double blendValue(double a, double b, double alpha)
{
    return alpha == 1.0 ? a : alpha == 0.0 ? b : b + alpha * (a - b);
}
inline glm::dvec3 blendValue(const glm::dvec3& a, const glm::dvec3& b, double alpha)
{
    return alpha == 1.0 ? a : alpha == 0.0 ? b : b + alpha * (a - b);
}

/// An alpha signal ready to evaluate (a painted file read once).
class AlphaSignal {
public:
    /// InputError naming the file and JSON path for a painted file that
    /// cannot be read or has no vertex alpha.
    AlphaSignal(const AlphaSpec& spec, const std::string& source);
    ~AlphaSignal();
    /// The weight of A at each point, for a level whose transition is `width`.
    std::vector<double> evaluate(const std::vector<glm::dvec3>& points, double width) const;
    /// The same at one point.
    double at(const glm::dvec3& p, double width) const;

private:
    AlphaSpec spec_;
    std::vector<std::unique_ptr<AlphaSignal>> of_;
    struct Painted;
    std::unique_ptr<Painted> painted_;
};

/// The shader's height (along the normal) and colour of a point whose blended
/// scalar is s and blend parameter beta.
struct Shade {
    double height = 0.0;
    glm::dvec3 color{0.0};
};
Shade shade(const ShaderSpec& shader, double s, double beta);

}  // namespace cambium
