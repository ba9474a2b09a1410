// cambium — the BlobTree: skeletal implicit primitives at the leaves,
// operators and warps inside (Wyvill, Galin & Guy 1999; papers 000-003).
//
// This is the authoring structure.  It is built by code (the builder methods
// below validate every parameter) or read from a JSON scene (scene_io.h), and
// evaluated directly by the reference evaluator (evaluator.h).
#pragma once

#include "core/box.h"

#include "cb_node_types.h"
#include "cb_warps.h"

#include <glm/glm.hpp>

#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace cambium {

enum class NodeType : int {
#define CB_X(ident, number, name, kind) ident = number,
    CB_NODE_TYPES(CB_X)
#undef CB_X
};

enum class NodeKind { Primitive, Operator, Warp };

/// The JSON type name ("cone", "pcm", ...).
const char* typeName(NodeType t);
NodeKind kindOf(NodeType t);
std::optional<NodeType> typeFromName(std::string_view name);
/// Every node type, in opcode order.
const std::vector<NodeType>& allNodeTypes();

/// How an n-ary operator (or one side of a GBB) combines its children's fields.
struct Combiner {
    NodeType type =
        NodeType::BLEND;       ///< BLEND, RICCI, UNION, INTERSECTION, DIFFERENCE, PCM, BETTER_BLEND
    double n = 2.0;            ///< ricci exponent, >= 1
    double width = 0.25;       ///< pcm propagation width in field units, in (0, T]
    double attenuation = 2.0;  ///< pcm bulge attenuation exponent, > 1
    double k = 0.3;            ///< better_blend cut-off, in [0, T)
    double darken = 0.0;  ///< pcm: how much the ridge darkens the colour, in [0, 1] (fully where
                          ///< |deformation| >= width / 10)
};

/// Bark furrows on a cone (kernels/cb_primitives.h, cb_bark_cone_field):
/// its surface radius r becomes r - A P(s, theta, r) for the bark's own
/// coordinates; none while both depths are zero (a plain cone).
struct BarkParams {
    double depth0 = 0.0, depth1 = 0.0;    ///< A at p0 and at p1 (world units)
    glm::dvec3 reference{1.0, 0.0, 0.0};  ///< unit, across the axis: theta = 0
    double s0 = 0.0;                      ///< arc length of p0 along its branch
    double around = 8.0;  ///< furrows around at the coarsest octave (a whole number)
    double along = 10.0;  ///< meander frequency along the stem, radians per unit length
    double phase = 0.0;   ///< the branch's own phases
    bool active() const { return depth0 > 0.0 || depth1 > 0.0; }
};

/// How the bark looks when baked (bake/bark_photo.h): a photo whose colour
/// histogram recolours the primitives of `color` (the bark's), at random or
/// coherently.  No photo: the primitives' colours as they are.
struct BarkLook {
    std::string photo;
    glm::dvec3 color{0.36, 0.28, 0.22};
    bool coherent = true;
};

/// The colourings' names in files and options: "coherent" (coherent true), "random".
inline const std::vector<std::string> kBarkColourings{"coherent", "random"};

/// Parameters of a primitive.  Radii are surface radii of the isolated
/// primitive at the tree's threshold.
struct Primitive {
    glm::dvec3 p0{0.0}, p1{0.0};  ///< skeleton; a sphere's centre is p0
    double r0 = 0.0, r1 = 0.0;    ///< surface radius at p0 and at p1
    double weight = 1.0;          ///< multiplies the field; negative for scars
    double sigma = 1.0;           ///< R-type: support = sigma * r / w^-1(T)
    double kernelWidth = 0.0;     ///< convolution: Cauchy kernel width s
    double support = 0.0;         ///< convolution: window radius R
    double q0 = 0.0, q1 = 0.0;    ///< convolution: densities at p0 and p1
    BarkParams bark;              ///< cone: bark furrows
};

struct GbbParams {
    Combiner b1{NodeType::PCM};    ///< B1, weighted by the bounding field
    Combiner b2{NodeType::BLEND};  ///< B2, weighted by 1 - bound
    int bound = -1;                ///< the bounding field's subtree
};

struct TransformParams {
    double forward[12];  ///< M as a row-major 3x4 matrix
    cb_affine inverse;   ///< M^-1, what the evaluator applies to points
};

using NodeParams =
    std::variant<Primitive, Combiner, GbbParams, TransformParams, cb_bend, cb_twist, cb_taper>;

struct Node {
    NodeType type = NodeType::BLEND;
    std::vector<int> children;
    std::optional<glm::dvec3> color;  ///< the node's own colour attribute
    glm::dvec3 shade{0.8};            ///< effective colour after inheritance (finalize)
    NodeParams params;

    const Primitive& prim() const { return std::get<Primitive>(params); }
    const Combiner& combiner() const { return std::get<Combiner>(params); }
    const GbbParams& gbb() const { return std::get<GbbParams>(params); }
};

/// Options shared by the R-type primitives (sphere, segment, cone).
struct PrimitiveOptions {
    double weight = 1.0;
    std::optional<double> support;  ///< support radius R at p0; default r / w^-1(T) (2r at T = 0.5)
};

struct ConvolutionOptions {
    double weight = 1.0;
    std::optional<double> kernelWidth;  ///< s; default 1 / max(r0, r1)
    std::optional<double> support;      ///< window radius; default 3 max(r0, r1)
};

/// The largest and smallest iso-values a BlobTree takes (its constructor
/// says why).
constexpr double kMaxThreshold = 0.99;
constexpr double kMinThreshold = 0.001;

class BlobTree {
public:
    /// threshold T in (0, 1): the surface is F = T, inside F > T.
    explicit BlobTree(double threshold = 0.5);

    double threshold() const { return T_; }
    /// The shortest wavelength of procedural detail (bark furrows fade in
    /// above it: a bake sets 4 voxels); 0: no limit.
    double detailLimit() const { return detailLimit_; }
    void setDetailLimit(double wavelength);
    const BarkLook& barkLook() const { return barkLook_; }
    /// The model time the tree is of (a grown tree's year; 0 for others).
    double time() const { return time_; }
    void setTime(double t) { time_ = t; }
    void setBarkLook(const BarkLook& look) { barkLook_ = look; }
    /// x_T = w^-1(T): where the Wyvill function crosses the threshold (1/2 at T = 1/2).
    double xT() const { return xT_; }

    // Builders.  Each validates its parameters (ParameterError naming the
    // field) and returns the new node's index.  Children must already exist.
    int sphere(const glm::dvec3& center, double radius, const PrimitiveOptions& o = {});
    int segment(const glm::dvec3& p0, const glm::dvec3& p1, double radius,
                const PrimitiveOptions& o = {});
    int cone(const glm::dvec3& p0, const glm::dvec3& p1, double r0, double r1,
             const PrimitiveOptions& o = {});
    /// Bark on cone `node` (ParameterError for depths that are negative,
    /// not finite, or reach past half the cone's radius, or a reference that
    /// is not a unit vector across the axis).
    void setBark(int node, const BarkParams& bark);
    int convolutionSegment(const glm::dvec3& p0, const glm::dvec3& p1, double r0, double r1,
                           const ConvolutionOptions& o = {});
    int op(const Combiner& c, std::vector<int> children);
    int gbb(int bound, std::vector<int> children, const Combiner& b1 = {NodeType::PCM},
            const Combiner& b2 = {NodeType::BLEND});
    int transform(const glm::dmat4& m, int child);
    /// angle in radians, |angle| < pi; dir is the bend direction (not parallel to p1 - p0).
    int bend(const glm::dvec3& p0, const glm::dvec3& p1, const glm::dvec3& dir, double angle,
             int child);
    /// rate in radians per unit length along the axis.
    int twist(const glm::dvec3& origin, const glm::dvec3& axis, double rate, int child);
    int taper(const glm::dvec3& origin, const glm::dvec3& axis, double length, double scale0,
              double scale1, int child);

    /// Room for `n` nodes, so that building a large tree moves none.
    void reserve(size_t n) { nodes_.reserve(n); }

    void setColor(int node, const glm::dvec3& rgb);
    void setRoot(int node);
    int root() const { return root_; }

    /// What thickening a bake's thin parts changes (bake/thicken.h).
    /// Primitive `node`'s radii become r0 and r1, no smaller than its own:
    /// an R-type primitive keeps its sigma (its support grows with its
    /// radius), a convolution segment scales its kernel width and window
    /// with its largest radius and takes the densities of its new radii.
    void setRadii(int node, double r0, double r1);
    /// Transform `node`'s matrix, and a new one (checked as transform()
    /// checks it).
    glm::dmat4 matrix(int node) const;
    void setMatrix(int node, const glm::dmat4& m);

    /// Resolves inherited colours: a primitive without its own colour takes
    /// the nearest ancestor's, else the default grey.  Call after building.
    void finalize();

    const Node& node(int i) const { return nodes_[size_t(i)]; }
    size_t size() const { return nodes_.size(); }
    const std::vector<Node>& nodes() const { return nodes_; }

    /// Checks a combiner's parameters against this tree's threshold.
    void validate(const Combiner& c) const;

private:
    int add(NodeType type, NodeParams params, std::vector<int> children = {});
    int addSkeletal(NodeType type, const glm::dvec3& p0, const glm::dvec3& p1, double r0, double r1,
                    const PrimitiveOptions& o);
    static Primitive primitive(const glm::dvec3& p0, const glm::dvec3& p1, double r0, double r1,
                               double weight);
    void checkChild(int child, const char* field) const;

    std::vector<Node> nodes_;
    int root_ = -1;
    double T_ = 0.5;
    double xT_ = 0.5;
    double detailLimit_ = 0.0;
    BarkLook barkLook_;
    double time_ = 0.0;
};

}  // namespace cambium
