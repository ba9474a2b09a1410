// cambium — axis-aligned boxes for supports and bounds.
#pragma once

#include <glm/glm.hpp>

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

}  // namespace cambium
