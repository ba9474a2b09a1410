// cambium — looking at a baked level set.
#include "use/render.h"

#include "cl/runtime.h"
#include "core/error.h"
#include "core/frames.h"
#include "core/files.h"
#include "core/math.h"
#include "core/system.h"
#include "io/vdb.h"
#include "use/world_sampler.h"
#include "core/clock.h"

#include <embree3/rtcore.h>
#include <malloc.h>
#include <fmt/format.h>
#include <openvdb/io/File.h>
#include <openvdb/math/Ray.h>
#include <openvdb/tools/RayIntersector.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/task_arena.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <optional>
#include <sstream>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <numeric>

namespace cambium {

Camera framingCamera(const Box& bounds, double aspect, double azimuthDeg, double elevationDeg)
{
    Camera cam;
    cam.target = bounds.center();
    const double radius = std::max(0.5 * glm::length(bounds.size()), 1e-9);
    const double az = glm::radians(azimuthDeg), el = glm::radians(elevationDeg);
    const glm::dvec3 dir(std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az));
    // The enclosing sphere fits the narrower of the two fields of view; then
    // the camera moves in (bisection) while the box's corners stay inside
    // the frame with a 5 % margin: a tall tree fills the height.
    const double tanY = std::tan(glm::radians(0.5 * cam.fovY)), tanX = tanY * aspect;
    const double far = radius / std::sin(std::min(std::atan(tanX), std::atan(tanY)));
    const glm::dvec3 w = -dir, u = glm::normalize(glm::cross(w, cam.up)), v = glm::cross(u, w);
    auto fits = [&](double distance) {
        const glm::dvec3 eye = cam.target + distance * dir;
        for (int k = 0; k < 8; ++k) {
            const glm::dvec3 c(k & 1 ? bounds.hi.x : bounds.lo.x, k & 2 ? bounds.hi.y : bounds.lo.y,
                               k & 4 ? bounds.hi.z : bounds.lo.z);
            const glm::dvec3 e = c - eye;
            const double z = glm::dot(e, w);
            if (!(z > 0.0) || std::abs(glm::dot(e, u)) > 0.95 * tanX * z ||
                std::abs(glm::dot(e, v)) > 0.95 * tanY * z)
                return false;
        }
        return true;
    };
    double lo = 0.0, hi = 1.1 * far;
    for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        (fits(mid) ? hi : lo) = mid;
    }
    cam.eye = cam.target + hi * dir;
    return cam;
}

Camera parseCamera(const std::string& spec, const Box& bounds, double aspect)
{
    if (spec == "auto")
        return framingCamera(bounds, aspect);
    // One decimal number of the spec, or a message naming it.
    auto number = [&](const std::string& item, const char* what) {
        char* end = nullptr;
        const double x = std::strtod(item.c_str(), &end);
        if (item.empty() || end == item.c_str() || *end != '\0' || !std::isfinite(x) ||
            writtenInHex(item.c_str(), end))
            throw InputError(fmt::format("--camera {}: {} '{}' is not a finite decimal number",
                                         spec, what, item));
        return x;
    };
    const std::string turntable = "turntable:";
    if (spec.rfind(turntable, 0) == 0)
        return framingCamera(bounds, aspect,
                             35.0 + number(spec.substr(turntable.size()), "the angle"));
    // look:EX,EY,EZ:TX,TY,TZ[:FOV] — an eye, a target and a vertical field of view.
    const std::string look = "look:";
    if (spec.rfind(look, 0) != 0)
        throw InputError(
            fmt::format("--camera {}: expected auto, turntable:ANGLE (degrees) or "
                        "look:EX,EY,EZ:TX,TY,TZ[:FOV]",
                        spec));
    std::vector<std::string> items;
    {
        std::string rest = spec.substr(look.size()), item;
        for (char& c : rest)
            if (c == ':')
                c = ',';
        std::istringstream in(rest + ",");
        while (std::getline(in, item, ','))
            items.push_back(item);
    }
    if (items.size() != 6 && items.size() != 7)
        throw InputError(
            fmt::format("--camera {}: look: takes 6 or 7 numbers (EX,EY,EZ:TX,TY,TZ[:FOV]), got {}",
                        spec, items.size()));
    static const char* const kNames[] = {"EX", "EY", "EZ", "TX", "TY", "TZ", "FOV"};
    double v[7];
    for (size_t i = 0; i < items.size(); ++i) {
        v[i] = number(items[i], kNames[i]);
        // (1e300 overflowed the view's direction, named "vertical")
        if (i < 6 && !(std::fabs(v[i]) <= kFarthestCoordinate))
            throw InputError(
                fmt::format("--camera {}: {} {:g} is beyond the {:g} from the origin "
                            "cambium reads",
                            spec, kNames[i], v[i], kFarthestCoordinate));
    }
    Camera cam;
    cam.eye = {v[0], v[1], v[2]};
    cam.target = {v[3], v[4], v[5]};
    if (items.size() == 7)
        cam.fovY = v[6];
    const glm::dvec3 w = cam.target - cam.eye;
    // (Below 1e-4 degrees a pixel's rays differ by less than a float
    // resolves: at 1e-9 every ray missed, an empty picture.)
    constexpr double kNarrowestView = 1e-4;
    if (!(glm::length(w) > 0.0))
        throw InputError(fmt::format("--camera {}: the eye is the target", spec));
    if (!(glm::length(glm::cross(glm::normalize(w), cam.up)) > 1e-6))
        throw InputError(fmt::format(
            "--camera {}: the view is vertical (the picture's up is +y: move the eye aside)",
            spec));
    if (!(cam.fovY >= kNarrowestView && cam.fovY < 180.0))
        throw InputError(fmt::format(
            "--camera {}: the field of view must be from {:g} to below 180 degrees (got {:g})",
            spec, kNarrowestView, cam.fovY));
    return cam;
}

Camera orbitCamera(const Camera& cam, double azimuthDeg, double elevationDeg)
{
    const glm::dvec3 d = cam.eye - cam.target;
    const double r = glm::length(d);
    const double azimuth = std::atan2(d.x, d.z) + glm::radians(azimuthDeg);
    const double elevation =
        std::clamp(std::asin(std::clamp(d.y / r, -1.0, 1.0)) + glm::radians(elevationDeg),
                   glm::radians(-85.0), glm::radians(85.0));
    Camera out = cam;
    out.eye =
        cam.target + r * glm::dvec3(std::cos(elevation) * std::sin(azimuth), std::sin(elevation),
                                    std::cos(elevation) * std::cos(azimuth));
    return out;
}

CameraFrame::CameraFrame(const Camera& cam, int w_, int h_)
    : eye(cam.eye),
      w(glm::normalize(cam.target - cam.eye)),
      u(glm::normalize(glm::cross(w, cam.up))),
      v(glm::cross(u, w)),
      tanY(std::tan(glm::radians(0.5 * cam.fovY))),
      width(w_),
      height(h_)
{
}

void CameraFrame::ray(double px, double py, glm::dvec3& origin, glm::dvec3& direction) const
{
    const double sx = (2.0 * px / width - 1.0) * tanY * double(width) / double(height);
    const double sy = (1.0 - 2.0 * py / height) * tanY;
    origin = eye;
    direction = glm::normalize(w + sx * u + sy * v);
}

void cameraRay(const Camera& cam, int width, int height, double px, double py, glm::dvec3& origin,
               glm::dvec3& direction)
{
    CameraFrame(cam, width, height).ray(px, py, origin, direction);
}

glm::vec3 shadeSurface(const glm::vec3& n, const glm::vec3& albedo)
{
    const glm::vec3 key = glm::normalize(glm::vec3(-0.45f, 0.75f, 0.5f));
    const float sky = 0.30f + 0.15f * n.y;  // brighter facing up
    const float sun = 0.85f * std::max(0.0f, glm::dot(n, key));
    return albedo * (sky + sun);
}

glm::vec3 shadeBackground(const glm::dvec3& dir)
{
    const float t = float(std::clamp(0.5 * (dir.y + 1.0), 0.0, 1.0));
    return glm::mix(glm::vec3(0.80f, 0.82f, 0.85f), glm::vec3(0.45f, 0.58f, 0.78f), t);
}

namespace {

RenderImage blankImage(int width, int height)
{
    RenderImage img;
    img.width = width;
    img.height = height;
    const size_t n = size_t(width) * size_t(height);
    img.rgb.assign(3 * n, 0.0f);
    img.alpha.assign(n, 0.0f);
    img.depth.assign(n, std::numeric_limits<float>::infinity());
    img.normal.assign(3 * n, 0.0f);
    return img;
}

/// A picture's rays, spp a pixel: sample 0 through the pixel's centre, the
/// others spread by the plastic-number (R2) sequence.
class PixelRays {
public:
    PixelRays(const Camera& camera, int width, int height, int spp)
        : frame_(camera, width, height), width_(width), spp_(size_t(spp)), jx_(spp_), jy_(spp_)
    {
        for (size_t s = 0; s < spp_; ++s) {
            jx_[s] = s == 0 ? 0.5 : std::fmod(0.5 + double(s) * 0.7548776662466927, 1.0);
            jy_[s] = s == 0 ? 0.5 : std::fmod(0.5 + double(s) * 0.5698402909980532, 1.0);
        }
    }
    /// Pixel (x, y)'s spp rays into `rays`.
    void pixel(int x, int y, TraceRay* rays) const
    {
        for (size_t s = 0; s < spp_; ++s)
            frame_.ray(x + jx_[s], y + jy_[s], rays[s].origin, rays[s].direction);
    }
    /// Row y's width * spp rays, pixel by pixel.
    void row(int y, TraceRay* rays) const
    {
        for (int x = 0; x < width_; ++x)
            pixel(x, y, rays + size_t(x) * spp_);
    }

private:
    CameraFrame frame_;
    int width_;
    size_t spp_;
    std::vector<double> jx_, jy_;
};

/// Shades row y from its rays' hits: the mean of the samples' colours, the
/// fraction that hit, depth and normal of the central sample.
void resolveRow(RenderImage& img, int spp, int y, const TraceRay* rays, const TraceHit* hits)
{
    for (int x = 0; x < img.width; ++x) {
        const size_t i = size_t(y) * size_t(img.width) + size_t(x);
        glm::vec3 sum(0.0f);
        int count = 0;
        for (int s = 0; s < spp; ++s) {
            const size_t k = size_t(x) * size_t(spp) + size_t(s);
            const TraceHit& h = hits[k];
            if (!h.hit) {
                sum += shadeBackground(rays[k].direction);
                continue;
            }
            ++count;
            sum += shadeSurface(h.normal, h.albedo);
            if (s == 0) {
                img.depth[i] = float(h.t);
                for (int c = 0; c < 3; ++c)
                    img.normal[3 * i + size_t(c)] = h.normal[c];
            }
        }
        const glm::vec3 c = sum / float(spp);
        for (int k = 0; k < 3; ++k)
            img.rgb[3 * i + size_t(k)] = c[k];
        img.alpha[i] = float(count) / float(spp);
    }
}

/// Renders a row at a time on all threads, with a tracer made per task
/// (`makeTracer`: tracers may hold accessors or ray buffers).  With
/// `ranges`, each pixel's rays are traced over its range only, and not at
/// all where it has none (they miss).
RenderImage renderRows(const Camera& camera, int width, int height, int spp,
                       const std::function<BatchTracer()>& makeTracer,
                       const RayRanges* ranges = nullptr)
{
    RenderImage img = blankImage(width, height);
    spp = std::max(1, spp);
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& rows) {
        const BatchTracer trace = makeTracer();
        const PixelRays generate(camera, width, height, spp);
        std::vector<TraceRay> rays(size_t(width) * size_t(spp)), traced;
        std::vector<TraceHit> hits(rays.size()), found;
        for (int y = rows.begin(); y < rows.end(); ++y) {
            generate.row(y, rays.data());
            if (!ranges) {
                trace(rays, hits);
            } else {
                const size_t row = size_t(y) * size_t(width);
                traced.clear();
                for (int x = 0; x < width; ++x) {
                    const float near = ranges->near[row + size_t(x)];
                    if (!(near <= ranges->far[row + size_t(x)]))
                        continue;
                    for (int s = 0; s < spp; ++s) {
                        TraceRay r = rays[size_t(x) * size_t(spp) + size_t(s)];
                        r.tmin = near;
                        r.tmax = ranges->far[row + size_t(x)];
                        traced.push_back(r);
                    }
                }
                if (!traced.empty())
                    trace(traced, found);
                size_t k = 0;
                for (int x = 0; x < width; ++x) {
                    const bool some = ranges->near[row + size_t(x)] <= ranges->far[row + size_t(x)];
                    for (int s = 0; s < spp; ++s)
                        hits[size_t(x) * size_t(spp) + size_t(s)] = some ? found[k++] : TraceHit();
                }
            }
            resolveRow(img, spp, y, rays.data(), hits.data());
        }
    });
    return img;
}

glm::vec3 unit(double x, double y, double z)
{
    const double len = std::sqrt(x * x + y * y + z * z);
    return len > 0.0 ? glm::vec3(float(x / len), float(y / len), float(z / len)) : glm::vec3(0.0f);
}

}  // namespace

struct CpuMarcher::Impl {
    using Intersector = openvdb::tools::LevelSetRayIntersector<openvdb::FloatGrid>;
    Intersector prototype;  // copied per tracer: its constructor measures the grid
    const openvdb::FloatGrid& surface;
    const openvdb::Vec3fGrid* color;
    Impl(const openvdb::FloatGrid& s, const openvdb::Vec3fGrid* c)
        : prototype(s), surface(s), color(c)
    {
    }
};

CpuMarcher::CpuMarcher(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color)
    : impl_(std::make_unique<Impl>(surface, color))
{
}

CpuMarcher::~CpuMarcher() = default;

BatchTracer CpuMarcher::tracer() const
{
    using RayT = Impl::Intersector::RayType;
    // An intersector and colour sampler of its own: both hold accessors.
    auto isect = std::make_shared<Impl::Intersector>(impl_->prototype);
    std::shared_ptr<const WorldSampler<openvdb::Vec3fGrid>> cs;
    if (impl_->color)
        cs = std::make_shared<const WorldSampler<openvdb::Vec3fGrid>>(*impl_->color);
    return [isect, cs](const std::vector<TraceRay>& rays, std::vector<TraceHit>& hits) {
        hits.resize(rays.size());
        for (size_t k = 0; k < rays.size(); ++k) {
            const glm::dvec3 &o = rays[k].origin, &d = rays[k].direction;
            // (OpenVDB's rays start a little after the eye and end at the
            // largest double, as its own defaults do)
            const RayT ray(openvdb::Vec3d(o.x, o.y, o.z), openvdb::Vec3d(d.x, d.y, d.z),
                           std::max(rays[k].tmin, openvdb::math::Delta<double>::value()),
                           std::min(rays[k].tmax, std::numeric_limits<double>::max()));
            openvdb::Vec3d p, g;
            double t = 0.0;
            TraceHit& h = hits[k];
            h = TraceHit();
            h.hit = isect->intersectsWS(ray, p, g, t);
            if (!h.hit)
                continue;
            h.t = t;
            h.position = glm::dvec3(p.x(), p.y(), p.z());
            h.normal = unit(g.x(), g.y(), g.z());
            h.albedo = kBarkAlbedo;
            if (cs) {
                const openvdb::Vec3f c = (*cs)(p);
                h.albedo = glm::vec3(c.x(), c.y(), c.z());
            }
        }
    };
}

void checkPicture(int width, int height, int spp)
{
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        throw InputError(fmt::format(
            "--width and --height must be between 1 and 16384 (got {} x {})", width, height));
    if (spp < 1 || spp > 4096)
        throw InputError(fmt::format("--spp must be between 1 and 4096 (got {})", spp));
    checkMemoryFits(128.0 * double(width) * double(height),
                    fmt::format("--width {} --height {}: a picture this large", width, height));
    // Each thread holds a row's samples at once: its rays, the rays it
    // traces and their hits (a 16384-pixel row at 4096 samples ran out of
    // memory after seconds, exit 1, sweep 20).
    const double sample = 2.0 * sizeof(TraceRay) + 2.0 * sizeof(TraceHit) + sizeof(uint32_t);
    // (the threads this process may run, a row each, as TBB counts them: a
    // Slurm task's CPUs, not the node's)
    const int threads = std::max(1, std::min(tbb::this_task_arena::max_concurrency(), height));
    checkMemoryFits(double(threads) * double(width) * double(spp) * sample,
                    fmt::format("--width {} at --spp {}: the rows' {} samples that {} threads hold "
                                "at once",
                                width, spp, formatCount(double(width) * double(spp)), threads),
                    "fewer samples per pixel, or a narrower picture");
}

void voxelizeActiveTiles(openvdb::FloatGrid& grid)
{
    auto tiles = grid.tree().cbeginValueOn();
    tiles.setMaxDepth(openvdb::FloatTree::ValueOnCIter::LEAF_DEPTH - 1);
    if (tiles)
        grid.tree().voxelizeActiveTiles();
}

namespace {

/// Where a box of a level set may be seen: the pixels its projection spans
/// (a pixel wider each way; x0 > x1 or y0 > y1: none of the picture's) and
/// the distances of its bounding sphere from the eye; `all` where a corner
/// lies at or behind the eye (any pixel, at any distance).
struct Footprint {
    bool all = false;
    int x0 = 0, x1 = -1, y0 = 0, y1 = -1;
    float near = 0.0f, far = 0.0f;
    bool seen() const { return all || (x0 <= x1 && y0 <= y1); }
};

/// Box b's footprint (index space, two voxels wider each way: a crossing of
/// the interpolated values lies within a cell of the voxels that hold it,
/// and the lookups around it read a voxel past it), from its corners.
Footprint footprint(const openvdb::math::Transform& xform, const openvdb::CoordBBox& b,
                    const CameraFrame& f)
{
    Footprint p;
    const int width = f.width, height = f.height;
    const double aspect = double(width) / double(height);
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    glm::dvec3 corner[8];
    for (int c = 0; c < 8; ++c) {
        const openvdb::Vec3d w =
            xform.indexToWorld(openvdb::Vec3d(c & 1 ? b.max()[0] + 2.0 : b.min()[0] - 2.0,
                                              c & 2 ? b.max()[1] + 2.0 : b.min()[1] - 2.0,
                                              c & 4 ? b.max()[2] + 2.0 : b.min()[2] - 2.0));
        corner[c] = glm::dvec3(w.x(), w.y(), w.z());
        const glm::dvec3 d = corner[c] - f.eye;
        const double z = glm::dot(d, f.w);
        if (!(z > 1e-9 * glm::length(d))) {  // at or behind the eye: any pixel
            p.all = true;
            return p;
        }
        const double sx = glm::dot(d, f.u) / z, sy = glm::dot(d, f.v) / z;
        const double px = (sx / (f.tanY * aspect) + 1.0) * 0.5 * width,
                     py = (1.0 - sy / f.tanY) * 0.5 * height;
        x0 = std::min(x0, px);
        x1 = std::max(x1, px);
        y0 = std::min(y0, py);
        y1 = std::max(y1, py);
    }
    const glm::dvec3 centre = 0.5 * (corner[0] + corner[7]);
    double radius = 0.0;
    for (const glm::dvec3& c : corner)
        radius = std::max(radius, glm::length(c - centre));
    const double d = glm::length(centre - f.eye);
    p.near = float(std::max(0.0, d - radius) * (1.0 - 1e-6));
    p.far = float((d + radius) * (1.0 + 1e-6));
    // (clamped in double: a box far off the picture's side projects beyond
    // an int's range)
    auto clampTo = [](double v, int hi) { return int(std::clamp(v, -2.0, double(hi) + 1.0)); };
    p.x0 = std::max(0, clampTo(std::floor(x0), width) - 1);
    p.x1 = std::min(width - 1, clampTo(std::floor(x1), width) + 1);
    p.y0 = std::max(0, clampTo(std::floor(y0), height) - 1);
    p.y1 = std::min(height - 1, clampTo(std::floor(y1), height) + 1);
    return p;
}

/// The footprints of `leaves` (on all cores).
template <class LeafT>
std::vector<Footprint> leafFootprints(const openvdb::math::Transform& xform,
                                      const std::vector<LeafT*>& leaves, const CameraFrame& f)
{
    std::vector<Footprint> out(leaves.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.size()),
                      [&](const tbb::blocked_range<size_t>& r) {
                          for (size_t i = r.begin(); i < r.end(); ++i)
                              out[i] = footprint(xform, leaves[i]->getNodeBoundingBox(), f);
                      });
    return out;
}

/// rayRanges of a grid whose leaves' footprints are `leaves` (in the
/// tree's order).
RayRanges rangesOf(const openvdb::FloatGrid& grid, const std::vector<Footprint>& leaves,
                   const CameraFrame& f)
{
    const int width = f.width, height = f.height;
    const size_t n = size_t(width) * size_t(height);
    RayRanges r;
    r.near.assign(n, std::numeric_limits<float>::infinity());
    r.far.assign(n, 0.0f);
    bool all = false;
    auto mark = [&](const Footprint& p) {
        all = all || p.all;
        for (int y = p.y0; y <= p.y1 && !all; ++y)
            for (int x = p.x0; x <= p.x1; ++x) {
                const size_t i = size_t(y) * size_t(width) + size_t(x);
                r.near[i] = std::min(r.near[i], p.near);
                r.far[i] = std::max(r.far[i], p.far);
            }
    };
    for (size_t i = 0; i < leaves.size() && !all; ++i)
        mark(leaves[i]);
    // Active tiles (files of other tools), above the leaves only.
    auto tile = grid.tree().cbeginValueOn();
    tile.setMaxDepth(grid.tree().treeDepth() - 2);
    for (; tile && !all; ++tile) {
        openvdb::CoordBBox b;
        tile.getBoundingBox(b);
        mark(footprint(grid.transform(), b, f));
    }
    if (all) {
        std::fill(r.near.begin(), r.near.end(), 0.0f);
        std::fill(r.far.begin(), r.far.end(), std::numeric_limits<float>::infinity());
    }
    return r;
}

/// The grid's leaves, in the tree's order.
std::vector<const openvdb::FloatTree::LeafNodeType*> leavesOf(const openvdb::FloatGrid& grid)
{
    std::vector<const openvdb::FloatTree::LeafNodeType*> leaves;
    leaves.reserve(grid.tree().leafCount());
    for (auto it = grid.tree().cbeginLeaf(); it; ++it)
        leaves.push_back(it.getLeaf());
    return leaves;
}

}  // namespace

RayRanges rayRanges(const openvdb::FloatGrid& grid, const Camera& camera, int width, int height)
{
    const CameraFrame f(camera, width, height);
    return rangesOf(grid, leafFootprints(grid.transform(), leavesOf(grid), f), f);
}

RenderImage CpuMarcher::render(const Camera& camera, int width, int height, int spp) const
{
    // Rays through pixels that no active leaf covers miss: they are not
    // traced (the picture is the same, tests/test_render.cpp).
    const RayRanges ranges = rayRanges(impl_->surface, camera, width, height);
    return renderRows(
        camera, width, height, spp, [this] { return tracer(); }, &ranges);
}

RenderImage renderLevelSetCpu(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                              const Camera& camera, int width, int height, int spp)
{
    return CpuMarcher(surface, color).render(camera, width, height, spp);
}

RenderImage renderBackground(const Camera& camera, int width, int height, int spp)
{
    return renderRows(camera, width, height, spp, [] {
        return [](const std::vector<TraceRay>&, std::vector<TraceHit>& hits) {
            std::fill(hits.begin(), hits.end(), TraceHit());
        };
    });
}

namespace {

/// The origins of the leaves a trilinear lookup at each of `hits` reads (the
/// voxels at the floor of its index point and one past on each axis),
/// sorted, each once.
std::vector<openvdb::Coord> leavesLookedUp(
    const openvdb::math::Transform& xform,
    const std::vector<std::vector<std::pair<uint32_t, TraceHit>>>& hits)
{
    tbb::enumerable_thread_specific<std::vector<openvdb::Coord>> found;
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, hits.size()), [&](const tbb::blocked_range<size_t>& r) {
            std::vector<openvdb::Coord> part;
            for (size_t y = r.begin(); y < r.end(); ++y)
                for (const auto& [k, hit] : hits[y]) {
                    const glm::dvec3& p = hit.position;
                    const openvdb::Coord lo =
                        openvdb::Coord::floor(xform.worldToIndex(openvdb::Vec3d(p.x, p.y, p.z)));
                    const openvdb::Coord a(lo.x() & ~7, lo.y() & ~7, lo.z() & ~7),
                        b((lo.x() + 1) & ~7, (lo.y() + 1) & ~7, (lo.z() + 1) & ~7);
                    for (int c = 0; c < 8; ++c) {
                        const openvdb::Coord o(c & 1 ? b.x() : a.x(), c & 2 ? b.y() : a.y(),
                                               c & 4 ? b.z() : a.z());
                        if (part.empty() || part.back() != o)
                            part.push_back(o);
                    }
                }
            // (each range's once, not each row's: the thread's
            // list grows over many ranges)
            std::sort(part.begin(), part.end());
            part.erase(std::unique(part.begin(), part.end()), part.end());
            std::vector<openvdb::Coord>& out = found.local();
            out.insert(out.end(), part.begin(), part.end());
        });
    std::vector<openvdb::Coord> all;
    for (const std::vector<openvdb::Coord>& part : found)
        all.insert(all.end(), part.begin(), part.end());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    return all;
}

/// Rows traced a strip at a time (`trace(first, last)`: rows first to
/// last - 1), each strip's leaves decoded before it and dropped once no
/// later strip needs them: a strip's rows as many as keep the leaves held
/// at most `atOnce` (at least a row a strip).  `prints`: the grid's leaves'
/// footprints, in the tree's order; leaves off the picture are never
/// decoded.  Where the grid has other leaves than `lazy`'s (active tiles
/// made voxels) or a box lies behind the eye, every leaf is decoded for one
/// strip.
void traceStrips(LazyLeaves& lazy, const std::vector<Footprint>& prints, int height, size_t atOnce,
                 const std::function<void(int, int)>& trace, LazySurface::Stats* stats)
{
    const size_t n = lazy.leaves().size();
    LazySurface::Stats seen;
    std::vector<std::vector<size_t>> startsAt(size_t(height) + 1);
    bool whole = prints.size() != n;
    for (size_t i = 0; i < n && !whole; ++i) {
        whole = prints[i].all;
        if (prints[i].seen())
            startsAt[size_t(prints[i].y0)].push_back(i);
    }
    if (whole) {
        std::vector<size_t> every(n);
        std::iota(every.begin(), every.end(), size_t(0));
        lazy.decode(every);
        trace(0, height);
        lazy.checkZeroCrossing();
        if (stats)
            *stats = LazySurface::Stats{1, n, n, 0};
        return;
    }
    std::vector<size_t> held, fresh, kept, dropped;
    for (int first = 0; first < height;) {
        // As many rows as keep the leaves held within atOnce.
        int last = first;
        size_t count = held.size();
        do {
            count += startsAt[size_t(last)].size();
            ++last;
        } while (last < height && count + startsAt[size_t(last)].size() <= atOnce);
        fresh.clear();
        for (int y = first; y < last; ++y)
            fresh.insert(fresh.end(), startsAt[size_t(y)].begin(), startsAt[size_t(y)].end());
        std::sort(fresh.begin(), fresh.end());
        lazy.decode(fresh);
        held.insert(held.end(), fresh.begin(), fresh.end());
        ++seen.strips;
        seen.mostHeld = std::max(seen.mostHeld, held.size());
        seen.decoded += fresh.size();
        trace(first, last);
        if (stats) {
            std::vector<uint8_t> isHeld(n, 0);
            for (size_t i : held)
                isHeld[i] = 1;
            for (size_t i = 0; i < n; ++i)
                seen.strayLeaves += !isHeld[i] && !lazy.leaves()[i]->buffer().empty();
        }
        kept.clear();
        dropped.clear();
        for (size_t i : held)
            (prints[i].y1 >= last ? kept : dropped).push_back(i);
        std::sort(dropped.begin(), dropped.end());
        lazy.drop(dropped);
        held.swap(kept);
        first = last;
    }
    lazy.checkZeroCrossing();
    if (stats)
        *stats = seen;
}

}  // namespace

RenderImage renderLevelSetCpu(
    openvdb::FloatGrid::Ptr surface,
    const std::function<openvdb::Vec3fGrid::Ptr(const std::vector<openvdb::Coord>&)>& colour,
    const Camera& camera, int width, int height, int spp, LazySurface lazy)
{
    spp = std::max(1, spp);
    const size_t rowRays = size_t(width) * size_t(spp);
    // 1. Every row's rays against the level set alone; its hits kept (ray
    //    index within the row, the hit).
    std::vector<std::vector<std::pair<uint32_t, TraceHit>>> hits(static_cast<size_t>(height));
    {
        const CameraFrame frame(camera, width, height);
        const std::vector<Footprint> prints =
            leafFootprints(surface->transform(), leavesOf(*surface), frame);
        const RayRanges ranges = rangesOf(*surface, prints, frame);
        const CpuMarcher marcher(*surface, nullptr);
        auto traceRows = [&](int first, int last) {
            tbb::parallel_for(
                tbb::blocked_range<int>(first, last), [&](const tbb::blocked_range<int>& r) {
                    const BatchTracer trace = marcher.tracer();
                    const PixelRays generate(camera, width, height, spp);
                    std::vector<TraceRay> rays(rowRays), traced;
                    std::vector<uint32_t> index;
                    std::vector<TraceHit> found;
                    for (int y = r.begin(); y < r.end(); ++y) {
                        traced.clear();
                        index.clear();
                        const size_t row = size_t(y) * size_t(width);
                        for (int x = 0; x < width; ++x) {
                            const float near = ranges.near[row + size_t(x)],
                                        far = ranges.far[row + size_t(x)];
                            if (!(near <= far))
                                continue;  // (its rays miss: not even made)
                            generate.pixel(x, y, rays.data() + size_t(x) * size_t(spp));
                            for (int s = 0; s < spp; ++s) {
                                const size_t k = size_t(x) * size_t(spp) + size_t(s);
                                TraceRay ray = rays[k];
                                ray.tmin = near;
                                ray.tmax = far;
                                traced.push_back(ray);
                                index.push_back(uint32_t(k));
                            }
                        }
                        if (traced.empty())
                            continue;
                        trace(traced, found);
                        for (size_t i = 0; i < found.size(); ++i)
                            if (found[i].hit)
                                hits[size_t(y)].emplace_back(index[i], found[i]);
                    }
                });
        };
        if (lazy.leaves)
            traceStrips(*lazy.leaves, prints, height, std::max<size_t>(1, lazy.leavesAtOnce),
                        traceRows, lazy.stats);
        else
            traceRows(0, height);
    }
    // 2. The level set goes (with the memory the allocator keeps), then the
    //    colour comes, the leaves the hits look up, and each hit's albedo is
    //    looked up.
    const std::vector<openvdb::Coord> leaves =
        colour ? leavesLookedUp(surface->transform(), hits) : std::vector<openvdb::Coord>();
    lazy.leaves.reset();
    surface.reset();
    ::malloc_trim(0);
    const openvdb::Vec3fGrid::Ptr color = colour ? colour(leaves) : nullptr;
    RenderImage img = blankImage(width, height);
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        std::unique_ptr<WorldSampler<openvdb::Vec3fGrid>> sample;
        if (color)
            sample = std::make_unique<WorldSampler<openvdb::Vec3fGrid>>(*color);
        const PixelRays generate(camera, width, height, spp);
        std::vector<TraceRay> rays(rowRays);
        std::vector<TraceHit> row(rowRays);
        for (int y = r.begin(); y < r.end(); ++y) {
            generate.row(y, rays.data());
            std::fill(row.begin(), row.end(), TraceHit());
            for (const auto& [k, hit] : hits[size_t(y)]) {
                TraceHit& h = row[k];
                h = hit;
                if (sample) {
                    const glm::dvec3& p = hit.position;
                    const openvdb::Vec3f c = (*sample)(openvdb::Vec3d(p.x, p.y, p.z));
                    h.albedo = glm::vec3(c.x(), c.y(), c.z());
                }
            }
            resolveRow(img, spp, y, rays.data(), row.data());
        }
    });
    return img;  // (the colour grid goes with this scope)
}

RenderImage renderBatches(const Camera& camera, int width, int height, int spp,
                          const BatchTracer& trace, size_t raysPerBatch)
{
    RenderImage img = blankImage(width, height);
    spp = std::max(1, spp);
    const size_t rowRays = size_t(width) * size_t(spp);
    const int rowsPerBatch = int(std::clamp<size_t>(raysPerBatch / rowRays, 1, size_t(height)));
    std::vector<TraceRay> rays(rowRays * size_t(rowsPerBatch));
    std::vector<TraceHit> hits(rays.size());
    const PixelRays generate(camera, width, height, spp);
    for (int y0 = 0; y0 < height; y0 += rowsPerBatch) {
        const int rows = std::min(rowsPerBatch, height - y0);
        tbb::parallel_for(0, rows,
                          [&](int r) { generate.row(y0 + r, rays.data() + size_t(r) * rowRays); });
        rays.resize(size_t(rows) * rowRays);
        hits.resize(rays.size());
        trace(rays, hits);
        tbb::parallel_for(0, rows, [&](int r) {
            resolveRow(img, spp, y0 + r, rays.data() + size_t(r) * rowRays,
                       hits.data() + size_t(r) * rowRays);
        });
    }
    return img;
}

struct EmbreeMesh::Impl {
    const TriangleMesh& mesh;
    RTCDevice device = nullptr;
    RTCScene scene = nullptr;
    explicit Impl(const TriangleMesh& m) : mesh(m) {}
    ~Impl()
    {
        if (scene)
            rtcReleaseScene(scene);
        if (device)
            rtcReleaseDevice(device);
    }
};

EmbreeMesh::EmbreeMesh(const TriangleMesh& mesh) : impl_(std::make_unique<Impl>(mesh))
{
    RTCDevice device = impl_->device = rtcNewDevice(nullptr);
    if (!device)
        throw std::runtime_error("Embree: cannot create a device");
    RTCScene scene = impl_->scene = rtcNewScene(device);
    RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    auto* v = static_cast<float*>(rtcSetNewGeometryBuffer(
        geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.points.size()));
    auto* idx = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                3 * sizeof(uint32_t), mesh.triangles.size()));
    if (!v || !idx) {
        rtcReleaseGeometry(geom);
        throw std::runtime_error("Embree: cannot allocate the mesh's buffers");
    }
    tbb::parallel_for(size_t(0), mesh.points.size(), [&](size_t i) {
        for (int k = 0; k < 3; ++k)
            v[3 * i + size_t(k)] = mesh.points[i][k];
    });
    tbb::parallel_for(size_t(0), mesh.triangles.size(), [&](size_t i) {
        for (int k = 0; k < 3; ++k)
            idx[3 * i + size_t(k)] = mesh.triangles[i][size_t(k)];
    });
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    rtcCommitScene(scene);
    // (Embree reports a failed build only here: short of memory, it left an
    // empty scene, and the picture was drawn empty with exit 0)
    const RTCError error = rtcGetDeviceError(device);
    if (error != RTC_ERROR_NONE)
        throw std::runtime_error(
            fmt::format("Embree could not build its structure over the mesh's {} triangles: {}",
                        mesh.triangles.size(),
                        error == RTC_ERROR_OUT_OF_MEMORY ? std::string("out of memory")
                                                         : fmt::format("error {}", int(error))));
}

EmbreeMesh::~EmbreeMesh() = default;

RenderImage renderMeshEmbree(const TriangleMesh& mesh, const Camera& camera, int width, int height,
                             int spp)
{
    return EmbreeMesh(mesh).render(camera, width, height, spp);
}

RenderImage EmbreeMesh::render(const Camera& camera, int width, int height, int spp) const
{
    const TriangleMesh& mesh = impl_->mesh;
    RTCScene scene = impl_->scene;
    return renderRows(camera, width, height, spp, [&]() -> BatchTracer {
        auto buffer = std::make_shared<std::vector<RTCRayHit>>();
        return
            [&mesh, scene, buffer](const std::vector<TraceRay>& rays, std::vector<TraceHit>& hits) {
                // A stream of the row's rays (rtcIntersect1M).
                std::vector<RTCRayHit>& rh = *buffer;
                rh.resize(rays.size());
                for (size_t k = 0; k < rays.size(); ++k) {
                    RTCRayHit& r = rh[k];
                    r.ray.org_x = float(rays[k].origin.x);
                    r.ray.org_y = float(rays[k].origin.y);
                    r.ray.org_z = float(rays[k].origin.z);
                    r.ray.dir_x = float(rays[k].direction.x);
                    r.ray.dir_y = float(rays[k].direction.y);
                    r.ray.dir_z = float(rays[k].direction.z);
                    r.ray.tnear = 0.0f;
                    r.ray.tfar = std::numeric_limits<float>::infinity();
                    r.ray.time = 0.0f;
                    r.ray.mask = 0xFFFFFFFFu;
                    r.ray.id = unsigned(k);
                    r.ray.flags = 0;
                    r.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                    r.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                }
                RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                rtcIntersect1M(scene, &ctx, rh.data(), unsigned(rh.size()), sizeof(RTCRayHit));
                for (size_t k = 0; k < rays.size(); ++k) {
                    TraceHit& h = hits[k];
                    h.hit = rh[k].hit.geomID != RTC_INVALID_GEOMETRY_ID;
                    if (!h.hit)
                        continue;
                    h.t = rh[k].ray.tfar;
                    const auto& tri = mesh.triangles[rh[k].hit.primID];
                    const float u = rh[k].hit.u, w = rh[k].hit.v, b0 = 1.0f - u - w;
                    const openvdb::Vec3s n = b0 * mesh.normals[tri[0]] + u * mesh.normals[tri[1]] +
                                             w * mesh.normals[tri[2]];
                    h.normal = unit(n.x(), n.y(), n.z());
                    h.albedo = kBarkAlbedo;
                    if (!mesh.colors.empty()) {
                        const openvdb::Vec3s c = b0 * mesh.colors[tri[0]] +
                                                 u * mesh.colors[tri[1]] + w * mesh.colors[tri[2]];
                        h.albedo = glm::vec3(c.x(), c.y(), c.z());
                    }
                }
            };
    });
}

Box meshBounds(const TriangleMesh& mesh)
{
    Box b;
    for (const auto& p : mesh.points)
        b.expand(glm::dvec3(p.x(), p.y(), p.z()));
    return b;
}

namespace {

/// An index-space box of a grid in world space.
Box worldBox(const openvdb::GridBase& grid, const openvdb::CoordBBox& b)
{
    if (b.empty())
        return Box();
    const openvdb::Vec3d lo = grid.indexToWorld(b.min().asVec3d()),
                         hi = grid.indexToWorld(b.max().asVec3d());
    return Box(
        glm::dvec3(std::min(lo.x(), hi.x()), std::min(lo.y(), hi.y()), std::min(lo.z(), hi.z())),
        glm::dvec3(std::max(lo.x(), hi.x()), std::max(lo.y(), hi.y()), std::max(lo.z(), hi.z())));
}

}  // namespace

Box storedActiveBounds(const std::string& path, const std::string& grid)
{
    // (a FIFO named as one before OpenVDB opens it: the open waited for ever)
    checkInputFile(path, ".vdb file");
    try {
        openvdb::io::File file(path);
        file.open(false);
        const openvdb::GridBase::Ptr g = file.readGridMetadata(grid);
        file.close();
        const auto lo =
            g->getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MIN);
        const auto hi =
            g->getMetadata<openvdb::Vec3IMetadata>(openvdb::GridBase::META_FILE_BBOX_MAX);
        if (lo && hi)
            return worldBox(
                *g, openvdb::CoordBBox(openvdb::Coord(lo->value()), openvdb::Coord(hi->value())));
    } catch (const std::exception&) {
        // (readLevelSet below names what is wrong with the file)
    }
    return activeWorldBounds(*readLevelSet(path, grid).surface);
}

Box activeWorldBounds(const openvdb::GridBase& grid)
{
    return worldBox(grid, grid.evalActiveVoxelBoundingBox());
}

}  // namespace cambium
