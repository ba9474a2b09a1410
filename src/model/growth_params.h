// cambium — the parameters of the global-to-local growth model (paper 000
// section 4): a species' scalars and its graphically defined functions,
// read from a JSON file (docs/growth-format.md).
#pragma once

#include "model/curve.h"
#include "model/tree_builder.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <optional>
#include <string>

namespace cambium {

struct GrowthParameters {
    std::string name;
    std::string source;             ///< the file (or text) read, for messages
    int years = 27;                 ///< y_max: the tree's last year
    uint64_t seed = 1;              ///< stochastic orientation
    double trunkLength = 20.0;      ///< the trunk's length at y_max: l_y = trunkLength * Gh(t_y)
    double minShootLength = 0.05;   ///< l_min (eq. 5, 7)
    double maxBranchLength = 8.0;   ///< l_max (eq. 8)
    double maxShootLength = 1.0;    ///< ls_max (eq. 14)
    double minScale = 0.1;          ///< s_min: no lateral below this scale factor
    double phyllotaxis = 137.5;     ///< degrees between successive laterals
    double longestSeparation = 40;  ///< degrees between this and last year's longest laterals
    double orientationNoise = 5.0;  ///< degrees of random variation of headings
    double branchingAngle = 45.0;   ///< degrees between a lateral and its parent at its base
    double baseRadius = 0.25;       ///< trunk radius at its base at y_max
    double tipRadius = 0.004;       ///< radius of a shoot's tip
    double thickening = 0.7;        ///< secondary growth: radius exponent of the supported length
    double growingSeason =
        0.6;  ///< fraction of each year in which shoots grow and bark ages; dormant after
    double shootSpread =
        0.5;  ///< fraction of the year over which a shoot's metamers start growing, base first
    double budRadius = 0.008;  ///< a full-grown bud's radius
    double scarRing = 0.3;     ///< weight of a new bud scale scar ring (0: none)
    double scarYears = 6.0;    ///< years over which a scar ring fades
    double ridgeYears =
        8.0;  ///< years over which a junction's bark ridge forms (GBB from blend to PCM)
    double ridgeRadius =
        4.0;  ///< the ridge's bounding field reaches this many lateral radii from the junction
    double leafFall = 0.85;      ///< time of year at which leaves begin to fall (gone 0.1 later)
    double maxInternodes = 3e6;  ///< refuse parameters that grow more internodes than this
    bool leaves = true;
    glm::dvec3 bark{0.36, 0.30, 0.24};
    BarkDetail barkDetail;  ///< "bark": {"depth", ...}: furrows (none by default)
    std::string barkPhoto;  ///< "bark": {"photo"}: its colours (a path from the file's directory)
    bool barkCoherent = true;  ///< "bark": {"colouring": "coherent" | "random"}
    glm::dvec3 leaf{0.25, 0.45, 0.15};

    // The graphically defined functions of eq. 5-15 and section 4.3.
    Curve Gh;               ///< trunk length by time t_y, relative to trunkLength
    Curve Gs1;              ///< young silhouette: order-1 length / parent length by position x_y
    Curve Gs2;              ///< mature silhouette
    Curve Go1;              ///< heading (degrees) along a branch of length 0, by position
    Curve Go2;              ///< heading (degrees) along a branch of length l_max
    Curve Gbs;              ///< branch scale factor by x_max
    Curve Ga;               ///< age (years) at which a branch is lost, by its scale factor
    Curve Gm;               ///< metamers in a shoot by its relative length q = ls / ls_max
    Curve Gl;               ///< leaf size by position along the shoot
    Curve Gss;              ///< lateral scale by position along the shoot
    Curve internodeGrowth;  ///< fraction of its final length an internode has, by time within its
                            ///< year
    Curve leafGrowth;       ///< fraction of its size a leaf has, by time within its year
    Curve budGrowth;        ///< fraction of its size a bud has, by time within its year
};

/// Reads a parameter file (docs/growth-format.md).  InputError naming the
/// file and the JSON path of anything missing, unknown, of the wrong type
/// or out of range, before any work.
GrowthParameters parseGrowthParameters(const std::string& text, const std::string& source);
GrowthParameters loadGrowthParameters(const std::string& path);

/// A benchmark's `--years`: each a year the tree of `params` grows, 1 to
/// its years (year 0, before the trunk, has no tree to bake).  InputError
/// naming the year, `source` and the range.
void checkGrowthYears(const std::vector<int>& years, const GrowthParameters& params,
                      const std::string& source);

/// `t`, or the last year when it is not given.  InputError naming `source`
/// and `option` unless it lies in [0, years].
double timeOfLife(const GrowthParameters& params, std::optional<double> t,
                  const std::string& source, const std::string& option);

/// A graphically defined function of the file: its key under "curves", its
/// member, and the range its values must lie in.
struct GrowthCurve {
    const char* key;
    Curve GrowthParameters::*member;
    double lo, hi;
};
/// Every curve of a parameter file, in the order docs/growth-format.md
/// gives them.
const std::vector<GrowthCurve>& growthCurves();

/// `text` (a parameter file read from `source`) with the points of curve
/// `key` replaced by `points`, the rest of the text (comments, layout) as it
/// was.  InputError, naming `source` and the JSON path, when `text` does not
/// read or the edited text would not (a point out of range, x not
/// increasing): the edit is checked by the same reader as the file.
std::string withCurvePoints(const std::string& text, const std::string& source,
                            const std::string& key,
                            const std::vector<std::pair<double, double>>& points);

/// Whether `path` is a growth parameter file rather than a scene: a .json
/// whose top-level object has "curves".  False for anything unreadable (the
/// scene reader then names the problem).
bool isGrowthParameterFile(const std::string& path);

}  // namespace cambium
