// cambium — a skeleton of internodes to a BlobTree with the papers' junction
// rules (papers 001 and 003, section 3): cones per internode, basal internodes
// shortened against bulges, PCM between the branches of a junction, bent
// internodes.
#pragma once

#include "blobtree/blobtree.h"
#include "model/skeleton.h"

namespace cambium {

/// Bark furrows on grown trees (docs/bark.md): every cone internode of known
/// age gets a multi-scale furrow pattern fixed to its wood (arc length along
/// its branch, angle from a reference carried along it), as deep as
/// min(depth r, maxDepth, 0.28 r) times a ramp of its age from startAge
/// (none) to fullAge (all), so young shoots stay smooth.
struct BarkDetail {
    double depth = 0.0;      ///< furrow depth over the radius; 0: none (today's smooth bark)
    double maxDepth = 0.02;  ///< the deepest furrow (world units)
    double startAge = 2.0, fullAge = 10.0;  ///< years
    double around = 9.0;  ///< furrows around a stem at the coarsest octave (whole)
    double along = 4.0;   ///< meander frequency along the stem, radians per unit length
    uint64_t seed = 1;    ///< the branches' phases

    /// The furrow depth of a stem of radius r and age `age` (years).
    double depthAt(double r, double age) const;
};

struct TreeBuildOptions {
    /// Pcm: F_J = PCM(F_B0, ..., F_Bm-1) + F_A (eq. 4-5), branches moved off
    /// the branching point by delta_Bi = r_A - r_i (eq. 6) and the basal
    /// internode shortened by delta_A = 2.75 max(r_i) - r_A (eq. 7): ridges
    /// between branches, collars on small ones.  Smooth: plain summation, the
    /// basal internode shortened by delta_A = 1.75 max(r_Bi,top) (eq. 3).
    /// A single continuation is always summed with delta_A = 1.75 r_B,top.
    enum class Junction { Pcm, Smooth } junction = Junction::Pcm;
    double pcmWidth = 0.2;        ///< PCM propagation width (field units)
    double pcmAttenuation = 2.0;  ///< PCM bulge attenuation exponent
    double ridgeDarken = 0.5;     ///< how much the PCM ridge darkens the bark, in [0, 1]
    /// Endpoint-preserving bend of every internode that leaves its basal
    /// internode's axis, in their plane, first away from that axis and back
    /// (paper 003 section 3.6), radians; 0: straight.
    double bend = 0.0;
    /// Paper 002's primitives.  Cone: papers 001/003.  Convolution: every
    /// internode a convolution segment with linearly varying density, summed
    /// without the rules (connected segments blend without bulges: a polyline).
    /// Mixed: the main axis (each parent's thickest child continues it) in
    /// cones with the rules, the laterals in convolution segments, the two
    /// kinds joined by better blending (eq. 6, cut-off `betterBlendK`).
    enum class Primitives { Cone, Convolution, Mixed } primitives = Primitives::Cone;
    double betterBlendK = 0.3;
    /// Scars of shed organs (paper 001 section 3.4): the weight of the
    /// negative sphere at the stub's tip and its radius over the stub's.
    double scarWeight = -1.25;
    double scarRadius = 1.5;
    /// Regrowth over saw cuts (paper 002 section 3.4), in [0, 1]: a short
    /// convolution segment over each cut end, whose tip is no spherical cap:
    /// a callus that swells the branch below the cut (16 % at 0.5, 24 % at 1)
    /// and rises over the cut face as it grows.  0: a bare cut.
    double regrowth = 0.0;
    /// Bark ridges over time (paper 000 section 3.2): with ridgeYears > 0
    /// and internode ages known, a junction's branches combine by generalized
    /// bounded blending, Fg = Fb PCM + (1 - Fb) blend, where the bounding field
    /// Fb is a Wyvill segment along the thinnest branch's axis from the
    /// branching point through its parent's bark (Fb = 1 on that axis), whose
    /// support grows from 0 to `ridgeRadius` times the thinnest branch's radius
    /// as the junction's youngest branch ages from 0 to ridgeYears (smoothly):
    /// a young junction blends, an old one has its PCM ridge, darkened by Fb.
    /// 0: PCM at once.
    double ridgeYears = 0.0;
    double ridgeRadius = 4.0;
    /// Bark colour (linear RGB) of every internode, into the Cd grid; scars
    /// are darker (the wood under the bark).
    glm::dvec3 bark{0.36, 0.28, 0.22};
    BarkDetail barkDetail;
    /// A photo whose colour histogram colours the bark when baked (paper 002
    /// section 3.5; bake/bark_photo.h), drawn coherently or at random.
    std::string barkPhoto;
    bool barkCoherent = true;
};

/// The BlobTree of a skeleton.  A pruned internode (`cut`) is cut flat
/// through its end across its axis (CSG difference).  Each internode appears once: in the PCM
/// group of the junction it branches from when that junction has several
/// branches, else directly in the top-level summation, so the tree's depth
/// stays three or four however large the skeleton.  An internode short for
/// its radii loses at most half its length to the rules.  InputError (naming
/// the internode) for one whose ends coincide.
BlobTree buildTree(const Skeleton& skeleton, const TreeBuildOptions& options = {});

/// InputError unless the options are in range (buildTree checks them; the
/// CLI calls it before any work).
void checkTreeBuildOptions(const TreeBuildOptions& options);

/// How much a basal internode is shortened at its tip (eq. 3 and 7), given
/// its radius at the tip and its children's radii at their bases and tips.
double basalShortening(const TreeBuildOptions& options, double rA,
                       const std::vector<double>& childBaseRadii,
                       const std::vector<double>& childTipRadii);

}  // namespace cambium
