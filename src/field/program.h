// cambium — the FieldProgram: a BlobTree compiled to the flat instruction
// stream of kernels/cb_program.h, with interval bounds over boxes and
// specialisation to a region (compare libfive's tape simplification).
#pragma once

#include "blobtree/blobtree.h"
#include "blobtree/evaluator.h"
#include "core/box.h"

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace cambium {

/// One instruction: { op, a, b, c } as documented in kernels/cb_program.h.
struct Instr {
    int32_t op, a, b, c;
};

/// A closed interval of field values.
struct Interval {
    double lo = 0.0, hi = 0.0;
    bool contains(double v) const { return lo <= v && v <= hi; }
    bool isZero() const { return lo == 0.0 && hi == 0.0; }
};

/// A view of an instruction stream.
struct Code {
    const Instr* data = nullptr;
    size_t size = 0;
    Code() = default;
    Code(const Instr* d, size_t n) : data(d), size(n) {}
    Code(const std::vector<Instr>& v) : data(v.data()), size(v.size()) {}  // NOLINT: a view
};

class FieldProgram {
public:
    /// Compiles a finalized BlobTree.  Throws InputError when the tree nests
    /// deeper than the kernels' fixed stacks allow.
    static FieldProgram compile(const BlobTree& tree);
    /// The same, its InputError naming `source` (the model's file).
    static FieldProgram compile(const BlobTree& tree, const std::string& source);

    double threshold() const;
    /// The shortest wavelength of procedural detail (BlobTree::detailLimit).
    double detailLimit() const;
    /// Sets it (a bake: 4 voxels, so that every octave of bark it keeps
    /// spans several voxels); InputError unless finite and >= 0.
    void setDetailLimit(double wavelength);
    /// Number of cones with bark.
    size_t barkCount() const { return bark_; }
    /// The parameter table (double; the kernels get a float copy).
    const std::vector<double>& params() const { return params_; }
    std::vector<float> paramsFloat() const;
    /// The whole program.
    const std::vector<Instr>& code() const { return code_; }
    /// Where the root's field can be positive (the surface lies inside).
    const Box& positiveBounds() const { return positive_; }
    /// The largest coordinate of any primitive's positive support in its
    /// own frame (before the transforms and warps above it): where the
    /// kernels' float positions must still tell voxels apart.
    double farthestLocal() const { return farthestLocal_; }
    /// Where the root's field can be nonzero.
    const Box& supportBounds() const { return support_; }
    /// Where the field of the primitive or subtree that `in` heads can be
    /// nonzero, in the space of the nearest warp above it (world space when
    /// there is none).
    const Box& supportOf(const Instr& in) const { return subtreeSupport_[size_t(in.c)]; }
    /// World area per unit of area of that space, at most: how much the
    /// transforms, tapers and twists above the primitive or subtree that
    /// `in` heads stretch its surface.
    double areaScaleOf(const Instr& in) const { return subtreeAreaScale_[size_t(in.c)]; }
    /// Number of primitives in the whole program.
    size_t primitiveCount() const { return primitives_; }
    /// The colour of every primitive when they all have the same: then the
    /// field's colour is that colour wherever it is defined (every operator
    /// blends or picks its children's colours).
    const std::optional<glm::dvec3>& uniformColor() const { return uniformColor_; }

    /// Whether `other` computes the same field and colour: the same
    /// instructions and parameter table, value for value.
    bool identical(const FieldProgram& other) const;

    /// `code` written out as the kernels read it — each instruction's op and
    /// the fields they use, its parameter block's values inlined — after the
    /// threshold: two programs (of this or another FieldProgram) compute the
    /// same values and colours wherever their canonical forms are equal.
    void canonical(Code code, std::vector<double>& out) const;

    /// Bounds of the field of `code` over `box`, and (when `out` is given)
    /// `code` specialised to the box appended to *out: children whose field is
    /// zero or provably irrelevant on the box are removed, operators left with
    /// one child collapse to it, so that the result computes exactly the same
    /// field as `code` at every point of the box.
    Interval specialize(Code code, const Box& box, std::vector<Instr>* out) const;

    /// Evaluates `code` at p on the host with the same interpreter as the
    /// kernels (kernels/cb_program.h, in double precision).
    FieldSample evaluate(Code code, const glm::dvec3& p) const;
    /// A surface voxel's Newton step from p toward F = T, at most `reach`
    /// long, into `step`, and the sample where it lands
    /// (kernels/cb_program.h, cb_surface_step, in double precision).
    FieldSample surfaceStep(Code code, const glm::dvec3& p, double reach, glm::dvec3& step) const;

    /// Stack depths a program needs: values and warp frames.
    static void depths(Code code, int& stack, int& warps);

    static int maxStackDepth();
    static int maxWarpDepth();

private:
    /// specialize() of the subtree at in[pos]: its bounds over `box`, its
    /// specialised code appended to *out, pos moved past it.  `depth` picks
    /// the working lists of this level of the recursion.
    Interval node(Code in, size_t& pos, const Box& box, std::vector<Instr>* out,
                  size_t depth) const;
    /// node() for a primitive.
    Interval primitiveNode(const Instr& head, const Box& box, std::vector<Instr>* out) const;
    /// node() for WARP subtree UNWARP: a warp over a zero subtree is zero.
    Interval warpNode(Code in, size_t& pos, const Box& box, std::vector<Instr>* out,
                      size_t depth) const;
    /// node() for an operator: its children specialised, those it can do
    /// without on the box removed, the operator collapsed where it can be.
    Interval operatorNode(Code in, size_t& pos, const Box& box, std::vector<Instr>* out,
                          size_t depth) const;
    Interval primitiveInterval(const Instr& in, const Box& box) const;
    Box warpChildBox(const Instr& in, const Box& box) const;

    std::vector<double> params_;
    std::vector<Instr> code_;
    std::vector<Box> subtreeSupport_;       ///< indexed by OPEN.c / WARP.c
    std::vector<double> subtreeAreaScale_;  ///< the same
    Box positive_, support_;
    double farthestLocal_ = 0.0;
    size_t primitives_ = 0;
    size_t bark_ = 0;
    std::optional<glm::dvec3> uniformColor_;
};

/// Squared distance between the segment [a, b] and a box (exact).
double segmentBoxDistance2(const glm::dvec3& a, const glm::dvec3& b, const Box& box);

}  // namespace cambium
