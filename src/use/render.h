// cambium — looking at a baked level set: a camera that frames it, ray
// marching through VDB's hierarchical DDA, simple shading, images written
// with OpenImageIO.
#pragma once

#include "core/box.h"
#include "io/grids.h"
#include "io/vdb.h"
#include "io/image_file.h"
#include "use/mesh.h"

#include <glm/glm.hpp>

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace cambium {

/// A pinhole camera, y up.
struct Camera {
    glm::dvec3 eye{0.0, 0.0, 1.0}, target{0.0}, up{0.0, 1.0, 0.0};
    double fovY = 35.0;  ///< vertical field of view, degrees
};

/// A view of `bounds` (world space) from `azimuthDeg` around the vertical
/// axis and `elevationDeg` above the horizon, as close as the bounds' corners
/// allow with a 5 % margin in the frame (aspect = width / height).
Camera framingCamera(const Box& bounds, double aspect, double azimuthDeg = 35.0,
                     double elevationDeg = 20.0);

/// "auto" (a three-quarter view) or "turntable:ANGLE" (the same view turned
/// ANGLE degrees about the vertical axis).  InputError otherwise.
Camera parseCamera(const std::string& spec, const Box& bounds, double aspect);

/// `cam` orbited about its target: turned `azimuthDeg` about the vertical
/// axis, then raised `elevationDeg` (the result kept within 85 degrees of
/// the horizon); the distance to the target and the field of view kept.
Camera orbitCamera(const Camera& cam, double azimuthDeg, double elevationDeg);

/// A camera's orthonormal frame for an image size: rays without recomputing it.
struct CameraFrame {
    CameraFrame(const Camera& cam, int width, int height);
    /// The world-space ray through image position (px, py) (pixels, y down).
    void ray(double px, double py, glm::dvec3& origin, glm::dvec3& direction) const;
    glm::dvec3 eye, w, u, v;
    double tanY;
    int width, height;
};

/// The world-space ray through image position (px, py) (pixels, y down).
void cameraRay(const Camera& cam, int width, int height, double px, double py, glm::dvec3& origin,
               glm::dvec3& direction);

/// Linear colour of a surface point with unit normal n and albedo, seen along
/// `dir`: a key light and a sky; the background for rays that miss.
glm::vec3 shadeSurface(const glm::vec3& n, const glm::vec3& albedo);
glm::vec3 shadeBackground(const glm::dvec3& dir);

/// A ray, and what it hit: distance, unit normal, albedo.
struct TraceRay {
    glm::dvec3 origin, direction;
    double tmin = 0.0, tmax = std::numeric_limits<double>::infinity();  ///< CpuMarcher's only
};
struct TraceHit {
    bool hit = false;
    double t = 0.0;
    glm::dvec3 position{0.0};  ///< world space (CpuMarcher's only)
    glm::vec3 normal{0.0f}, albedo{0.0f};
};
/// Traces a batch of rays (a row's samples): hits[i] for rays[i].
using BatchTracer =
    std::function<void(const std::vector<TraceRay>& rays, std::vector<TraceHit>& hits)>;

/// The albedo of a surface without a colour grid.
inline const glm::vec3 kBarkAlbedo{0.60f, 0.50f, 0.40f};

/// Renders with one tracer called on batches of about `raysPerBatch` rays
/// (whole rows), rays made and shaded on all threads around each call: for
/// tracers that use every core themselves (OpenCL).
RenderImage renderBatches(const Camera& camera, int width, int height, int spp,
                          const BatchTracer& trace, size_t raysPerBatch = size_t(1) << 20);

/// OpenVDB's LevelSetRayIntersector on a level set (hierarchical DDA to the
/// zero crossing, then refined on the trilinear interpolant), colour from
/// `color` (Cd) when given: the CPU march, and the reference of the OpenCL one.
class CpuMarcher {
public:
    CpuMarcher(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color);
    ~CpuMarcher();
    CpuMarcher(const CpuMarcher&) = delete;
    CpuMarcher& operator=(const CpuMarcher&) = delete;
    /// A tracer for one thread at a time (it holds accessors).
    BatchTracer tracer() const;
    /// On all threads, a row at a time.
    RenderImage render(const Camera& camera, int width, int height, int spp) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// InputError, before any work, unless a picture of `width` x `height` at
/// `spp` samples a pixel is one the renderers make: 1 to 16384 pixels a side
/// (--width, --height), 1 to 4096 samples (--spp), and memory for it (about
/// 128 bytes a pixel: its channels, the pixels converted for the file and the
/// encoded bytes).  What render and preview both check.
void checkPicture(int width, int height, int spp);

/// A level set's active tiles above its leaves (another tool's file may
/// hold its surface there) made voxels: both marches step through leaves
/// only (a band of two active tiles drew an empty picture, exit 0, sweep
/// 20).  Their voxels are bounded by memory when the file is read.
void voxelizeActiveTiles(openvdb::FloatGrid& grid);

/// Where each pixel's rays may meet a level set: within the bounding
/// spheres of the active leaves and tiles (two voxels wider each way) whose
/// projections cover the pixel, from the nearest to the farthest (world
/// units from the eye; near > far: nowhere, the rays miss); every pixel from
/// 0 to infinity where a box lies behind the eye.  CpuMarcher::render traces
/// each pixel's rays over its range only.
struct RayRanges {
    std::vector<float> near, far;  ///< a pixel each, row by row
};
RayRanges rayRanges(const openvdb::FloatGrid& surface, const Camera& camera, int width, int height);

/// CpuMarcher(surface, color).render(...): `spp` samples per pixel
/// (stratified, deterministic).
RenderImage renderLevelSetCpu(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                              const Camera& camera, int width, int height, int spp);

/// The picture of nothing: every ray misses (the sky), as the renderers
/// draw it where they miss (an empty frame of a sequence).
RenderImage renderBackground(const Camera& camera, int width, int height, int spp);

/// A level set read with its topology only, for renderLevelSetCpu: its
/// leaves decoded by `leaves` a strip of the picture's rows at a time.
struct LazySurface {
    std::unique_ptr<LazyLeaves> leaves;  ///< (none: the grid holds its values)
    /// The most leaves whose values are held at once (unless one row's
    /// leaves are more): 32768 leaves hold 64 MiB of values.
    size_t leavesAtOnce = kLeavesAtOnce;
    static constexpr size_t kLeavesAtOnce = 32768;
    struct Stats {
        size_t strips = 0, mostHeld = 0, decoded = 0;
        /// Leaves not held that a strip's rays gave values to (a lookup in
        /// a leaf without values allocates them, unset): none, or the
        /// strips missed a leaf their rays meet.  Counted only with stats.
        size_t strayLeaves = 0;
    };
    /// (when set: the strips, the most leaves held, the leaves decoded, the
    /// stray ones)
    Stats* stats = nullptr;
};

/// The same picture holding one grid at a time: every ray traced against
/// `surface` (its hits kept, a few bytes each), the level set then dropped
/// and its memory given back, then `colour(leaves)` asked for the grid the
/// hits' colours are looked up in, with the values of the leaves at
/// `leaves` (the origins the lookups read, sorted; null: none; a file's Cd,
/// those leaves decoded: readColourGrid).  With `lazy.leaves`, the level
/// set's leaves are decoded a strip of rows at a time (those whose
/// footprints reach the strip's rows, as rayRanges finds them) and dropped
/// after the last strip that needs them: the picture is the same.  What
/// `cambium render` runs: its peak is a strip's leaves and the level set's
/// topology, not the level set's and the colour's.
RenderImage renderLevelSetCpu(
    openvdb::FloatGrid::Ptr surface,
    const std::function<openvdb::Vec3fGrid::Ptr(const std::vector<openvdb::Coord>&)>& colour,
    const Camera& camera, int width, int height, int spp, LazySurface lazy = {});

/// Ray marches a level set with OpenCL (kernels/march.cl): a NanoVDB copy of
/// the grid (and of `color`, when given) made once, read through PNanoVDB.h,
/// walked with its hierarchical DDA; the zero crossing of the trilinear
/// interpolant found cell by cell and refined, as LevelSetRayIntersector
/// does.  Throws OpenCLError when no OpenCL device is usable.
class OpenCLMarcher {
public:
    OpenCLMarcher(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color);
    /// The same, dropping the grids as load(LevelSetGrids&&) does.
    explicit OpenCLMarcher(LevelSetGrids&& grids);
    ~OpenCLMarcher();
    OpenCLMarcher(const OpenCLMarcher&) = delete;
    OpenCLMarcher& operator=(const OpenCLMarcher&) = delete;
    /// Replaces the grids, keeping the context and the built kernel (the
    /// next frame of a sequence).
    void load(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color);
    /// The same, dropping each of `grids` once its NanoVDB copy is made (the
    /// march reads only those): a render holds the level set twice at most.
    void load(LevelSetGrids&& grids);
    /// hits[i] for rays[i] (world space, unit directions).
    void trace(const std::vector<TraceRay>& rays, std::vector<TraceHit>& hits) const;
    RenderImage render(const Camera& camera, int width, int height, int spp) const;
    /// Bytes of the NanoVDB copies.
    size_t gridBytes() const;
    /// "Portable Computing Language: cpu-..." (platform and device).
    std::string deviceName() const;

private:
    void build();
    void warmUp();
    /// NanoVDB copies of the grids, calling `converted` after each.
    void convert(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                 const std::function<void(bool colour)>& converted);
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// OpenCLMarcher(surface, color).render(...).
RenderImage renderLevelSetOpenCL(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                                 const Camera& camera, int width, int height, int spp);

/// A triangle mesh in an Embree 3 scene (its BVH built once), rendered as
/// the level set is (a stream of a row's rays at a time, rtcIntersect1M),
/// normals and colours interpolated from the vertices: the independent check
/// of the level-set march.  The mesh must outlive it.
class EmbreeMesh {
public:
    explicit EmbreeMesh(const TriangleMesh& mesh);
    ~EmbreeMesh();
    EmbreeMesh(const EmbreeMesh&) = delete;
    EmbreeMesh& operator=(const EmbreeMesh&) = delete;
    RenderImage render(const Camera& camera, int width, int height, int spp) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// EmbreeMesh(mesh).render(...).
RenderImage renderMeshEmbree(const TriangleMesh& mesh, const Camera& camera, int width, int height,
                             int spp);

/// World-space bounds of a mesh's points.
Box meshBounds(const TriangleMesh& mesh);

/// The world-space bounds of the active voxels of level set `grid` in a .vdb
/// file: from the statistics metadata written with it (no voxels read), else
/// from the grid read whole.
Box storedActiveBounds(const std::string& path, const std::string& grid);

/// World-space bounds of a grid's active voxels.
Box activeWorldBounds(const openvdb::GridBase& grid);

}  // namespace cambium
