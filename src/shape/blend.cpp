// cambium — multi-scale blending and the post-blend shader.
#include "shape/blend.h"

#include "core/error.h"
#include "core/parallel.h"
#include "io/mesh_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cambium {

double transitionWeight(double s, double width)
{
    if (width <= 0.0)
        return s > 0.0 ? 1.0 : s < 0.0 ? 0.0 : 0.5;
    const double u = s / width + 0.5;
    if (u <= 0.0)
        return 0.0;
    if (u >= 1.0)
        return 1.0;
    return u * u * (3.0 - 2.0 * u);
}

double transitionWidth(const BlendSpec& blend, int level)
{
    return blend.constantWidth ? blend.width : std::ldexp(blend.width, 1 - std::max(level, 1));
}

struct AlphaSignal::Painted {
    std::vector<float> alpha;
    PointGrid grid{1.0};
    explicit Painted(double cell) : grid(cell) {}
};

AlphaSignal::AlphaSignal(const AlphaSpec& spec, const std::string& source) : spec_(spec)
{
    for (const AlphaSpec& o : spec.of)
        of_.push_back(std::make_unique<AlphaSignal>(o, source));
    if (spec.type != AlphaType::Painted)
        return;
    TriangleMesh m;
    try {
        m = readMesh(spec.file);
    } catch (const InputError& e) {
        throw InputError(fmt::format("{}: {}.file: {}", source, spec.path, e.what()));
    }
    if (m.alpha.size() != m.points.size() || m.points.empty())
        throw InputError(fmt::format(
            "{}: {}.file: {} has no vertex alpha (a PLY with a vertex property 'alpha', "
            "as painters write with a colour's alpha)",
            source, spec.path, spec.file));
    // Cells of about the mean spacing of the painted points.
    glm::dvec3 lo(m.points[0][0], m.points[0][1], m.points[0][2]), hi = lo;
    for (const auto& p : m.points)
        for (int k = 0; k < 3; ++k)
            lo[k] = std::min(lo[k], double(p[k])), hi[k] = std::max(hi[k], double(p[k]));
    const glm::dvec3 e = hi - lo;
    const double area = 2.0 * (e.x * e.y + e.y * e.z + e.z * e.x);
    const double cell = std::max(std::sqrt(area / double(m.points.size())) * 2.0,
                                 1e-9 * std::max({e.x, e.y, e.z, 1.0}));
    painted_ = std::make_unique<Painted>(cell);
    painted_->alpha.resize(m.alpha.size());
    for (size_t i = 0; i < m.points.size(); ++i) {
        const float a = m.alpha[i];
        if (!(a >= 0.0f && a <= 1.0f))
            throw InputError(fmt::format("{}: {}.file: {}: vertex {} has alpha {} (not in [0, 1])",
                                         source, spec.path, spec.file, i, a));
        painted_->alpha[i] = a;
        painted_->grid.insert(int(i), glm::dvec3(m.points[i][0], m.points[i][1], m.points[i][2]));
    }
}

AlphaSignal::~AlphaSignal() = default;

double AlphaSignal::at(const glm::dvec3& p, double width) const
{
    switch (spec_.type) {
        case AlphaType::Constant:
            return spec_.value;
        case AlphaType::Plane:
            return transitionWeight(glm::dot(p - spec_.point, spec_.normal), width);
        case AlphaType::Sphere:
            return transitionWeight(spec_.radius - glm::length(p - spec_.point), width);
        case AlphaType::Noise: {
            const double n = rockValue(p, 0, 1.0, spec_.frequency, spec_.seed);
            return transitionWeight((n - spec_.threshold) / spec_.frequency, width);
        }
        case AlphaType::Strokes: {
            double a = spec_.background;
            for (const Stroke& s : spec_.strokes)
                a += (s.value - a) * editDropOff(glm::length(p - s.at) / s.radius);
            return a;
        }
        case AlphaType::Painted:
            return double(painted_->alpha[size_t(painted_->grid.nearest(p))]);
        case AlphaType::Multiply: {
            double a = 1.0;
            for (const auto& o : of_)
                a *= o->at(p, width);
            return a;
        }
        case AlphaType::Screen: {
            double a = 1.0;
            for (const auto& o : of_)
                a *= 1.0 - o->at(p, width);
            return 1.0 - a;
        }
        case AlphaType::Max: {
            double a = 0.0;
            for (const auto& o : of_)
                a = std::max(a, o->at(p, width));
            return a;
        }
        case AlphaType::Min: {
            double a = 1.0;
            for (const auto& o : of_)
                a = std::min(a, o->at(p, width));
            return a;
        }
        case AlphaType::Invert:
            return 1.0 - of_.front()->at(p, width);
    }
    return 0.0;
}

std::vector<double> AlphaSignal::evaluate(const std::vector<glm::dvec3>& points, double width) const
{
    std::vector<double> out(points.size());
    forEachIndex(points.size(),
                 [&](size_t v) { out[v] = std::clamp(at(points[v], width), 0.0, 1.0); });
    return out;
}

Shade shade(const ShaderSpec& sh, double s, double beta)
{
    auto palette = [&](const ShaderSpec::Palette& p) {
        if (s < sh.seaLevel) {
            const double t = std::clamp(1.0 + (s - sh.seaLevel) / sh.depth, 0.0, 1.0);
            return p.deep + (p.shallow - p.deep) * t;
        }
        if (s >= sh.snowLine)
            return p.snow;
        const double t = (s - sh.seaLevel) / (sh.snowLine - sh.seaLevel);
        return p.lowland + (p.mountain - p.lowland) * t;
    };
    Shade out;
    out.height = sh.relief * std::max(s, sh.seaLevel);
    out.color = blendValue(palette(sh.a), palette(sh.b), std::clamp(beta, 0.0, 1.0));
    return out;
}

}  // namespace cambium
