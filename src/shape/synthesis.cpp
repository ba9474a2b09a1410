// cambium — shape synthesis.
#include "shape/synthesis.h"

#include "core/error.h"
#include "core/parallel.h"
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
    // 4^(levels - 1) at the finest.  Then the mesh made of the finest level
    // and its file's bytes: measured, the rock sphere at level 10 (6.3
    // million finest vertices) peaked at 4.74 GB, 570 bytes a vertex of the
    // 4/3 (330 had been counted, and a shape under `ulimit -v` ran out).
    const double finest = double(baseCorners) * std::pow(4.0, std::max(levels - 1, 0));
    return finest * (4.0 / 3.0) * 570.0;
}

void checkSynthesisMemory(const ControlMesh& base, int levels, const std::string& what)
{
    checkMemoryFits(
        estimateSynthesisBytes(base.faceVerts.size(), levels),
        fmt::format("{}: {} levels of a base of {} faces", what, levels, base.faceCount()),
        "use fewer levels");
}

BaseShape makeBase(const BaseSpec& b, const std::string& source, Device device,
                   const std::function<void(const char*, double)>& progress)
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
                return captureBase(b, source, device, progress);
            BaseShape s;
            s.mesh = readControlMesh(b.file);
            // Checked here to name the file (MultiresSurface knows the shape).
            checkControlMesh(s.mesh, fmt::format("{}: base {}", source, b.file));
            return s;
        }
        case BaseType::LevelSet:
        case BaseType::Model:
            return captureBase(b, source, device, progress);
    }
    throw std::logic_error("makeBase: unknown base type");
}

ShapeSurface::ShapeSurface(const ShapeSpec& spec, int levels, Device device)
    : ShapeSurface(spec, levels, makeBase(spec.base, spec.source, device))
{
}

std::vector<DetailSpec> allDetails(const ShapeSpec& spec)
{
    std::vector<DetailSpec> out = spec.details;
    out.insert(out.end(), spec.blend.a.details.begin(), spec.blend.a.details.end());
    out.insert(out.end(), spec.blend.b.details.begin(), spec.blend.b.details.end());
    return out;
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
    for (const DetailSpec& d : allDetails(spec))
        check(d.path, d.levels);
    for (const BlendSide* side : {&spec.blend.a, &spec.blend.b})
        for (const EditSpec& e : side->edits)
            check(e.path, e.levels);
    for (const EditSpec& e : spec.edits)
        check(e.path, e.levels);
}

void checkShapeDetails(const ShapeSpec& spec, const ControlMesh& base)
{
    const double e0 = meanEdgeLength(base);
    for (const DetailSpec& d : allDetails(spec)) {
        if (d.type != DetailType::Rock || d.amplitude == 0.0 || !rockFoldsOnAPlane(d, e0))
            continue;
        // The largest amplitude that does not fold, to a few percent: halved
        // until it does not (an amplitude of 1000 was bisected from 0 and
        // told "at most about 0"), then bisected.
        double hi = d.amplitude;
        DetailSpec probe = d;
        for (int k = 0; k < 64; ++k) {
            probe.amplitude = 0.5 * hi;
            if (!rockFoldsOnAPlane(probe, e0))
                break;
            hi = probe.amplitude;
        }
        double lo = 0.5 * hi;
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
    base_ = base.mesh;
    surface_ = std::make_unique<MultiresSurface>(base.mesh, spec_.levels, spec_.source + ": base");
    baseDetail_.resize(size_t(spec_.levels) + 1);
    if (base.target) {
        surface_->analyse(base.target);
        for (int l = 1; l <= spec_.levels; ++l)
            baseDetail_[size_t(l)] = surface_->level(l).detail;
    }
    adjacency_.resize(size_t(spec_.levels) + 1);
    makeDetails();
}

void ShapeSurface::makeDetails()
{
    details_.clear();
    for (const DetailSpec& d : spec_.details)
        details_.push_back(makeDetail(d));
    alpha_.assign(size_t(spec_.levels) + 1, {});
    alphaSignal_.reset();
    for (auto& side : sideDetails_)
        side.clear();
    influence_.clear();
    if (spec_.blend.enabled) {
        for (int side = 0; side < 2; ++side)
            for (const DetailSpec& d : (side ? spec_.blend.b : spec_.blend.a).details)
                sideDetails_[side].push_back(makeDetail(d));
        alphaSignal_ = std::make_unique<AlphaSignal>(spec_.blend.alpha, spec_.source);
        influence_.resize(size_t(spec_.levels) + 1);
    }
}

void ShapeSurface::setSpec(const ShapeSpec& spec, bool checked)
{
    const int levels = spec_.levels;
    spec_ = spec;
    spec_.levels = levels;
    if (!checked) {
        checkShapeLevels(spec_, levels);
        checkShapeDetails(spec_, base_);
    }
    makeDetails();
}

ShapeSurface::~ShapeSurface() = default;

const Adjacency& ShapeSurface::adjacency(int l)
{
    auto& a = adjacency_[size_t(l)];
    if (!a)
        a = std::make_unique<Adjacency>(surface_->level(l));
    return *a;
}

void ShapeSurface::resetDetails(int l, SubdivLevel& level, bool base) const
{
    const std::vector<glm::dvec3>& given = baseDetail_[size_t(l)];
    if (given.empty() || !base)
        std::fill(level.detail.begin(), level.detail.end(), glm::dvec3(0.0));
    else
        level.detail = given;
    std::fill(level.scalarDetail.begin(), level.scalarDetail.end(), 0.0);
}

void ShapeSurface::addDetails(int l, SubdivLevel& level,
                              const std::vector<std::unique_ptr<Detail>>& details,
                              const std::vector<EditSpec>& edits, const VertexMask* mask)
{
    if (l == 0)
        return;
    for (auto& d : details)
        d->apply(l, level, adjacency(l), mask);
    for (const EditSpec& e : edits)
        applyEdit(e, l, level, adjacency(l));
}

void ShapeSurface::hook(int l, SubdivLevel& level)
{
    const BlendSpec& blend = spec_.blend;
    if (!blend.enabled) {
        resetDetails(l, level, true);
        addDetails(l, level, details_, spec_.edits, nullptr);
        return;
    }
    // Each side's details on the blended surface's level where its alpha is
    // not 0, then their linear combination by the level's alpha (the coarser
    // levels already blended), then the details both share.
    const size_t n = level.vertexCount();
    std::vector<double>& alpha = alpha_[size_t(l)];
    alpha = alphaSignal_->evaluate(level.subdivided, transitionWidth(blend, l));
    VertexMask wantA(n), wantB(n);
    forEachIndex(n, [&](size_t v) {
        wantA[v] = alpha[v] > 0.0;
        wantB[v] = alpha[v] < 1.0;
    });
    std::vector<glm::dvec3> detailA(n);
    std::vector<double> scalarA(n);
    resetDetails(l, level, blend.a.baseDetail);
    addDetails(l, level, sideDetails_[0], blend.a.edits, &wantA);
    std::swap(level.detail, detailA);
    std::swap(level.scalarDetail, scalarA);
    resetDetails(l, level, blend.b.baseDetail);
    addDetails(l, level, sideDetails_[1], blend.b.edits, &wantB);
    // Each side's influence (x: A, y: B), carried through the subdivision.
    std::vector<glm::dvec2> influence =
        l == 0 ? std::vector<glm::dvec2>(n, glm::dvec2(0.0))
               : surface_->subdivideValues(l, influence_[size_t(l) - 1]);
    forEachIndex(n, [&](size_t v) {
        const double a = alpha[v];
        if (a > 0.0)
            influence[v].x += a * (glm::length(detailA[v]) + std::fabs(scalarA[v]));
        if (a < 1.0)
            influence[v].y +=
                (1.0 - a) * (glm::length(level.detail[v]) + std::fabs(level.scalarDetail[v]));
        level.detail[v] = blendValue(detailA[v], level.detail[v], a);
        level.scalarDetail[v] = blendValue(scalarA[v], level.scalarDetail[v], a);
    });
    influence_[size_t(l)] = std::move(influence);
    addDetails(l, level, details_, spec_.edits, nullptr);
}

std::vector<double> ShapeSurface::blendParameter() const
{
    const size_t n = surface_->finest().vertexCount();
    if (!spec_.blend.enabled)
        return std::vector<double>(n, 1.0);
    const size_t L = size_t(levels());
    std::vector<double> beta(n);
    forEachIndex(n, [&](size_t v) {
        const double a = influence_[L][v].x, b = influence_[L][v].y;
        beta[v] = a + b > 0.0 ? std::clamp(a / (a + b), 0.0, 1.0) : alpha_[L][v];
    });
    return beta;
}

void ShapeSurface::synthesize(const std::function<void(double)>& progress)
{
    synthesizeFrom(0, progress);
}

void ShapeSurface::synthesizeFrom(int l, const std::function<void(double)>& progress)
{
    // Each level has about 4 times the vertices of the one before.
    const int last = surface_->levels();
    const double total = std::pow(4.0, last + 1) - std::pow(4.0, l);
    try {
        surface_->synthesizeFrom(l, [&](int lv, SubdivLevel& level) {
            hook(lv, level);
            if (progress)
                progress((std::pow(4.0, lv + 1) - std::pow(4.0, l)) / total);
        });
    } catch (const InputError& e) {  // a detail's, named by its path: the file too
        throw InputError(fmt::format("{}: {}", spec_.source, e.what()));
    }
}

glm::dvec3 shapeColor(const ColorSpec& c, double s, double beta)
{
    if (!c.sides.empty())
        return blendValue(shapeColor(c.sides[0], s, beta), shapeColor(c.sides[1], s, beta),
                          std::clamp(beta, 0.0, 1.0));
    if (!c.ramp)
        return c.color;
    const double t = std::clamp((s - c.low) / (c.high - c.low), 0.0, 1.0);
    return c.lowColor + (c.highColor - c.lowColor) * t;
}

TriangleMesh ShapeSurface::mesh() const
{
    const SubdivLevel& f = surface_->finest();
    const size_t n = f.vertexCount();
    const std::vector<double> beta = spec_.blend.enabled ? blendParameter() : std::vector<double>();
    auto betaAt = [&](size_t v) { return beta.empty() ? 1.0 : beta[v]; };
    if (!spec_.shader.enabled) {
        TriangleMesh m = levelMesh(f);
        m.colors.resize(n);
        forEachIndex(n, [&](size_t v) {
            const glm::dvec3 c = shapeColor(spec_.color, f.scalar[v], betaAt(v));
            m.colors[v] = openvdb::Vec3s(float(c.x), float(c.y), float(c.z));
        });
        return m;
    }
    // The post-blend shader: heights along the finest level's normals (its
    // frames', the surface its last details displace).
    std::vector<glm::dvec3> points(n);
    std::vector<openvdb::Vec3s> colors(n);
    forEachIndex(n, [&](size_t v) {
        const Shade s = shade(spec_.shader, f.scalar[v], betaAt(v));
        points[v] = f.points[v] + s.height * f.frames[v].n;
        colors[v] = openvdb::Vec3s(float(s.color.x), float(s.color.y), float(s.color.z));
    });
    TriangleMesh m = levelMesh(f, &points);
    m.colors = std::move(colors);
    return m;
}

}  // namespace cambium
