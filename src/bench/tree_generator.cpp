// cambium — the benchmark skeleton generator.
#include "bench/tree_generator.h"

#include "model/skeleton.h"

#include "core/error.h"
#include "core/math.h"
#include "core/random.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <deque>
#include <iterator>

namespace cambium {

namespace {

// The output must equal the original generator's to the last printed digit.
// An ulp of difference in a direction moves every descendant's position, and
// now and then that turns a sixth decimal, so each expression below keeps the
// original's operands, order and grouping (a + b + c is (a + b) + c; no
// algebraic shortcuts such as glm::dot or glm::cross, whose order is theirs).
// For the same reason this file must not be compiled with multiply-add
// contraction (-ffp-contract=off where -march enables FMA).

struct Vec3 {
    double x, y, z;
};

/// v scaled to unit length; a zero vector comes back unchanged.
Vec3 normalized(const Vec3& v)
{
    // The squares summed left to right from zero, as the original does.
    double squares = 0.0;
    squares += v.x * v.x;
    squares += v.y * v.y;
    squares += v.z * v.z;
    double length = std::sqrt(squares);
    if (length == 0.0)
        length = 1.0;
    return {v.x / length, v.y / length, v.z / length};
}

/// A unit vector perpendicular to v: v crossed with whichever of x and y is
/// further from parallel to it.
Vec3 perpendicular(const Vec3& v)
{
    const Vec3 a = std::abs(v.x) < 0.9 ? Vec3{1.0, 0.0, 0.0} : Vec3{0.0, 1.0, 0.0};
    return normalized({v.y * a.z - v.z * a.y, v.z * a.x - v.x * a.z, v.x * a.y - v.y * a.x});
}

/// v rotated by `angle` radians about the unit `axis` (Rodrigues), term by
/// term in the original's order (math.h's rotateAbout groups differently).
Vec3 rotated(const Vec3& v, const Vec3& axis, double angle)
{
    const double c = std::cos(angle), s = std::sin(angle);
    const double d = axis.x * v.x + axis.y * v.y + axis.z * v.z;
    const double cx = axis.y * v.z - axis.z * v.y;
    const double cy = axis.z * v.x - axis.x * v.z;
    const double cz = axis.x * v.y - axis.y * v.x;
    return {v.x * c + cx * s + axis.x * d * (1.0 - c), v.y * c + cy * s + axis.y * d * (1.0 - c),
            v.z * c + cz * s + axis.z * d * (1.0 - c)};
}

/// An internode waiting to grow: where it starts, roughly where it points,
/// its base radius and length, its branch order and its phyllotaxis phase.
struct Bud {
    int parent;
    Vec3 p0, direction;
    double r0, length;
    int order;
    double phase;  ///< degrees
};

}  // namespace

std::string generateBenchSkeleton(const TreeGeneratorOptions& options)
{
    if (options.laterals < 1)
        throw InputError(fmt::format("the tree generator needs at least 1 lateral per node, got {}",
                                     options.laterals));

    // Python seeds with the magnitude of a negative seed; every int's fits 32 bits.
    Mt19937 rng;
    rng.seedPython(uint32_t(std::llabs(static_cast<long long>(options.seed))));

    // The apical child keeps this share of the parent's cross-section (pipe
    // model); the laterals split the rest.  Radii stop shrinking at 12 mm.
    const double share = 0.55;
    const double minRadius = 0.012;

    fmt::memory_buffer out;
    fmt::format_to(std::back_inserter(out), "# {}\n", kSkeletonColumns);

    // Breadth first, so a smaller tree is the first levels of a larger one.
    std::deque<Bud> queue;
    queue.push_back({-1, {0.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, 0.25, options.height / 12.0, 0, 0.0});
    for (int id = 0; !queue.empty() && id < options.internodes; ++id) {
        const Bud bud = queue.front();
        queue.pop_front();

        // A random wobble, then a slight pull upwards (phototropism).  The
        // three draws are taken x, y, z in turn.
        const double jx = rng.uniform(-0.08, 0.08);
        const double jy = rng.uniform(-0.08, 0.08);
        const double jz = rng.uniform(-0.08, 0.08);
        Vec3 d = normalized({bud.direction.x + jx, bud.direction.y + jy, bud.direction.z + jz});
        d = normalized({d.x, d.y + 0.05, d.z});
        const Vec3 p1{bud.p0.x + bud.length * d.x, bud.p0.y + bud.length * d.y,
                      bud.p0.z + bud.length * d.z};

        const int lateralCount = bud.order < 6 ? options.laterals : 1;
        const double apicalRadius = bud.r0 > 0.016 ? bud.r0 * std::sqrt(share) : bud.r0;
        const double r1 = std::max(apicalRadius, minRadius);
        fmt::format_to(std::back_inserter(out),
                       "{} {} {:.6f} {:.6f} {:.6f} {:.6f} {:.6f} {:.6f} {:.6f} {:.6f}\n", id,
                       bud.parent, bud.p0.x, bud.p0.y, bud.p0.z, p1.x, p1.y, p1.z, bud.r0, r1);

        queue.push_back({id, p1, d, r1, bud.length * 0.92, bud.order, bud.phase + 137.5});

        // Laterals around the stem at the golden angle, each tilted away from
        // the stem by the branching angle give or take ten degrees.
        const Vec3 axis = perpendicular(d);
        const double lateralRadius =
            std::max(bud.r0 * std::sqrt((1.0 - share) / double(lateralCount)), minRadius);
        for (int k = 0; k < lateralCount; ++k) {
            const double around = (bud.phase + 137.5 * double(k + 1)) * kDegree;
            const Vec3 side = rotated(axis, d, around);
            const double tilt = (options.angle + rng.uniform(-10.0, 10.0)) * kDegree;
            const Vec3 lateral = normalized({std::cos(tilt) * d.x + std::sin(tilt) * side.x,
                                             std::cos(tilt) * d.y + std::sin(tilt) * side.y,
                                             std::cos(tilt) * d.z + std::sin(tilt) * side.z});
            queue.push_back(
                {id, p1, lateral, lateralRadius, bud.length * 0.7, bud.order + 1, bud.phase});
        }
    }
    return fmt::to_string(out);
}

}  // namespace cambium
