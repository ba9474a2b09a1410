// cambium — how much memory a bake will need, before it starts.
#include "bake/options.h"
#include "bake/stages.h"

#include "cb_program.h"

#include <openvdb/openvdb.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace cambium {

double surfaceRadiusScale(double weight, double sigma, double T, double xT)
{
    const double W = std::abs(weight);
    if (!(W > 1.0))
        return 1.0;
    // kernels/cb_primitives.h: F(d) = W w(u) with u = (xT / sigma)(d / r - 1
    // + sigma), so F = T at u = w^-1(T / |W|).
    return 1.0 + sigma * (cb_wyvill_inverse(T / W) / xT - 1.0);
}

double estimateBandVoxels(const FieldProgram& program, double h, double halfWidth)
{
    // Surface area of the primitives in world units (an overestimate where
    // they overlap): a primitive under a transform or taper that scales by
    // s counts s^2 times its own, under a twist its stretch along the turns
    // too (FieldProgram::areaScaleOf).  Each is convex, and so is its image
    // under affine maps, so the part of it inside a box has at most the
    // box's area: the surface's bounds (a huge sphere that cuts, a saw cut,
    // counts so) and its support box in world space, its own or under
    // transforms the outermost one's.  Under a bend, twist or taper it may
    // fold: then the band it makes is at most the outermost warp's box, as
    // an area the box's volume over the band's width.
    auto boxArea = [](const Box& box) {
        const glm::dvec3 b = box.size();
        return 2.0 * (b.x * b.y + b.y * b.z + b.z * b.x);
    };
    auto bandArea = [&](const Box& box) {
        const glm::dvec3 b = box.size() + glm::dvec3(2.0 * halfWidth * h);
        return b.x * b.y * b.z / (2.0 * halfWidth * h);
    };
    const double boundsArea = boxArea(program.positiveBounds());
    double area = 0.0;
    const auto& P = program.params();
    const double T = P[CB_P_T], xT = P[CB_P_XT];
    std::vector<const Box*> warps;
    int folding = 0;  // bends, twists and tapers among them
    for (const Instr& in : program.code()) {
        if (in.op == CB_I_WARP) {
            warps.push_back(&program.supportOf(in));
            folding += in.b != CB_TRANSFORM;
        } else if (in.op == CB_I_UNWARP) {
            warps.pop_back();
            folding -= in.b != CB_TRANSFORM;
        }
        const double* q = P.data() + in.a;
        double a = -1.0;
        if (in.op == CB_SPHERE) {
            const double r = q[CB_SPHERE_RADIUS] *
                             surfaceRadiusScale(q[CB_SPHERE_WEIGHT], q[CB_SPHERE_SIGMA], T, xT);
            a = 4.0 * M_PI * r * r;
        } else if (in.op == CB_SEGMENT || in.op == CB_CONE || in.op == CB_I_BARK_CONE) {
            const double m = surfaceRadiusScale(q[CB_CONE_WEIGHT], q[CB_CONE_SIGMA], T, xT),
                         r0 = m * q[CB_CONE_R0], r1 = m * q[CB_CONE_R1];
            a = M_PI * (r0 + r1) * q[CB_CONE_LEN] +
                2.0 * M_PI * std::max(r0, r1) * std::max(r0, r1);
        } else if (in.op == CB_CONVOLUTION_SEGMENT) {
            // Its window is three times its largest radius; a weight above
            // 1 moves the surface out towards the window.
            const double r = q[CB_CONV_SUPPORT] / (std::abs(q[CB_CONV_WEIGHT]) > 1.0 ? 1.0 : 3.0);
            a = 2.0 * M_PI * r * q[CB_CONV_LEN] + 2.0 * M_PI * r * r;
        }
        if (!(a >= 0.0))
            continue;
        a *= program.areaScaleOf(in);  // in world units
        area += folding > 0
                    ? std::min(a, bandArea(*warps.front()))
                    : std::min({a, boundsArea,
                                boxArea(warps.empty() ? program.supportOf(in) : *warps.front())});
    }
    return area / (h * h) * 2.0 * halfWidth;
}

namespace {

/// Leaves sampled per band voxel (a leaf holds about 150 band voxels of its
/// 512; about 1.4 times as many leaves are sampled as hold any).
constexpr double kSampledLeavesPerBandVoxel = 1.4 / 150.0;

/// A varying colour's bytes per band voxel in a packed bake (its leaves
/// compressed as they are made).  Measured at 0.003 on two unit spheres of
/// two colours (14.6 M voxels): 289 MB with the colour shell, 307 MB with
/// the band's, 277 MB with none; it was counted as 41 bytes, the unpacked
/// band's three floats, and a bake that needed 1.1 GB was refused as 8 GB.
constexpr double kPackedColour = 3.0;

/// Bytes a bake holds per leaf its topology search found to sample, set low
/// so that the check refuses only what surely does not fit: measured 1.27 KB
/// on two coincident spheres (2.9 M leaves, 3.7 GB), 1.65 KB with colours.
constexpr double kBytesPerSampledLeaf = 1200.0;

/// File bytes per estimated band voxel.  Measured on the examples, a file
/// holds 5-7 bytes per active voxel (surface 3.5-5, the colour shell 0.4-1.8,
/// the band's colour twice that; halves 0.65 of it), but the estimate's band
/// is 0.8 times the true one on twiggy trees and 3-11 times it where
/// primitives overlap: these are set low, so that the disk check refuses
/// only what surely does not fit (bush.l 1.0x its file, the Populus 0.4x,
/// branch_junction 4x).
constexpr double kFileSurface = 1.5, kFileHalfSurface = 1.0, kFileColour = 0.5,
                 kFileHalfColour = 0.3;

}  // namespace

double estimateBakeBytes(const FieldProgram& program, double h, double halfWidth, bool packed)
{
    // Per band voxel: the output grid (a float leaf of 2 KB holds about 150
    // of them on a tree: 14 bytes; packed, its compressed bytes and a leaf of
    // value mask only: 4.5 and 0.7 bytes on the benchmark trees, counted as
    // 6; a colour that varies adds three floats per leaf voxel, 41 bytes,
    // and packed, kPackedColour), the per-leaf tables (neighbours, inside bits,
    // state, jobs: about 250 bytes per sampled leaf, 2.5 bytes) and the
    // stages' state streamed through the slabs (about three sampled voxels
    // per band voxel, 2 bytes of value and a share of the surface points
    // each, of which a slab and a quarter is held: on a tree a fifth,
    // counted as half); plus the libraries (OpenVDB and PoCL's LLVM, about
    // 150 MB).
    const double perVoxel = (packed ? 6.0 : 14.0) +
                            (program.uniformColor() ? 0.0
                             : packed               ? kPackedColour
                                                    : 41.0) +
                            250.0 * kSampledLeavesPerBandVoxel + 0.5 * 3.0 * 3.0;
    return estimateBandVoxels(program, h, halfWidth) * perVoxel + 150e6;
}

double internalNodeBytes(size_t leaves, bool colour,
                         const std::function<openvdb::Coord(size_t)>& origin)
{
    using FloatLower = openvdb::FloatTree::RootNodeType::ChildNodeType::ChildNodeType;
    using FloatUpper = openvdb::FloatTree::RootNodeType::ChildNodeType;
    using ColourLower = openvdb::Vec3STree::RootNodeType::ChildNodeType::ChildNodeType;
    using ColourUpper = openvdb::Vec3STree::RootNodeType::ChildNodeType;
    std::vector<uint64_t> keys(leaves);
    auto count = [&](int log2) {
        tbb::parallel_for(size_t(0), leaves, [&](size_t l) {
            const openvdb::Coord o = origin(l);
            keys[l] = nodeKey(o.x(), o.y(), o.z(), log2);
        });
        tbb::parallel_sort(keys.begin(), keys.end());
        return double(std::unique(keys.begin(), keys.end()) - keys.begin());
    };
    return count(FloatLower::TOTAL) *
               double(sizeof(FloatLower) + (colour ? sizeof(ColourLower) : 0)) +
           count(FloatUpper::TOTAL) *
               double(sizeof(FloatUpper) + (colour ? sizeof(ColourUpper) : 0));
}

double estimateBakeBytesFromLeaves(size_t sampledLeaves)
{
    return double(sampledLeaves) * kBytesPerSampledLeaf + 150e6;
}

double estimateFileBytes(const FieldProgram& program, double h, double halfWidth,
                         ColourExtent colour, bool half, bool fog)
{
    // Per estimated band voxel, the file's blosc-compressed leaves: the
    // surface's floats, a colour that varies (the shell about half the
    // band's), the fog's floats as the surface's.
    const double band = estimateBandVoxels(program, h, halfWidth);
    double perVoxel = half ? kFileHalfSurface : kFileSurface;
    if (!program.uniformColor() && colour != ColourExtent::None)
        perVoxel +=
            (colour == ColourExtent::Band ? 1.0 : 0.5) * (half ? kFileHalfColour : kFileColour);
    if (fog)
        perVoxel += half ? kFileHalfSurface : kFileSurface;
    return band * perVoxel + 4096.0;
}

double estimateBakeSeconds(double bandVoxels, int cores)
{
    // Measured here (2 cores), in estimated band voxels a second a core,
    // whole processes: the year-27 Populus at 0.005 2.1-2.5 M (47.6 M
    // estimated, 9.7-11.3 s; 16.5 s beside another process), the
    // 20,000-internode tree at 0.005 5.5 M (48.2 M in 4.4 s), models of
    // large blended primitives 9-12 M (the
    // estimate counts their overlaps).  A small bake's start-up makes its
    // rate lower (the Populus at 0.02: 2.27 M in 1.12 s), but it says
    // nothing below ten seconds.  At 2 M, rather long than short (1 M said
    // 24 s for either tree).
    return bandVoxels / (2e6 * std::max(cores, 1));
}

double estimateReuseBytes(const FieldProgram& program, double h, double halfWidth)
{
    return 2.0 * 1100.0 * kSampledLeavesPerBandVoxel * estimateBandVoxels(program, h, halfWidth);
}

}  // namespace cambium
