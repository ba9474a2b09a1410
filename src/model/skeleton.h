// cambium — tree skeletons: internodes with end points, radii and parents.
#pragma once

#include "blobtree/blobtree.h"

#include <glm/glm.hpp>

#include <optional>
#include <string>
#include <vector>

namespace cambium {

struct Internode {
    long long id = 0;
    long long parent = -1;  ///< -1 for a root
    glm::dvec3 p0{0.0}, p1{0.0};
    double r0 = 0.0, r1 = 0.0;  ///< surface radius at p0 and at p1
    int order = 0;              ///< branch order (0: the trunk's axis)
    long long module =
        -1;  ///< index of the module (L-systems) or branch (growth) that made it, -1 for none
    bool cut = false;  ///< pruned: ends in a saw cut through p1, across its axis
    /// Years since it began to grow (growth models); negative when unknown.
    /// Junction ages drive the bark ridges (TreeBuildOptions::ridgeYears).
    double age = -1.0;
    /// Its own colour (an L-system's colour index), else the builder's bark.
    std::optional<glm::dvec3> colour;
};

/// Where a lateral organ was lost (shed): a stub from `base` (on the parent
/// axis) towards `tip` (a little beyond the bark) of radius `radius`, with a
/// negative field at its tip that presses a scar into the bark.
struct Scar {
    glm::dvec3 base{0.0}, tip{0.0};
    double radius = 0.0;
    long long parent = -1;  ///< the internode it sits on
    double weight = 1.0;    ///< fraction of the scar's full depth (0: the stub alone)
};

/// Organs and marks that are not internodes, each one primitive.
struct Organ {
    /// Leaf: a flat ellipsoid from p0 (the blade's base) to p1 (its tip),
    /// `radius` wide on each side, `thickness` thick on each side, its face
    /// across `normal`.  Bud: a sphere of `radius` at p0.  Ring: a bud scale
    /// scar, a band from p0 to p1 of `radius` summed with the branch at
    /// `weight`.
    enum class Kind { Leaf, Bud, Ring } kind = Kind::Bud;
    glm::dvec3 p0{0.0}, p1{0.0}, normal{0.0, 1.0, 0.0};
    double radius = 0.0, thickness = 0.0, weight = 1.0;
    glm::dvec3 colour{0.5};
};

struct Skeleton {
    std::vector<Internode> internodes;
    std::vector<Scar> scars;
    std::vector<Organ> organs;
};

/// Reads the text format of ../shared/bench/gen_skeleton.py (docs/skeleton-format.md):
/// one internode per line, `id parent x0 y0 z0 x1 y1 z1 r0 r1`; blank lines and
/// lines starting with # are ignored.  Throws InputError naming the file, line
/// and field of anything malformed.
Skeleton parseSkeleton(const std::string& text, const std::string& source);
Skeleton loadSkeleton(const std::string& path);

/// The columns of the text format, for a header comment.
inline constexpr const char* kSkeletonColumns = "id parent x0 y0 z0 x1 y1 z1 r0 r1";
/// One internode as a line of the text format (no newline; numbers in their
/// shortest form that reads back to the same double): what parseSkeleton reads.
std::string formatInternode(const Internode& internode);

/// The simplest BlobTree of a skeleton: a summation blend of one cone per
/// internode (the benchmark field).
BlobTree skeletonToBlend(const Skeleton& skeleton, double threshold = 0.5);

}  // namespace cambium
