// cambium — axis-aligned boxes for supports and bounds.
#pragma once

#include <glm/glm.hpp>

#include <algorithm>
#include <array>
#include <limits>

namespace cambium {

/// An axis-aligned box; default-constructed it is empty (lo > hi).
struct Box {
    glm::dvec3 lo{std::numeric_limits<double>::infinity()};
    glm::dvec3 hi{-std::numeric_limits<double>::infinity()};

    Box() = default;
    Box(const glm::dvec3& l, const glm::dvec3& h) : lo(l), hi(h) {}

    /// The box of all points within distance r of p.
    static Box around(const glm::dvec3& p, double r) { return {p - r, p + r}; }

    bool empty() const { return !(lo.x <= hi.x && lo.y <= hi.y && lo.z <= hi.z); }
    glm::dvec3 size() const { return empty() ? glm::dvec3(0.0) : hi - lo; }
    glm::dvec3 center() const { return 0.5 * (lo + hi); }
    bool contains(const glm::dvec3& p) const
    {
        return p.x >= lo.x && p.y >= lo.y && p.z >= lo.z && p.x <= hi.x && p.y <= hi.y &&
               p.z <= hi.z;
    }

    void expand(const glm::dvec3& p)
    {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    void expand(const Box& b)
    {
        if (!b.empty()) {
            lo = glm::min(lo, b.lo);
            hi = glm::max(hi, b.hi);
        }
    }
    /// Grows the box by r on every side (nothing happens to an empty box).
    Box padded(double r) const { return empty() ? Box() : Box(lo - r, hi + r); }
    Box intersected(const Box& b) const
    {
        Box r(glm::max(lo, b.lo), glm::min(hi, b.hi));
        return r.empty() ? Box() : r;
    }
    /// The eight corners (only meaningful for a non-empty box).
    std::array<glm::dvec3, 8> corners() const
    {
        std::array<glm::dvec3, 8> c;
        for (int i = 0; i < 8; ++i)
            c[i] = glm::dvec3(i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
        return c;
    }
};

/// Range of heights along the unit axis a from o, and the largest distance
/// from that axis, over a box's corners (distance to a line is convex, so the
/// corners bound it over the whole box).
inline void axialExtent(const Box& box, const glm::dvec3& o, const glm::dvec3& a, double& hmin,
                        double& hmax, double& rmax)
{
    hmin = std::numeric_limits<double>::infinity();
    hmax = -hmin;
    rmax = 0.0;
    for (const auto& c : box.corners()) {
        const glm::dvec3 d = c - o;
        const double h = glm::dot(d, a);
        hmin = std::min(hmin, h);
        hmax = std::max(hmax, h);
        rmax = std::max(rmax, glm::length(d - h * a));
    }
}

/// The box of the image of a box under the affine map m (row-major 3x4).
inline Box affineImage(const Box& box, const double m[12])
{
    Box out;
    for (const auto& c : box.corners())
        out.expand(glm::dvec3(m[0] * c.x + m[1] * c.y + m[2] * c.z + m[3],
                              m[4] * c.x + m[5] * c.y + m[6] * c.z + m[7],
                              m[8] * c.x + m[9] * c.y + m[10] * c.z + m[11]));
    return out;
}

/// The box of a cylinder of radius r about the unit axis a, from a0 to a1.
inline Box cylinderBox(const glm::dvec3& a0, const glm::dvec3& a1, const glm::dvec3& a, double r)
{
    Box box;
    box.expand(a0);
    box.expand(a1);
    const glm::dvec3 e = r * glm::sqrt(glm::max(glm::dvec3(0.0), 1.0 - a * a));
    return Box(box.lo - e, box.hi + e);
}

}  // namespace cambium
