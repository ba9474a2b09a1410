// cambium — bark colour from a photograph (paper 002, section 3.5): the
// photo's colour histogram as a probability distribution, and the baked
// bark's colours drawn from it, at random (the paper) or coherently (a
// smooth noise of the bark's own coordinates through the inverse CDF).
#pragma once

#include "bake/levelset.h"
#include "blobtree/blobtree.h"

#include <glm/glm.hpp>

#include <string>
#include <vector>

namespace cambium {

/// A photo's colours: RGB bins of 1/16 per channel (linear), each with its
/// share of the pixels and their mean colour, in order of luminance; the
/// cumulative shares make the inverse CDF.
class ColourHistogram {
public:
    static constexpr int kLevels = 16;  ///< bins per channel

    /// InputError naming the file for a photo that cannot be read.
    static ColourHistogram fromPhoto(const std::string& path);
    /// From linear RGB pixels (3 floats each).
    static ColourHistogram fromPixels(const std::vector<float>& rgb);

    size_t bins() const { return colour_.size(); }
    const glm::dvec3& colour(size_t bin) const { return colour_[bin]; }
    double share(size_t bin) const { return share_[bin]; }
    /// The bin of u in [0, 1): the first whose cumulative share exceeds u.
    size_t bin(double u) const;
    /// The bin a colour falls in (its index here), or bins() if the photo has none there.
    size_t binOf(const glm::dvec3& rgb) const;

private:
    std::vector<glm::dvec3> colour_;
    std::vector<double> share_, cumulative_;
    std::vector<int> key_;  ///< the quantised colour of each bin, for binOf
};

enum class BarkColouring { Random, Coherent };

/// Paper 002's draw for one voxel: a uniform number from its coordinates.
double randomDraw(const openvdb::Coord& voxel, uint64_t seed);

/// The coherent draw's noise at bark coordinates (s along the branch, theta
/// around it), mapped through its own measured distribution to a uniform
/// number in [0, 1): smooth in s and theta, periodic in theta.
double coherentDraw(double s, double theta, uint64_t seed);

/// Whether colour `c` is the bark colour `bark` times a shade k > 0.05
/// (within 1 % of |bark|): what colourBarkFromPhoto recolours.
bool isBarkShade(const glm::dvec3& c, const glm::dvec3& bark);

/// Whether any cone or segment of `tree` (weight > 0) is of the bark
/// colour: else a photo would recolour nothing.
bool hasBarkToPaint(const BlobTree& tree, const glm::dvec3& bark);

/// Recolours the bark of baked grids: every active Cd voxel within 1.5
/// voxels of the surface whose colour is the bark colour (`bark`) times a
/// shade k (scars and ridges are darker) becomes k times a colour drawn from
/// the histogram; other colours (leaves) stay.  The coherent draw takes each
/// voxel's bark coordinates from the nearest cone of `tree` (its
/// BarkParams: the tree builder's coordinates; cones without any get
/// coordinates of their own axis).  Returns the voxels recoloured.
size_t colourBarkFromPhoto(BakedGrids& grids, const BlobTree& tree, const ColourHistogram& photo,
                           BarkColouring mode, const glm::dvec3& bark, uint64_t seed = 1);

}  // namespace cambium
