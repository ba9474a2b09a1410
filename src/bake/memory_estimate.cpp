// cambium — how much memory a bake will need, before it starts.
#include "bake/levelset.h"

#include "cb_program.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cambium {

namespace {

/// Voxels within the band, from the primitives' surface area.
double bandVoxels(const FieldProgram& program, double h, double halfWidth)
{
    // Surface area of the primitives (an overestimate where they overlap).
    // Each is convex, so the part of it inside a box has at most the box's
    // area: the surface's bounds (a huge sphere that cuts, a saw cut, counts
    // so) and its support box in world space — its own, or under warps the
    // outermost warp's (a unit sphere mapped onto a leaf counts as the leaf).
    auto boxArea = [](const Box& box) {
        const glm::dvec3 b = box.size();
        return 2.0 * (b.x * b.y + b.y * b.z + b.z * b.x);
    };
    const double boundsArea = boxArea(program.positiveBounds());
    double area = 0.0;
    const auto& P = program.params();
    std::vector<const Box*> warps;
    for (const Instr& in : program.code()) {
        if (in.op == CB_I_WARP)
            warps.push_back(&program.supportOf(in));
        else if (in.op == CB_I_UNWARP)
            warps.pop_back();
        const double* q = P.data() + in.a;
        double a = -1.0;
        if (in.op == CB_SPHERE)
            a = 4.0 * M_PI * q[CB_SPHERE_RADIUS] * q[CB_SPHERE_RADIUS];
        else if (in.op == CB_SEGMENT || in.op == CB_CONE || in.op == CB_I_BARK_CONE)
            a = M_PI * (q[CB_CONE_R0] + q[CB_CONE_R1]) * q[CB_CONE_LEN] +
                2.0 * M_PI * std::max(q[CB_CONE_R0], q[CB_CONE_R1]) *
                    std::max(q[CB_CONE_R0], q[CB_CONE_R1]);
        else if (in.op == CB_CONVOLUTION_SEGMENT) {
            const double r =
                q[CB_CONV_SUPPORT] / 3.0;  // its window is three times its largest radius
            a = 2.0 * M_PI * r * q[CB_CONV_LEN] + 2.0 * M_PI * r * r;
        }
        if (a >= 0.0)
            area += std::min(
                {a, boundsArea, boxArea(warps.empty() ? program.supportOf(in) : *warps.front())});
    }
    return area / (h * h) * 2.0 * halfWidth;
}

/// Leaves sampled per band voxel (a leaf holds about 150 band voxels of its
/// 512; about 1.4 times as many leaves are sampled as hold any).
constexpr double kSampledLeavesPerBandVoxel = 1.4 / 150.0;

}  // namespace

double estimateBakeBytes(const FieldProgram& program, double h, double halfWidth, bool packed)
{
    // Per band voxel: the output grid (a float leaf of 2 KB holds about 150
    // of them on a tree: 14 bytes; packed, its compressed bytes and a leaf of
    // value mask only: 4.5 and 0.7 bytes on the benchmark trees, counted as
    // 6; a colour that varies adds three floats per leaf voxel: 41 bytes,
    // counted so packed too), the per-leaf tables (neighbours, inside bits,
    // state, jobs: about 250 bytes per sampled leaf, 2.5 bytes) and the
    // stages' state streamed through the slabs (about three sampled voxels
    // per band voxel, 2 bytes of value and a share of the surface points
    // each, of which a slab and a quarter is held: on a tree a fifth,
    // counted as half); plus the libraries (OpenVDB and PoCL's LLVM, about
    // 150 MB).
    const double perVoxel = (packed ? 6.0 : 14.0) + (program.uniformColor() ? 0.0 : 41.0) +
                            250.0 * kSampledLeavesPerBandVoxel + 0.5 * 3.0 * 3.0;
    return bandVoxels(program, h, halfWidth) * perVoxel + 150e6;
}

double estimateReuseBytes(const FieldProgram& program, double h, double halfWidth)
{
    return 2.0 * 1100.0 * kSampledLeavesPerBandVoxel * bandVoxels(program, h, halfWidth);
}

}  // namespace cambium
