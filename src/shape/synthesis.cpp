// cambium — shape synthesis.
#include "shape/synthesis.h"

#include "core/error.h"
#include "core/system.h"
#include "shape/base_shapes.h"
#include "shape/capture.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cambium {

double estimateSynthesisBytes(size_t baseCorners, int levels)
{
    // Per vertex of a level: Q, P, detail (3 x 24 bytes), frame (72), two
    // scalars and their details (32), topology and OpenSubdiv's (about 150);
    // the levels together hold 4/3 of the finest, which has about as many
    // vertices as faces: a face of n corners makes n quads at level 1, each
    // 4^(levels - 1) at the finest.
    const double finest = double(baseCorners) * std::pow(4.0, std::max(levels - 1, 0));
    return finest * (4.0 / 3.0) * 330.0;
}

void checkSynthesisMemory(const ControlMesh& base, int levels, const std::string& what)
{
    const double bytes = estimateSynthesisBytes(base.faceVerts.size(), levels);
    const double available = availableMemoryBytes();
    if (bytes > available)
        throw InputError(fmt::format(
            "{}: {} levels of a base of {} faces need about {} of "
            "memory ({} available): use fewer levels",
            what, levels, base.faceCount(), formatBytes(bytes), formatBytes(available)));
}

BaseShape makeBase(const BaseSpec& b, const std::string& source, Device device)
{
    switch (b.type) {
        case BaseType::Cube:
            return cubeBase(b.size);
        case BaseType::Sphere:
            return sphereBase(b.radius, b.sphereCells);
        case BaseType::Torus:
            return torusBase(b.major, b.minor, b.around, b.tube);
        case BaseType::Plane:
            return planeBase(b.size, b.cells);
        case BaseType::Fuse:
            return fuseBase(b.length, b.radius, b.terms, b.around, b.rings);
        case BaseType::Mesh: {
            if (b.analyse)
                return captureBase(b, source, device);
            BaseShape s;
            s.mesh = readControlMesh(b.file);
            return s;
        }
        case BaseType::LevelSet:
        case BaseType::Model:
            return captureBase(b, source, device);
    }
    throw std::logic_error("makeBase: unknown base type");
}

ShapeSurface::ShapeSurface(const ShapeSpec& spec, int levels, Device device)
    : ShapeSurface(spec, levels, makeBase(spec.base, spec.source, device))
{
}

void checkShapeLevels(const ShapeSpec& spec, int levels)
{
    auto check = [&](const std::string& path, const std::vector<int>& used) {
        for (int l : used)
            if (l > levels)
                throw InputError(
                    fmt::format("{}: {}.levels: level {} is finer than the {} levels "
                                "synthesised",
                                spec.source, path, l, levels));
    };
    for (const DetailSpec& d : spec.details)
        check(d.path, d.levels);
    for (const EditSpec& e : spec.edits)
        check(e.path, e.levels);
}

void checkShapeDetails(const ShapeSpec& spec, const ControlMesh& base)
{
    const double e0 = meanEdgeLength(base);
    for (const DetailSpec& d : spec.details) {
        if (d.type != DetailType::Rock || d.amplitude == 0.0 || !rockFoldsOnAPlane(d, e0))
            continue;
        // The largest amplitude that does not fold, to a few percent.
        double lo = 0.0, hi = d.amplitude;
        DetailSpec probe = d;
        for (int step = 0; step < 6; ++step) {
            probe.amplitude = 0.5 * (lo + hi);
            (rockFoldsOnAPlane(probe, e0) ? hi : lo) = probe.amplitude;
        }
        throw InputError(fmt::format(
            "{}: {}.amplitude: {} folds the surface onto itself on a plane of this base's edge "
            "length ({:.3g}): self-intersecting; use an amplitude of at most about {:.3g}",
            spec.source, d.path, d.amplitude, e0, lo));
    }
}

ShapeSurface::ShapeSurface(const ShapeSpec& spec, int levels, const BaseShape& base) : spec_(spec)
{
    if (levels >= 0)
        spec_.levels = levels;
    checkShapeLevels(spec_, spec_.levels);
    checkShapeDetails(spec_, base.mesh);
    surface_ = std::make_unique<MultiresSurface>(base.mesh, spec_.levels, spec_.source + ": base");
    baseDetail_.resize(size_t(spec_.levels) + 1);
    if (base.target) {
        surface_->analyse(base.target);
        for (int l = 1; l <= spec_.levels; ++l)
            baseDetail_[size_t(l)] = surface_->level(l).detail;
    }
    for (const DetailSpec& d : spec_.details)
        details_.push_back(makeDetail(d));
    adjacency_.resize(size_t(spec_.levels) + 1);
}

ShapeSurface::~ShapeSurface() = default;

const Adjacency& ShapeSurface::adjacency(int l)
{
    auto& a = adjacency_[size_t(l)];
    if (!a)
        a = std::make_unique<Adjacency>(surface_->level(l));
    return *a;
}

void ShapeSurface::hook(int l, SubdivLevel& level)
{
    const std::vector<glm::dvec3>& base = baseDetail_[size_t(l)];
    if (base.empty())
        std::fill(level.detail.begin(), level.detail.end(), glm::dvec3(0.0));
    else
        level.detail = base;
    std::fill(level.scalarDetail.begin(), level.scalarDetail.end(), 0.0);
    if (l == 0)
        return;
    for (auto& d : details_)
        d->apply(l, level, adjacency(l));
    for (const EditSpec& e : spec_.edits)
        applyEdit(e, l, level, adjacency(l));
}

void ShapeSurface::synthesize()
{
    synthesizeFrom(0);
}

void ShapeSurface::synthesizeFrom(int l)
{
    surface_->synthesizeFrom(l, [this](int lv, SubdivLevel& level) { hook(lv, level); });
}

glm::dvec3 ShapeSurface::color(double s) const
{
    const ColorSpec& c = spec_.color;
    if (!c.ramp)
        return c.color;
    const double t = std::clamp((s - c.low) / (c.high - c.low), 0.0, 1.0);
    return c.lowColor + (c.highColor - c.lowColor) * t;
}

TriangleMesh ShapeSurface::mesh() const
{
    const SubdivLevel& f = surface_->finest();
    TriangleMesh m = levelMesh(f);
    m.colors.resize(f.vertexCount());
    for (size_t v = 0; v < f.vertexCount(); ++v) {
        const glm::dvec3 c = color(f.scalar[v]);
        m.colors[v] = openvdb::Vec3s(float(c.x), float(c.y), float(c.z));
    }
    return m;
}

}  // namespace cambium
