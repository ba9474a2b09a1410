// cambium — the CPU reference evaluator of a BlobTree.
//
// Simple and obviously right: it walks the tree recursively, applies the
// per-operation math of kernels/cb_*.h in double precision and carries the
// gradient by the chain rule.  This is the oracle every kernel is tested
// against, not the fast path.  Thread-safe: evaluation reads the tree only.
#pragma once

#include "blobtree/blobtree.h"

#include <glm/glm.hpp>

#include <vector>

namespace cambium {

/// Field value, analytic gradient and blended colour at a point.
struct FieldSample {
    double value = 0.0;
    glm::dvec3 gradient{0.0};
    glm::dvec3 color{0.0};
};

/// Combines children's samples the way an operator (or one side of a GBB)
/// does.  Colour is the field-weighted combination of the children's colours
/// (paper 001 sec. 3.6): weights |f_i| for sums and PCM, f_i^n for Ricci,
/// |g_k(f_i)| for better blending; CSG takes the colour of the child it picks.
FieldSample combine(const Combiner& c, const std::vector<FieldSample>& kids, double threshold);

class ReferenceEvaluator {
public:
    /// The tree must be finalized (colours resolved) and outlive the evaluator.
    explicit ReferenceEvaluator(const BlobTree& tree) : tree_(tree) {}

    FieldSample sample(const glm::dvec3& p) const { return sample(tree_.root(), p); }
    FieldSample sample(int node, const glm::dvec3& p) const;
    double value(const glm::dvec3& p) const { return sample(p).value; }

private:
    const BlobTree& tree_;
};

}  // namespace cambium
