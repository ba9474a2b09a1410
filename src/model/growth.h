// cambium — the global-to-local model of a growing tree (paper 000 section 4).
//
// The global phase (the constructor) decides, for every branch and every
// year, its length (eq. 5-7, 12), scale factor (eq. 10, 13, 15), lifespan
// (eq. 11) and shoots (eq. 14: metamers, the 137.5 degree spiral, the 40
// degree rule).  The local phase (`skeleton(t)`) draws the tree at any real
// time t in [0, years]: each metamer's internode elongates along a growth
// curve offset in time along its shoot (section 4.3), headings interpolate
// Go1 and Go2 (eq. 8-9), radii follow the supported length (secondary
// thickening), branches that are lost die back over their last year and
// leave a scar, leaves grow and fall within each year.  Year y is the time
// interval (y - 1, y]: at t = y every branch has its length l_y.  Growth
// happens in the first `growing_season` of each year; after it the tree is
// dormant (only the leaves still fall).
#pragma once

#include "blobtree/blobtree.h"
#include "model/growth_params.h"
#include "model/skeleton.h"
#include "model/tree_builder.h"

#include <map>
#include <optional>
#include <vector>

namespace cambium {

/// One year's growth increment of a branch.
struct GrowthShoot {
    int year = 0;          ///< grown over (year - 1, year]
    int firstMetamer = 0;  ///< index of its first metamer along the branch
    int metamers = 0;      ///< m (eq. 14, adjusted by the 40 degree rule)
    int planned = 0;       ///< round(Gm(q)) before the 40 degree rule
    double start = 0.0;    ///< the branch's length before it, l_{y-1}
    double length = 0.0;   ///< l_s = l_y - l_{y-1}
};

struct GrowthBranch {
    int order = 0;
    int parent = -1;        ///< branch index, -1 for the trunk
    int node = -1;          ///< the parent's metamer at whose top it grows
    double position = 0.0;  ///< x: its distance along the parent from the parent's base
    double azimuth0 = 0.0;  ///< radians: azimuth of its first metamer's lateral (phyllotaxis start)
    double azimuth = 0.0;   ///< radians: its direction around the parent's axis
    double scale = 1.0;     ///< s_b (eq. 10, 13, 15)
    int birth = 1;          ///< the year of its first shoot
    /// The year over which it is lost (it dies back, then leaves a scar);
    /// greater than the tree's years when it lives to the end.
    int lost = 0;
    std::vector<double> length;       ///< length[k]: l_{birth - 1 + k} (length[0] = 0)
    std::vector<GrowthShoot> shoots;  ///< one per year it grows, in order
    std::vector<int> laterals;        ///< branch indices of its laterals, by node
    double phase[4] = {0, 0, 0, 0};   ///< stochastic orientation (seeded)
    std::vector<double> finalRadius;  ///< each metamer's base radius at the end (or at its loss)

    /// The last year it grows.
    int lastYear() const { return birth - 1 + int(length.size()) - 1; }
    /// l_y (0 before its birth, its last length after it stops growing).
    double lengthAt(int year) const;
    int metamers() const
    {
        return shoots.empty() ? 0 : shoots.back().firstMetamer + shoots.back().metamers;
    }
};

/// The year a time falls in: year y is (y - 1, y], and t = 0 is in year 1.
int growthYear(double t);

/// Counts for `cambium growth --print-stats`.
struct GrowthStats {
    double time = 0.0;
    std::map<int, long long> branchesByOrder;  ///< living (or dying) branches
    std::map<int, long long> internodesByOrder;
    long long lostBranches = 0;  ///< shed so far (scars)
    long long leaves = 0, buds = 0, rings = 0;
    long long shoots = 0,
              shootsAdjusted = 0;  ///< grown by then; of them, moved by the 40 degree rule
    double height = 0.0;           ///< the trunk's length
};

class GrowthModel {
public:
    /// The global phase.  InputError when the parameters grow more than
    /// `maxInternodes` internodes (naming the year it happens).
    explicit GrowthModel(GrowthParameters params);

    const GrowthParameters& params() const { return p_; }
    const std::vector<GrowthBranch>& branches() const { return branches_; }

    /// The tree at time t in [0, years]: internodes (with ages and branch
    /// orders), scars of lost branches and, as organs, buds, bud scale scar
    /// rings and (when `leaves`) leaves.
    Skeleton skeleton(double t, bool leaves) const;
    GrowthStats stats(double t, bool leaves) const;
    /// The counts of skeleton(t, ...), already drawn.
    GrowthStats stats(double t, const Skeleton& skeleton) const;

    /// How the tree builder builds this species (ridges over ridge_years).
    TreeBuildOptions buildOptions() const;
    /// skeleton(t) built into a BlobTree.
    BlobTree tree(double t, bool leaves) const;

    /// The growth clock at calendar time t: it runs `growing_season` times
    /// faster within each year's growing season and stands still after it
    /// (a dormant season), so that the year's growth ends with the season.
    double growthTime(double t) const;
    /// The length of branch b at growth time t as it grows (its last length once it
    /// stops; dying back is not counted).
    double grownLength(int b, double t) const;
    /// Whether the 40 degree rule can hold for a shoot of m metamers after a
    /// shoot whose last metamer is `previous` (-1: none), its first being `first`.
    bool separationHolds(int first, int m, int previous) const;

private:
    /// Draws skeleton(t) (growth.cpp).
    class SkeletonDrawer;

    void grow();
    /// Each branch's supported length at growth time t (its own and its
    /// laterals', lost ones at the length they had).
    std::vector<double> branchSupports(double t) const;
    /// The support at each metamer's base of branch bi (index m: 0), and each
    /// metamer's length at t into `lengths`.
    std::vector<double> metamerSupports(size_t bi, double t, const std::vector<double>& support,
                                        std::vector<double>& lengths) const;
    /// Radius from supported length: tip_radius + (base_radius - tip_radius) (S /
    /// S_ref)^thickening.
    double radiusOf(double support) const;
    /// How far metamer k of shoot s is through its own growth at growth
    /// time t, in [0, 1]: the metamers start one after the other, base
    /// first, over `shoot_spread` of the season (section 4.3, figure 12).
    double organTime(const GrowthShoot& s, int k, double t) const;
    double metamerLength(const GrowthShoot& s, int k, double t) const;

    GrowthParameters p_;
    std::vector<GrowthBranch> branches_;
    double supportRef_ = 1.0;  ///< the trunk base's supported length at the last year
};

}  // namespace cambium
