// cambium — polygonising a baked level set and writing the mesh.
#include "use/mesh.h"

#include "core/error.h"
#include "core/files.h"
#include "core/frames.h"
#include "io/vdb.h"
#include "use/world_sampler.h"
#include "core/clock.h"

#include <fmt/format.h>
#include <openvdb/tools/VolumeToMesh.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <cstdio>
#include <iterator>
#include <ostream>
#include <memory>

namespace cambium {

TriangleMesh meshLevelSet(const openvdb::FloatGrid& surface, const openvdb::Vec3fGrid* color,
                          double adaptivity)
{
    TriangleMesh mesh;
    std::vector<openvdb::Vec3I> tris;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(surface, mesh.points, tris, quads, 0.0,
                                 std::clamp(adaptivity, 0.0, 1.0));
    // volumeToMesh winds its polygons clockwise seen from outside a level set
    // (whose inside is negative): reversed here.
    mesh.triangles.reserve(tris.size() + 2 * quads.size());
    for (const auto& t : tris)
        mesh.triangles.push_back({t[2], t[1], t[0]});
    for (const auto& q : quads) {
        // The shorter diagonal gives the better-shaped pair.
        const float d02 = (mesh.points[q[0]] - mesh.points[q[2]]).lengthSqr();
        const float d13 = (mesh.points[q[1]] - mesh.points[q[3]]).lengthSqr();
        if (d02 <= d13) {
            mesh.triangles.push_back({q[2], q[1], q[0]});
            mesh.triangles.push_back({q[3], q[2], q[0]});
        } else {
            mesh.triangles.push_back({q[3], q[1], q[0]});
            mesh.triangles.push_back({q[3], q[2], q[1]});
        }
    }
    // Normals: central differences of the trilinear level set, half a voxel
    // either side; colours: trilinear Cd.
    const double h = surface.voxelSize()[0];
    const size_t n = mesh.points.size();
    mesh.normals.resize(n);
    if (color)
        mesh.colors.resize(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        const WorldSampler<openvdb::FloatGrid> d(surface);
        std::unique_ptr<WorldSampler<openvdb::Vec3fGrid>> c;
        if (color)
            c = std::make_unique<WorldSampler<openvdb::Vec3fGrid>>(*color);
        for (size_t i = r.begin(); i < r.end(); ++i) {
            const openvdb::Vec3d p = mesh.points[i];
            openvdb::Vec3d g;
            for (int k = 0; k < 3; ++k) {
                openvdb::Vec3d e(0.0);
                e[k] = 0.5 * h;
                g[k] = double(d(p + e)) - double(d(p - e));
            }
            const double len = g.length();
            mesh.normals[i] = len > 0.0 ? openvdb::Vec3s(g / len) : openvdb::Vec3s(0.0f);
            if (c)
                mesh.colors[i] = (*c)(p);
        }
    });
    return mesh;
}

double meshArea(const TriangleMesh& m)
{
    double a = 0.0;
    for (const auto& t : m.triangles) {
        const openvdb::Vec3d p0 = m.points[t[0]], p1 = m.points[t[1]], p2 = m.points[t[2]];
        a += 0.5 * (p1 - p0).cross(p2 - p0).length();
    }
    return a;
}

double meshVolume(const TriangleMesh& m)
{
    double v = 0.0;
    for (const auto& t : m.triangles) {
        const openvdb::Vec3d p0 = m.points[t[0]], p1 = m.points[t[1]], p2 = m.points[t[2]];
        v += p0.dot(p1.cross(p2)) / 6.0;
    }
    return v;
}

}  // namespace cambium
