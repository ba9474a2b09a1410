// cambium — built-in base shapes.
#include "shape/base_shapes.h"

#include "core/math.h"

#include <array>
#include <cmath>
#include <map>

namespace cambium {

namespace {

void addQuad(ControlMesh& m, int a, int b, int c, int d)
{
    m.faceSizes.push_back(4);
    m.faceVerts.insert(m.faceVerts.end(), {a, b, c, d});
}

void addTriangle(ControlMesh& m, int a, int b, int c)
{
    m.faceSizes.push_back(3);
    m.faceVerts.insert(m.faceVerts.end(), {a, b, c});
}

/// The cube [-1, 1]^3 with each face a grid of n x n quads, points shared
/// along the edges, faces outwards.
BaseShape gridCube(int n)
{
    BaseShape s;
    std::map<std::array<int, 3>, int> index;  // integer lattice point -> point
    auto point = [&](int x, int y, int z) {
        const std::array<int, 3> key{x, y, z};
        const auto it = index.find(key);
        if (it != index.end())
            return it->second;
        const int i = int(s.mesh.points.size());
        s.mesh.points.push_back(glm::dvec3(x, y, z) * (2.0 / n) - glm::dvec3(1.0));
        index[key] = i;
        return i;
    };
    // Each face: its normal axis, side, and two in-plane axes ordered so the
    // quads run counter-clockwise seen from outside.
    for (int axis = 0; axis < 3; ++axis)
        for (int side = 0; side < 2; ++side) {
            int u = (axis + 1) % 3, v = (axis + 2) % 3;
            if (side == 0)
                std::swap(u, v);
            for (int i = 0; i < n; ++i)
                for (int j = 0; j < n; ++j) {
                    auto at = [&](int a, int b) {
                        int c[3];
                        c[axis] = side * n;
                        c[u] = a;
                        c[v] = b;
                        return point(c[0], c[1], c[2]);
                    };
                    addQuad(s.mesh, at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                }
        }
    return s;
}

}  // namespace

BaseShape cubeBase(double size)
{
    BaseShape s;
    const double a = size / 2;
    for (int i = 0; i < 8; ++i)  // bit 0: x, bit 1: y, bit 2: z
        s.mesh.points.push_back({i & 1 ? a : -a, i & 2 ? a : -a, i & 4 ? a : -a});
    // Counter-clockwise seen from outside.
    addQuad(s.mesh, 0, 2, 3, 1);  // z-
    addQuad(s.mesh, 4, 5, 7, 6);  // z+
    addQuad(s.mesh, 0, 1, 5, 4);  // y-
    addQuad(s.mesh, 2, 6, 7, 3);  // y+
    addQuad(s.mesh, 0, 4, 6, 2);  // x-
    addQuad(s.mesh, 1, 3, 7, 5);  // x+
    return s;
}

BaseShape sphereBase(double radius, int cells)
{
    BaseShape s = cells <= 1 ? cubeBase(2.0) : gridCube(cells);
    for (glm::dvec3& p : s.mesh.points)
        p = radius * glm::normalize(p);
    s.target = [radius](const glm::dvec3& q, const Frame& f, double) {
        const double len = glm::length(q);
        return len > 0.0 ? q * (radius / len) : radius * f.n;
    };
    return s;
}

BaseShape torusBase(double major, double minor, int around, int tube)
{
    BaseShape s;
    for (int i = 0; i < around; ++i) {
        const double u = 2 * kPi * i / around;
        for (int j = 0; j < tube; ++j) {
            const double v = 2 * kPi * j / tube;
            const double rho = major + minor * std::cos(v);
            s.mesh.points.push_back({rho * std::cos(u), rho * std::sin(u), minor * std::sin(v)});
        }
    }
    auto at = [&](int i, int j) { return (i % around) * tube + (j % tube); };
    for (int i = 0; i < around; ++i)
        for (int j = 0; j < tube; ++j)
            addQuad(s.mesh, at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
    s.target = [major, minor](const glm::dvec3& q, const Frame& f, double) {
        const glm::dvec2 xy(q.x, q.y);
        const double rxy = glm::length(xy);
        if (!(rxy > 0.0))
            return q + f.n * 0.0;  // on the axis: no nearest point; keep it
        const glm::dvec3 c(xy.x * major / rxy, xy.y * major / rxy, 0.0);
        const glm::dvec3 d = q - c;
        const double len = glm::length(d);
        return len > 0.0 ? c + d * (minor / len) : c + f.n * minor;
    };
    return s;
}

BaseShape planeBase(double size, int cells)
{
    BaseShape s;
    const int n = cells + 1;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            s.mesh.points.push_back(
                {size * (double(i) / cells - 0.5), size * (double(j) / cells - 0.5), 0.0});
    for (int j = 0; j < cells; ++j)
        for (int i = 0; i < cells; ++i)
            addQuad(s.mesh, j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i);
    return s;
}

double fuseProfile(double t, int terms)
{
    double sum = 0.0, scale = 1.0;
    for (int i = 0; i < terms; ++i, scale *= 2.0)
        sum += std::sin(scale * t) / scale;
    return std::sin(sum);
}

BaseShape fuseBase(double length, double radius, int terms, int around, int rings)
{
    BaseShape s;
    s.mesh.points.push_back({0.0, 0.0, 0.0});  // pole at z = 0
    for (int j = 1; j < rings; ++j) {
        const double t = kPi * j / rings;
        const double rho = radius * fuseProfile(t, terms), z = length * j / rings;
        for (int i = 0; i < around; ++i) {
            const double u = 2 * kPi * i / around;
            s.mesh.points.push_back({rho * std::cos(u), rho * std::sin(u), z});
        }
    }
    const int top = int(s.mesh.points.size());
    s.mesh.points.push_back({0.0, 0.0, length});
    auto ring = [&](int j, int i) { return 1 + (j - 1) * around + (i % around); };
    for (int i = 0; i < around; ++i)
        addTriangle(s.mesh, 0, ring(1, i + 1), ring(1, i));
    for (int j = 1; j + 1 < rings; ++j)
        for (int i = 0; i < around; ++i)
            addQuad(s.mesh, ring(j, i), ring(j, i + 1), ring(j + 1, i + 1), ring(j + 1, i));
    for (int i = 0; i < around; ++i)
        addTriangle(s.mesh, top, ring(rings - 1, i), ring(rings - 1, i + 1));
    s.target = [length, radius, terms](const glm::dvec3& q, const Frame&, double) {
        const double z = std::clamp(q.z, 0.0, length);
        const double rho = radius * fuseProfile(kPi * z / length, terms);
        const double rxy = std::hypot(q.x, q.y);
        if (!(rxy > 0.0))
            return glm::dvec3(0.0, 0.0, z);
        return glm::dvec3(q.x * rho / rxy, q.y * rho / rxy, z);
    };
    return s;
}

}  // namespace cambium
