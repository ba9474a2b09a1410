// Parity of the OpenCL sampling kernels (kernels/sample.cl, float8 lanes on
// PoCL) with the CPU reference evaluator, for every opcode and for random
// BlobTrees mixing all node types, including points on support borders and
// inside PCM propagation regions.
#include "bake/sampler.h"

#include "blobtree/bounds.h"
#include "random_tree.h"
#include "scenes.h"
#include "test_util.h"

#include "cb_primitives.h"

#include <gtest/gtest.h>
#include <openvdb/math/Half.h>

#include <cmath>
#include <cstring>
#include <random>

namespace {

using namespace cambium;
using namespace cambium::test;

class SamplerParity : public ::testing::Test {
protected:
    static void SetUpTestSuite() { cl_ = makeOpenCLSampler().release(); }
    static void TearDownTestSuite() { delete cl_; }
    static FieldSampler* cl_;
};
FieldSampler* SamplerParity::cl_ = nullptr;

/// Points where a tree is interesting: random ones in its support, and for
/// every primitive points just inside and outside the end of its support and
/// on its surface.
std::vector<glm::dvec3> probePoints(const BlobTree& tree, std::mt19937& rng, int random)
{
    std::vector<glm::dvec3> pts;
    const Box box = computeBounds(tree)[size_t(tree.root())].support.padded(0.05);
    for (int i = 0; i < random; ++i)
        pts.push_back(randomIn(rng, box.lo, box.hi));
    for (const Node& n : tree.nodes()) {
        if (kindOf(n.type) != NodeKind::Primitive)
            continue;
        const Primitive& p = n.prim();
        const double reach = n.type == NodeType::CONVOLUTION_SEGMENT
                                 ? p.support
                                 : cb_skeletal_reach(p.r0, p.sigma, tree.xT());
        for (int k = 0; k < 8; ++k) {
            const glm::dvec3 d = randomUnit(rng);
            for (double r : {reach * (1 - 1e-4), reach * (1 + 1e-4), p.r0, 0.5 * p.r0})
                pts.push_back(p.p0 + r * d);
        }
    }
    return pts;
}

struct Mismatch {
    int value = 0, gradient = 0, colour = 0;
    size_t n = 0;
};

/// Compares the kernel with the reference evaluator at `points` (rounded to
/// float first, as the kernel sees them).
Mismatch compare(FieldSampler& s, const BlobTree& tree, std::vector<glm::dvec3> points)
{
    for (auto& p : points)
        p = glm::dvec3(glm::vec3(p));
    const FieldProgram prog = FieldProgram::compile(tree);
    s.setProgram(prog);
    const std::vector<float> out = s.samplePoints(prog.code(), points);
    ReferenceEvaluator ref(tree);
    const size_t n = points.size();
    std::vector<FieldSample> want(n);
    double range = 1.0;
    for (size_t i = 0; i < n; ++i) {
        want[i] = ref.sample(points[i]);
        EXPECT_TRUE(std::isfinite(want[i].value) && std::isfinite(out[i]))
            << "reference " << want[i].value << " kernel " << out[i];
        range = std::max(range, std::abs(want[i].value));
    }
    Mismatch m;
    m.n = n;
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 g(out[n + i], out[2 * n + i], out[3 * n + i]);
        const glm::dvec3 c(out[4 * n + i], out[5 * n + i], out[6 * n + i]);
        if (std::abs(out[i] - want[i].value) > 1e-5 * range) {
            ++m.value;
            ADD_FAILURE() << "value " << out[i] << " vs " << want[i].value << " at " << points[i].x
                          << " " << points[i].y << " " << points[i].z;
        }
        if (glm::length(g - want[i].gradient) > 1e-3 * std::max(1.0, glm::length(want[i].gradient)))
            ++m.gradient;
        if (glm::length(c - want[i].color) > 1e-3)
            ++m.colour;
    }
    return m;
}

TEST_F(SamplerParity, EveryOpcode)
{
    for (NodeType type : allNodeTypes()) {
        SCOPED_TRACE(typeName(type));
        const BlobTree tree = sceneFor(type);
        std::mt19937 rng(30 + int(type));
        const Mismatch m = compare(*cl_, tree, probePoints(tree, rng, 3000));
        // Gradients and colours jump across creases (CSG switches, PCM ridges,
        // cone end planes): a float and a double evaluation may land on
        // different sides of one.  Such points are rare.
        EXPECT_LE(m.gradient, int(m.n / 200)) << m.gradient << " of " << m.n;
        EXPECT_LE(m.colour, int(m.n / 200)) << m.colour << " of " << m.n;
    }
}

TEST_F(SamplerParity, BarkCones)
{
    // A bent branch of three cones with bark, summed, with and without the
    // detail limit (sample.cl's CB_I_BARK_CONE against the reference).
    for (double limit : {0.0, 0.08}) {
        BlobTree t;
        const glm::dvec3 p[4] = {{0, 0, 0}, {0, 0.5, 0.05}, {0.1, 1.0, 0.1}, {0.3, 1.4, 0.1}};
        std::vector<int> cones;
        for (int i = 0; i < 3; ++i) {
            const int c = t.cone(p[i], p[i + 1], 0.16 - 0.04 * i, 0.12 - 0.04 * i);
            BarkParams b;
            b.depth0 = 0.012 - 0.003 * i;
            b.depth1 = 0.009 - 0.003 * i;
            const glm::dvec3 axis = glm::normalize(p[i + 1] - p[i]);
            b.reference = glm::normalize(glm::cross(axis, glm::dvec3(1, 0, 0)));
            b.s0 = 0.5 * i;
            b.around = 7;
            b.along = 11.0;
            b.phase = 0.2 + i;
            t.setBark(c, b);
            cones.push_back(c);
        }
        t.setRoot(t.op({NodeType::BLEND}, cones));
        t.setDetailLimit(limit);
        t.finalize();
        std::mt19937 rng(77);
        const Mismatch m = compare(*cl_, t, probePoints(t, rng, 4000));
        EXPECT_LE(m.gradient, int(m.n / 200)) << m.gradient << " of " << m.n;
        EXPECT_LE(m.colour, int(m.n / 200)) << m.colour << " of " << m.n;
    }
}

TEST_F(SamplerParity, PcmPropagationRegion)
{
    // Points where the weaker field is inside the propagation band (T - w, T):
    // the bulge the kernel computes must be the reference's.
    BlobTree tree;
    const int a = tree.sphere({-0.4, 0, 0}, 0.8), b = tree.sphere({0.5, 0, 0}, 0.6);
    Combiner pcm{NodeType::PCM};
    pcm.width = 0.25;
    tree.setRoot(tree.op(pcm, {a, b}));
    tree.finalize();
    ReferenceEvaluator ref(tree);
    std::mt19937 rng(31);
    std::vector<glm::dvec3> pts;
    while (pts.size() < 4000) {
        const glm::dvec3 p = randomIn(rng, glm::dvec3(-1.5), glm::dvec3(1.5));
        const double w = std::min(ref.sample(a, p).value, ref.sample(b, p).value);
        if (w > 0.5 - pcm.width && w < 0.5)
            pts.push_back(p);
    }
    const Mismatch m = compare(*cl_, tree, pts);
    EXPECT_EQ(m.value, 0);
    EXPECT_LE(m.gradient, 20);
}

TEST_F(SamplerParity, WarpsFarFromTheirOriginsTinyBendsAndHeavyRicciBlends)
{
    // Where the float kernels once differed from the double reference by far
    // more than a voxel (exit 0, wrong surfaces): a twist about an origin 1e7
    // along its axis (the float angle lost 1000 degrees), a taper whose origin
    // is 1.4e7 away (its distance from the axis lost whole units), a bend of
    // 1e-4 degrees (an arc radius of 5.7e5: r - rho lost 0.03), and Ricci's
    // n = 64 over weights of 1e6 (f^n overflowed: an infinite field).
    const double deg = M_PI / 180.0;
    NamedTrees named;
    named.add("twist", [&](BlobTree& t) {
        return t.twist({0, -1e7, 0}, {0, 1, 0}, 1000 * deg,
                       t.cone({0.1, 0, 0}, {0.1, 1, 0}, 0.05, 0.05));
    });
    named.add("taper", [&](BlobTree& t) {
        return t.taper({-1e7, -1e7, 0}, {1, 1, 0}, 1e8, 1.0, 1.0001,
                       t.cone({0, 0, 0}, {0, 1, 0}, 0.1, 0.05));
    });
    for (double angle : {1e-4, 1e-3, 30.0})
        named.add("bend", [&](BlobTree& t) {
            return t.bend({0, 0, 0}, {0, 1, 0}, {1, 0, 0}, angle * deg,
                          t.cone({0, 0, 0}, {0, 1, 0}, 0.1, 0.05));
        });
    named.add("ricci", [&](BlobTree& t) {
        PrimitiveOptions heavy;
        heavy.weight = 1e6;
        Combiner ricci{NodeType::RICCI};
        ricci.n = 64;
        return t.op(ricci, {t.sphere({0, 0, 0}, 1, heavy), t.sphere({0.8, 0, 0}, 0.7, heavy)});
    });
    for (auto& [name, tree] : named.trees) {
        SCOPED_TRACE(name);
        std::mt19937 rng(41);
        const Mismatch m = compare(*cl_, tree, probePoints(tree, rng, 3000));
        EXPECT_EQ(m.value, 0);
        EXPECT_LE(m.gradient, int(m.n / 200)) << m.gradient << " of " << m.n;
        EXPECT_LE(m.colour, int(m.n / 200)) << m.colour << " of " << m.n;
    }
}

TEST_F(SamplerParity, RandomTreesMixingAllNodeTypes)
{
    for (unsigned seed = 0; seed < 40; ++seed) {
        SCOPED_TRACE(seed);
        const BlobTree tree = RandomTreeBuilder(300 + seed).build(1 + int(seed % 4));
        std::mt19937 rng(seed);
        const Mismatch m = compare(*cl_, tree, probePoints(tree, rng, 1500));
        EXPECT_LE(m.gradient, int(m.n / 100)) << m.gradient << " of " << m.n;
        EXPECT_LE(m.colour, int(m.n / 100)) << m.colour << " of " << m.n;
    }
}

TEST_F(SamplerParity, LeavesMatchTheCpuPath)
{
    // The leaf kernel places voxels where the CPU path does and computes the
    // same samples, with specialised programs.
    const BlobTree tree = RandomTreeBuilder(77).build(3);
    const FieldProgram prog = FieldProgram::compile(tree);
    const double h = 0.05;
    std::vector<Instr> pool;
    std::vector<LeafJob> jobs;
    for (int i = 0; i < 27; ++i) {
        const int o[3] = {-12 + 8 * (i % 3), -12 + 8 * ((i / 3) % 3), -12 + 8 * (i / 9)};
        const Box box(glm::dvec3(o[0], o[1], o[2]) * h,
                      glm::dvec3(o[0] + 7, o[1] + 7, o[2] + 7) * h);
        LeafJob job{{o[0], o[1], o[2]}, int32_t(pool.size()), 0};
        prog.specialize(prog.code(), box.padded(kSurfaceReach * h), &pool);
        job.codeLength = int32_t(pool.size()) - job.codeOffset;
        jobs.push_back(job);
    }
    auto cpu = makeCpuSampler();
    for (FieldSampler* s : {cpu.get(), cl_}) {
        s->setProgram(prog);
        s->setLeaves(jobs, pool);
    }
    std::vector<uint16_t> a(jobs.size() * kLeafVoxels), b(a.size());  // F - T as halves
    cpu->sampleValues(jobs, 0, jobs.size(), h, a.data());
    cl_->sampleValues(jobs, 0, jobs.size(), h, b.data());
    // Gradient and colour at a scattering of voxels, grouped by leaf.
    std::vector<SurfaceQuery> queries;
    for (size_t l = 0; l < jobs.size(); ++l)
        for (int i = int(l) % 7; i < kLeafVoxels; i += 5 + int(l % 3))
            queries.push_back({int32_t(l), uint16_t(i)});
    std::vector<SurfaceSample> sa(queries.size()), sb(queries.size());
    cpu->sampleSurface(queries.data(), queries.size(), h, sa.data());
    cl_->sampleSurface(queries.data(), queries.size(), h, sb.data());
    ReferenceEvaluator ref(tree);
    auto position = [&](size_t l, int i) {
        return glm::dvec3(float(jobs[l].origin[0] + (i & 7)) * float(h),
                          float(jobs[l].origin[1] + ((i >> 3) & 7)) * float(h),
                          float(jobs[l].origin[2] + (i >> 6)) * float(h));
    };
    for (size_t l = 0; l < jobs.size(); ++l)
        for (int i = 0; i < kLeafVoxels; ++i) {
            const size_t k = l * kLeafVoxels + size_t(i);
            // F - T rounded to half: 2^-11 relative, plus what float evaluation adds.
            const float fa = halfToFloat(a[k]), fb = halfToFloat(b[k]);
            ASSERT_NEAR(fa, fb, 1e-5 + std::ldexp(std::max(std::abs(fa), std::abs(fb)), -10))
                << "leaf " << l << " voxel " << i;
            // The specialised CPU program equals the reference at the voxel centre.
            const double r = ref.value(position(l, i)) - prog.threshold();
            ASSERT_NEAR(fa, r, 1e-6 + std::ldexp(std::abs(r), -11));
            if (std::abs(r) > 1e-6) {  // the side, exactly
                ASSERT_EQ(halfPositive(a[k]), r > 0.0) << "leaf " << l << " voxel " << i;
            }
        }
    // The surface samples: the CPU path's against the reference evaluator's
    // Newton step (at most a voxel) and its sample where the step lands, the
    // kernel's against the CPU path's where a surface voxel could be (the
    // step within a voxel: elsewhere it follows the direction of a gradient
    // that may vanish, where float and double part ways).
    const double T = prog.threshold();
    size_t near = 0;
    for (size_t q = 0; q < queries.size(); ++q) {
        const glm::dvec3 p = position(size_t(queries[q].leaf), queries[q].voxel);
        const FieldSample r0 = ref.sample(p);
        const double g2 = glm::dot(r0.gradient, r0.gradient);
        double k = g2 > 0.0 ? (T - r0.value) / g2 : 0.0;
        const double len = std::abs(k) * std::sqrt(g2);
        if (len > kSurfaceReach * h)
            k *= kSurfaceReach * h / len;
        const glm::dvec3 step = k * r0.gradient;
        const FieldSample r = ref.sample(p + step);
        auto half = [](uint16_t v) { return double(halfToFloat(v)); };
        ASSERT_NEAR(half(sa[q].value), r.value - T, 1e-6 + std::ldexp(std::abs(r.value - T), -10))
            << "query " << q;
        for (int c = 0; c < 3; ++c) {
            ASSERT_NEAR(half(sa[q].step[c]), step[c] / h, 1e-3) << "query " << q;
            ASSERT_NEAR(half(sa[q].gradient[c]), r.gradient[c],
                        1e-3 * std::max(1.0, std::abs(r.gradient[c])))
                << "query " << q;
        }
        for (int c = 0; c < 3; ++c)
            ASSERT_LE(std::abs(int(sa[q].color[c]) - int(sb[q].color[c])), 1) << "query " << q;
        if (len >= 0.9 * h)
            continue;
        ++near;
        ASSERT_NEAR(half(sa[q].value), half(sb[q].value), 1e-4 + 1e-3 * std::abs(half(sa[q].value)))
            << "query " << q;
        for (int c = 0; c < 3; ++c) {
            ASSERT_NEAR(half(sa[q].step[c]), half(sb[q].step[c]), 2e-3) << "query " << q;
            const double ga = half(sa[q].gradient[c]), gb = half(sb[q].gradient[c]);
            ASSERT_NEAR(ga, gb, 2e-3 * std::max(1.0, std::abs(ga))) << "query " << q;
        }
    }
    EXPECT_GE(near, queries.size() / 20) << "too few queries next to the surface to compare";
}

}  // namespace

namespace {

TEST(HalfFloat, EveryHalfConvertsExactlyAndBack)
{
    // Against OpenVDB's (Imath's) half for all 65,536 bit patterns.
    for (uint32_t b = 0; b < 0x10000u; ++b) {
        openvdb::math::internal::half h;
        h.setBits(uint16_t(b));
        const float want = float(h), got = cambium::halfToFloat(uint16_t(b));
        if (std::isnan(want)) {
            EXPECT_TRUE(std::isnan(got)) << b;
            continue;
        }
        uint32_t wb, gb;
        std::memcpy(&wb, &want, 4);
        std::memcpy(&gb, &got, 4);
        ASSERT_EQ(wb, gb) << "half bits " << b;
        EXPECT_EQ(cambium::floatToHalf(got), uint16_t(b));
    }
}

TEST(HalfFloat, FloatsRoundToTheNearestEvenHalfAsOpenVDBs)
{
    // Every float halfway between two halves and a float either side of it
    // (where rounding decides), and a million random floats of every
    // magnitude, against OpenVDB's (Imath's) conversion.
    auto expectSame = [](float f) {
        const uint16_t want = openvdb::math::internal::half(f).bits();
        const uint16_t got = cambium::floatToHalf(f);
        if (std::isnan(f))
            EXPECT_TRUE(std::isnan(cambium::halfToFloat(got))) << f;
        else
            ASSERT_EQ(got, want) << std::hexfloat << f;
    };
    for (uint32_t b = 0; b < 0x7C00u; ++b) {
        const float lo = cambium::halfToFloat(uint16_t(b)),
                    hi = cambium::halfToFloat(uint16_t(b + 1));
        const float mid = lo + 0.5f * (hi - lo);  // exact: halves have 11 bits
        for (const float f : {mid, std::nextafter(mid, 0.0f), std::nextafter(mid, INFINITY)}) {
            expectSame(f);
            expectSame(-f);
        }
    }
    std::mt19937 rng(5);
    for (int i = 0; i < 1000000; ++i) {
        const uint32_t bits = uint32_t(rng());
        float f;
        std::memcpy(&f, &bits, 4);
        expectSame(f);
    }
    for (const float f : {0.0f, -0.0f, 65504.0f, 65519.99f, 65520.0f, 1e10f, INFINITY, -INFINITY,
                          NAN, 0x1p-25f, 0x1.000002p-25f, 0x1p-24f, 0x1.8p-24f})
        expectSame(f);
}

}  // namespace
