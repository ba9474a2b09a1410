// The parameter-block layouts of kernels/cb_program.h: the compiler writes
// every node's parameters where the named offsets say the interpreter reads
// them, every field of every block is written, and the blocks tile the table.
// Also the PCM colour ridge that the kernels and the reference evaluator share.
#include "random_tree.h"

#include "field/program.h"

#include "cb_program.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

namespace {

using namespace cambium;

/// The nodes in the order the compiler emits their blocks (pre-order; a
/// GBB's bound after its children).
void emissionOrder(const BlobTree& tree, int index, std::vector<int>& out)
{
    const Node& n = tree.node(index);
    out.push_back(index);
    for (int c : n.children)
        emissionOrder(tree, c, out);
    if (n.type == NodeType::GBB)
        emissionOrder(tree, n.gbb().bound, out);
}

bool startsBlock(const Instr& in)
{
    return in.op == CB_SPHERE || in.op == CB_SEGMENT || in.op == CB_CONE ||
           in.op == CB_CONVOLUTION_SEGMENT || in.op == CB_I_OPEN || in.op == CB_I_WARP;
}

size_t blockSize(const Instr& in)
{
    switch (in.op) {
        case CB_SPHERE:
            return CB_SPHERE_SIZE;
        case CB_SEGMENT:
        case CB_CONE:
            return CB_CONE_SIZE;
        case CB_CONVOLUTION_SEGMENT:
            return CB_CONV_SIZE;
        case CB_I_OPEN:
            return in.b == CB_GBB ? CB_GBB_SIZE : CB_OP_SIZE;
        default:  // WARP
            return in.b == CB_TRANSFORM ? CB_AFFINE_SIZE
                   : in.b == CB_BEND    ? CB_BEND_SIZE
                   : in.b == CB_TWIST   ? CB_TWIST_SIZE
                                        : CB_TAPER_SIZE;
    }
}

template <class Vec3>
void expect3(const double* field, const Vec3& v, const char* what)
{
    EXPECT_EQ(field[0], v.x) << what;
    EXPECT_EQ(field[1], v.y) << what;
    EXPECT_EQ(field[2], v.z) << what;
}

void expectCombiner(const double* op, const Combiner& c)
{
    EXPECT_EQ(op[CB_OP_TYPE], double(c.type));
    EXPECT_EQ(op[CB_OP_N], c.n);
    EXPECT_EQ(op[CB_OP_WIDTH], c.width);
    EXPECT_EQ(op[CB_OP_ATTENUATION], c.attenuation);
    EXPECT_EQ(op[CB_OP_K], c.k);
    EXPECT_EQ(op[CB_OP_DARKEN], c.darken);
}

void expectPrimitiveBlock(const double* q, const Node& n)
{
    const Primitive& p = n.prim();
    const glm::dvec3 axis = p.p1 - p.p0;
    const double len = glm::length(axis);
    const glm::dvec3 u = len > 0.0 ? axis / len : glm::dvec3(0.0);
    switch (n.type) {
        case NodeType::SPHERE:
            expect3(q + CB_SPHERE_CENTER, p.p0, "sphere centre");
            EXPECT_EQ(q[CB_SPHERE_RADIUS], p.r0);
            EXPECT_EQ(q[CB_SPHERE_SIGMA], p.sigma);
            EXPECT_EQ(q[CB_SPHERE_WEIGHT], p.weight);
            expect3(q + CB_SPHERE_RGB, n.shade, "sphere colour");
            break;
        case NodeType::SEGMENT:
        case NodeType::CONE:
            expect3(q + CB_CONE_P0, p.p0, "cone p0");
            expect3(q + CB_CONE_AXIS, u, "cone axis");
            EXPECT_EQ(q[CB_CONE_LEN], len);
            EXPECT_EQ(q[CB_CONE_R0], p.r0);
            EXPECT_EQ(q[CB_CONE_R1], p.r1);
            EXPECT_EQ(q[CB_CONE_SIGMA], p.sigma);
            EXPECT_EQ(q[CB_CONE_WEIGHT], p.weight);
            expect3(q + CB_CONE_RGB, n.shade, "cone colour");
            break;
        default:
            expect3(q + CB_CONV_P0, p.p0, "convolution p0");
            expect3(q + CB_CONV_AXIS, u, "convolution axis");
            EXPECT_EQ(q[CB_CONV_LEN], len);
            EXPECT_EQ(q[CB_CONV_Q0], p.q0);
            EXPECT_EQ(q[CB_CONV_Q1], p.q1);
            EXPECT_EQ(q[CB_CONV_KERNEL_WIDTH], p.kernelWidth);
            EXPECT_EQ(q[CB_CONV_SUPPORT], p.support);
            EXPECT_EQ(q[CB_CONV_WEIGHT], p.weight);
            expect3(q + CB_CONV_RGB, n.shade, "convolution colour");
            break;
    }
}

void expectWarpBlock(const double* w, const Node& n)
{
    switch (n.type) {
        case NodeType::TRANSFORM: {
            const cb_affine& inv = std::get<TransformParams>(n.params).inverse;
            for (int k = 0; k < 12; ++k)
                EXPECT_EQ(w[CB_AFFINE_M + k], inv.m[k]);
            break;
        }
        case NodeType::BEND: {
            const cb_bend& b = std::get<cb_bend>(n.params);
            expect3(w + CB_BEND_P0, b.p0, "bend p0");
            expect3(w + CB_BEND_U, b.u, "bend u");
            expect3(w + CB_BEND_V, b.v, "bend v");
            expect3(w + CB_BEND_W, b.w, "bend w");
            EXPECT_EQ(w[CB_BEND_LEN], b.len);
            EXPECT_EQ(w[CB_BEND_THETA], b.theta);
            EXPECT_EQ(w[CB_BEND_RHO], b.rho);
            EXPECT_EQ(w[CB_BEND_CH], b.ch);
            EXPECT_EQ(w[CB_BEND_SH], b.sh);
            EXPECT_EQ(w[CB_BEND_LSCALE], b.lscale);
            break;
        }
        case NodeType::TWIST: {
            const cb_twist& t = std::get<cb_twist>(n.params);
            expect3(w + CB_TWIST_ORIGIN, t.o, "twist origin");
            expect3(w + CB_TWIST_AXIS, t.a, "twist axis");
            EXPECT_EQ(w[CB_TWIST_RATE], t.rate);
            EXPECT_EQ(w[CB_TWIST_PHASE], t.phase);
            break;
        }
        default: {
            const cb_taper& t = std::get<cb_taper>(n.params);
            expect3(w + CB_TAPER_ORIGIN, t.o, "taper origin");
            expect3(w + CB_TAPER_AXIS, t.a, "taper axis");
            EXPECT_EQ(w[CB_TAPER_LEN], t.len);
            EXPECT_EQ(w[CB_TAPER_SCALE0], t.scale0);
            EXPECT_EQ(w[CB_TAPER_SCALE1], t.scale1);
            EXPECT_EQ(w[CB_TAPER_START], t.start);
            break;
        }
    }
}

TEST(ParameterLayout, EveryFieldIsWhereItsNameSays)
{
    for (unsigned seed = 1; seed <= 100; ++seed) {
        const BlobTree tree = test::RandomTreeBuilder(seed).build(2 + int(seed % 3));
        const FieldProgram prog = FieldProgram::compile(tree);
        const std::vector<double>& P = prog.params();
        ASSERT_GE(P.size(), size_t(CB_P_HEADER));
        EXPECT_EQ(P[CB_P_T], tree.threshold());
        EXPECT_EQ(P[CB_P_XT], tree.xT());
        EXPECT_EQ(P[CB_P_ZERO], 0.0);
        for (double v : P)
            ASSERT_FALSE(std::isnan(v)) << "a field the compiler left unwritten, seed " << seed;

        std::vector<int> nodes;
        emissionOrder(tree, tree.root(), nodes);
        size_t next = CB_P_HEADER, k = 0;
        for (const Instr& in : prog.code()) {
            if (!startsBlock(in))
                continue;
            ASSERT_LT(k, nodes.size());
            const Node& n = tree.node(nodes[k++]);
            ASSERT_EQ(size_t(in.a), next) << "blocks follow each other without gaps, seed " << seed;
            next += blockSize(in);
            const double* q = P.data() + in.a;
            switch (kindOf(n.type)) {
                case NodeKind::Primitive:
                    expectPrimitiveBlock(q, n);
                    break;
                case NodeKind::Warp:
                    expectWarpBlock(q, n);
                    break;
                case NodeKind::Operator:
                    if (n.type == NodeType::GBB) {
                        expectCombiner(q + CB_GBB_B1, n.gbb().b1);
                        expectCombiner(q + CB_GBB_B2, n.gbb().b2);
                    } else {
                        expectCombiner(q, n.combiner());
                    }
                    break;
            }
        }
        EXPECT_EQ(k, nodes.size());
        EXPECT_EQ(next, P.size());
    }
}

TEST(PcmRidge, DarkensUpToDarkenFullyAtATenthOfTheWidth)
{
    std::mt19937 rng(3);
    auto uni = [&](double a, double b) {
        return std::uniform_real_distribution<double>(a, b)(rng);
    };
    for (int i = 0; i < 10000; ++i) {
        const double darken = uni(0.0, 1.0), w = uni(0.01, 0.5);
        const double d = i % 10 == 0 ? 0.0 : uni(-0.2, 0.2);
        // The formula as the reference evaluator wrote it before sharing it.
        const double expected = 1.0 - darken * std::clamp(10.0 * std::abs(d) / w, 0.0, 1.0);
        EXPECT_EQ(cb_pcm_ridge_shade(darken, d, w), expected);
    }
    EXPECT_EQ(cb_pcm_ridge_shade(0.7, 0.0, 0.25), 1.0);
    EXPECT_EQ(cb_pcm_ridge_shade(0.7, 0.05, 0.25), 1.0 - 0.7);
    EXPECT_EQ(cb_pcm_ridge_shade(0.7, -0.5, 0.25), 1.0 - 0.7);
}

}  // namespace
