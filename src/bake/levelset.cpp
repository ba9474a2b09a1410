// cambium — narrow-band level-set assembly from sampled fields.
#include "bake/levelset.h"

#include "bake/topology.h"

#include "cb_program.h"

#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/SignedFloodFill.h>

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <cstdlib>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <array>
#include <unordered_map>

namespace cambium {

namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

constexpr int kBatchLeaves = 4096;

/// A point on the surface found next to a sign change, in index space.
struct SurfacePoint {
    float p[3];      // position
    int16_t n[3];    // outward unit normal * 32767
    uint8_t rgb[3];  // colour
};

inline int vox(int x, int y, int z) { return x + 8 * y + 64 * z; }

uint64_t leafKey(int x, int y, int z)
{
    return (uint64_t(uint32_t(x >> 3) & 0x1FFFFF) << 42) | (uint64_t(uint32_t(y >> 3) & 0x1FFFFF) << 21) |
           uint64_t(uint32_t(z >> 3) & 0x1FFFFF);
}

/// Chains of consecutive leaves along one axis: directional sweeps run along them.
std::vector<std::vector<int>> chains(const std::vector<LeafJob>& jobs, int axis)
{
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;
    std::vector<std::array<int, 4>> keys(jobs.size());  // (a, b, along, index)
    for (size_t i = 0; i < jobs.size(); ++i)
        keys[i] = {jobs[i].origin[a], jobs[i].origin[b], jobs[i].origin[axis], int(i)};
    std::sort(keys.begin(), keys.end());
    std::vector<std::vector<int>> out;
    for (size_t k = 0; k < keys.size(); ++k) {
        const bool continues = k > 0 && keys[k][0] == keys[k - 1][0] && keys[k][1] == keys[k - 1][1] &&
                               keys[k][2] == keys[k - 1][2] + 8;
        if (!continues)
            out.emplace_back();
        out.back().push_back(keys[k][3]);
    }
    return out;
}

}  // namespace

double autoVoxelSize(const FieldProgram& program, double voxels)
{
    const Box b = program.positiveBounds();
    const glm::dvec3 s = b.size();
    const double extent = std::max({s.x, s.y, s.z});
    return extent > 0.0 ? extent / voxels : 0.0;
}

double estimateBakeBytes(const FieldProgram& program, double h, double halfWidth)
{
    // Surface area of the primitives (an overestimate where they overlap).
    double area = 0.0;
    const auto& P = program.params();
    for (const Instr& in : program.code()) {
        const double* q = P.data() + in.a;
        if (in.op == CB_SPHERE)
            area += 4.0 * M_PI * q[3] * q[3];
        else if (in.op == CB_SEGMENT || in.op == CB_CONE || in.op == CB_CONVOLUTION_SEGMENT)
            area += M_PI * (q[7] + q[8]) * q[6] + 2.0 * M_PI * std::max(q[7], q[8]) * std::max(q[7], q[8]);
    }
    // Band voxels; about three sampled voxels per band voxel, each holding its
    // value (4 bytes), propagation state (8) and a share of the surface points
    // (3); the output grids (16 bytes per band voxel).
    const double bandVoxels = area / (h * h) * 2.0 * halfWidth;
    return bandVoxels * (3.0 * (4.0 + 8.0 + 3.0) + 16.0) + 64e6;
}

BakedGrids bakeLevelSet(const FieldProgram& program, FieldSampler& sampler,
                        const BakeOptions& opt)
{
    const auto start = Clock::now();
    const double h = opt.voxelSize, W = opt.halfWidth, T = program.threshold();
    // The background is the band's half-width in world units, rounded up so
    // that OpenVDB's checks see at least halfWidth voxels.
    float background = float(W * h);
    while (double(background) / h < W)
        background = std::nextafter(background, INFINITY);
    BakedGrids out;
    BakeStats& st = out.stats;
    st.voxelSize = h;
    auto progress = [&](const char* stage, double f) {
        if (opt.progress)
            opt.progress(stage, f);
    };

    // 1. Topology.
    auto t = Clock::now();
    BandTopology topo = findBandLeaves(program, h, W, [&](double f) { progress("topology", f); });
    st.topologySeconds = since(t);
    st.boxesTested = topo.boxesTested;
    const size_t n = topo.leaves.size();
    st.candidateLeaves = n;
    st.meanProgramLength = n ? double(topo.pool.size()) / double(n) : 0.0;

    // 2. Values of every voxel of those leaves, in batches.
    t = Clock::now();
    std::vector<float> value(n * kLeafVoxels);
    sampler.setProgram(program);
    sampler.setLeafCode(topo.pool);
    for (size_t b0 = 0; b0 < n; b0 += kBatchLeaves) {
        const size_t b1 = std::min(n, b0 + kBatchLeaves);
        sampler.sampleValues(topo.leaves, b0, b1, h, value.data() + b0 * kLeafVoxels);
        progress("sampling", 0.8 * double(b1) / double(n));
    }
    const double valueSeconds = since(t);

    // 3. Neighbours, the voxels next to a sign change of F - T, their
    // gradients and colours, and the surface points they give.
    std::vector<std::array<int32_t, 27>> nb(n);  // (dx+1) + 3 (dy+1) + 9 (dz+1), -1 if absent
    {
        std::unordered_map<uint64_t, int> index;
        index.reserve(n * 2);
        for (size_t l = 0; l < n; ++l)
            index[leafKey(topo.leaves[l].origin[0], topo.leaves[l].origin[1], topo.leaves[l].origin[2])] =
                int(l);
        tbb::parallel_for(size_t(0), n, [&](size_t l) {
            const int32_t* o = topo.leaves[l].origin;
            for (int k = 0; k < 27; ++k) {
                const auto it = index.find(leafKey(o[0] + 8 * (k % 3 - 1), o[1] + 8 * ((k / 3) % 3 - 1),
                                                   o[2] + 8 * (k / 9 - 1)));
                nb[l][size_t(k)] = it == index.end() ? -1 : it->second;
            }
        });
    }
    const float Tf = float(T);
    static const int dirs[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    // Per leaf, its surface voxels in voxel order with the distance (voxels)
    // to the nearest crossing along their edges and that edge's direction.
    struct Edge {
        uint16_t voxel;
        uint8_t dir;
        float t;
    };
    std::vector<std::vector<Edge>> edges(n);
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        // The leaf's values with a one-voxel halo from its neighbours (NaN
        // where no leaf was sampled: no surface can be within a voxel there).
        float F[10][10][10];
        for (int z = -1; z <= 8; ++z)
            for (int y = -1; y <= 8; ++y)
                for (int x = -1; x <= 8; ++x) {
                    const int ox = x < 0 ? -1 : (x > 7), oy = y < 0 ? -1 : (y > 7), oz = z < 0 ? -1 : (z > 7);
                    const int nl = (ox | oy | oz) ? nb[l][size_t((ox + 1) + 3 * (oy + 1) + 9 * (oz + 1))] : int(l);
                    F[z + 1][y + 1][x + 1] =
                        nl < 0 ? NAN
                               : value[size_t(nl) * kLeafVoxels + size_t(vox(x - 8 * ox, y - 8 * oy, z - 8 * oz))] - Tf;
                }
        for (int z = 0; z < 8; ++z)
            for (int y = 0; y < 8; ++y)
                for (int x = 0; x < 8; ++x) {
                    const float fv = F[z + 1][y + 1][x + 1];
                    const bool in = fv > 0.0f;
                    float edge = INFINITY;
                    int e = 0;
                    for (int k = 0; k < 6; ++k) {
                        const float fu = F[z + 1 + dirs[k][2]][y + 1 + dirs[k][1]][x + 1 + dirs[k][0]];
                        if (fu == fu && (fu > 0.0f) != in) {
                            const float tc = fv / (fv - fu);
                            if (tc < edge) {
                                edge = tc;
                                e = k;
                            }
                        }
                    }
                    if (edge <= 1.0f)
                        edges[l].push_back({uint16_t(vox(x, y, z)), uint8_t(e), edge});
                }
    });
    std::vector<size_t> first(n + 1, 0);
    for (size_t l = 0; l < n; ++l)
        first[l + 1] = first[l] + edges[l].size();
    const size_t np = first[n];
    std::vector<SurfaceQuery> queries(np);
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        for (size_t k = 0; k < edges[l].size(); ++k)
            queries[first[l] + k] = {int32_t(l), edges[l][k].voxel};
    });
    t = Clock::now();
    std::vector<SurfaceSample> surface(np);
    sampler.sampleSurface(topo.leaves, queries, h, surface.data());
    queries = {};
    st.samplingSeconds = valueSeconds + since(t);
    progress("sampling", 1.0);
    topo.pool = {};

    t = Clock::now();
    std::vector<SurfacePoint> points(np);
    std::vector<int32_t> src(n * kLeafVoxels, -1);   // nearest surface point, -1 for none
    std::vector<float> d2(n * kLeafVoxels, INFINITY);  // its squared distance, index units
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        const int32_t* o = topo.leaves[l].origin;
        for (size_t k = 0; k < edges[l].size(); ++k) {
            const Edge& ed = edges[l][k];
            const size_t q = first[l] + k;
            const int i = ed.voxel;
            const float fv = value[l * kLeafVoxels + size_t(i)] - Tf;
            const bool in = fv > 0.0f;
            const glm::vec3 g(halfToFloat(surface[q].gradient[0]), halfToFloat(surface[q].gradient[1]),
                              halfToFloat(surface[q].gradient[2]));
            const float glen = glm::length(g);
            // Outward normal: against the gradient (F grows inwards).
            glm::vec3 nrm = glen > 0.0f ? -g / glen : glm::vec3(0.0f);
            float dist = glen > 0.0f ? std::abs(fv) / (glen * float(h)) : INFINITY;
            if (!(dist <= ed.t)) {  // the crossing along an edge bounds the distance
                dist = ed.t;
                if (!(glen > 0.0f))
                    nrm = (in ? 1.0f : -1.0f) *
                          glm::vec3(float(dirs[ed.dir][0]), float(dirs[ed.dir][1]), float(dirs[ed.dir][2]));
            }
            // Closest point: from outside, inwards along -n; from inside, outwards.
            const glm::vec3 cp = glm::vec3(float(o[0] + (i & 7)), float(o[1] + ((i >> 3) & 7)),
                                           float(o[2] + (i >> 6))) + (in ? dist : -dist) * nrm;
            SurfacePoint& sp = points[q];
            for (int c = 0; c < 3; ++c) {
                sp.p[c] = cp[c];
                sp.n[c] = int16_t(std::lround(32767.0f * nrm[c]));
                sp.rgb[c] = surface[q].color[c];
            }
            src[l * kLeafVoxels + size_t(i)] = int32_t(q);
            d2[l * kLeafVoxels + size_t(i)] = dist * dist;
        }
        edges[l] = {};
    });
    edges = {};
    surface = {};
    st.surfacePoints = np;
    if (std::getenv("CAMBIUM_TIMING"))
        fmt::print(stderr, "values {:.3f} s, surface points {:.3f} s ({} points)\n", valueSeconds, since(t), np);

    // 4. Propagation: sweeps along each axis in both directions, each voxel
    // offered its predecessor's surface point; two rounds.  Lines are
    // independent, so the result is deterministic.
    const float limit2 = float((W + 2.0) * (W + 2.0));
    // Two rounds: the first carries points along x, then y, then z; the second
    // repairs the paths the first could not take (max error 0.25 -> 0.1 voxel,
    // tests/test_bake.cpp).
    for (int pass = 0; pass < 6; ++pass) {
        const int axis = pass % 3;
        const auto rows = chains(topo.leaves, axis);
        const int stride = axis == 0 ? 1 : (axis == 1 ? 8 : 64);
        const int s1 = axis == 0 ? 8 : 1, s2 = axis == 2 ? 8 : 64;  // the other two axes' strides
        for (int dir : {1, -1})
            tbb::parallel_for(size_t(0), rows.size(), [&](size_t r) {
                const auto& chain = rows[r];
                const int nc = int(chain.size());
                for (int line = 0; line < 64; ++line) {
                    const int base = (line & 7) * s1 + (line >> 3) * s2;
                    int32_t carry = -1;
                    for (int c = 0; c < nc; ++c) {
                        const int leaf = chain[size_t(dir > 0 ? c : nc - 1 - c)];
                        const int32_t* o = topo.leaves[size_t(leaf)].origin;
                        int32_t* sl = src.data() + size_t(leaf) * kLeafVoxels;
                        float* dl = d2.data() + size_t(leaf) * kLeafVoxels;
                        for (int s = 0; s < 8; ++s) {
                            const int a = dir > 0 ? s : 7 - s;
                            const int i = base + a * stride;
                            if (carry >= 0) {
                                const SurfacePoint& sp = points[size_t(carry)];
                                const float dx = float(o[0] + (i & 7)) - sp.p[0],
                                            dy = float(o[1] + ((i >> 3) & 7)) - sp.p[1],
                                            dz = float(o[2] + (i >> 6)) - sp.p[2];
                                const float dd = dx * dx + dy * dy + dz * dz;
                                if (dd < dl[i] && dd < limit2) {
                                    dl[i] = dd;
                                    sl[i] = carry;
                                }
                            }
                            carry = sl[i];
                        }
                    }
                }
            });
    }
    d2 = {};
    progress("assembly", 0.5);
    if (std::getenv("CAMBIUM_TIMING"))
        fmt::print(stderr, "sweeps done {:.3f} s\n", since(t));

    // 5. Grids.
    out.surface = openvdb::FloatGrid::create(background);
    out.color = openvdb::Vec3fGrid::create(openvdb::Vec3f(0.0f));
    const auto xform = openvdb::math::Transform::createLinearTransform(h);
    out.surface->setTransform(xform);
    out.color->setTransform(xform->copy());
    std::vector<openvdb::FloatTree::LeafNodeType*> sLeaves(n, nullptr);
    std::vector<openvdb::Vec3fTree::LeafNodeType*> cLeaves(n, nullptr);
    std::vector<size_t> activeCount(n, 0);
    tbb::parallel_for(size_t(0), n, [&](size_t l) {
        const int32_t* o = topo.leaves[l].origin;
        const openvdb::Coord origin(o[0], o[1], o[2]);
        auto* sl = new openvdb::FloatTree::LeafNodeType(origin, background, false);
        auto* cl = new openvdb::Vec3fTree::LeafNodeType(origin, openvdb::Vec3f(0.0f), false);
        size_t active = 0;
        for (int i = 0; i < kLeafVoxels; ++i) {
            const int x = i & 7, y = (i >> 3) & 7, z = i >> 6;
            const bool inside = value[l * kLeafVoxels + size_t(i)] > Tf;
            // VDB leaves index x slowest: offset = 64 x + 8 y + z.
            const openvdb::Index off = openvdb::Index(64 * x + 8 * y + z);
            float v = inside ? -background : background;
            const int32_t si = src[l * kLeafVoxels + size_t(i)];
            if (si >= 0) {
                const SurfacePoint& sp = points[size_t(si)];
                const glm::vec3 d(float(o[0] + x) - sp.p[0], float(o[1] + y) - sp.p[1],
                                  float(o[2] + z) - sp.p[2]);
                const float euclid = glm::length(d);
                float plane = (d.x * float(sp.n[0]) + d.y * float(sp.n[1]) + d.z * float(sp.n[2])) / 32767.0f;
                // The tangent plane's distance, where it agrees with the field's sign
                // and does not exceed the distance to the point itself.
                if ((plane < 0.0f) != inside || std::abs(plane) > euclid)
                    plane = inside ? -euclid : euclid;
                const float sd = plane * float(h);
                if (std::abs(sd) < background) {
                    sl->setValueOn(off, sd);
                    cl->setValueOn(off, openvdb::Vec3f(sp.rgb[0], sp.rgb[1], sp.rgb[2]) / 255.0f);
                    ++active;
                    continue;
                }
            }
            sl->setValueOnly(off, v);
        }
        activeCount[l] = active;
        if (active) {
            sLeaves[l] = sl;
            cLeaves[l] = cl;
        } else {
            delete sl;
            delete cl;
        }
    });
    value = {};
    src = {};
    points = {};
    for (size_t l = 0; l < n; ++l)
        if (sLeaves[l]) {
            out.surface->tree().addLeaf(sLeaves[l]);
            out.color->tree().addLeaf(cLeaves[l]);
            ++st.activeLeaves;
            st.activeVoxels += activeCount[l];
        }
    openvdb::tools::signedFloodFill(out.surface->tree());
    out.surface->setGridClass(openvdb::GRID_LEVEL_SET);
    out.surface->setName("surface");
    out.color->setName("Cd");
    out.color->setVectorType(openvdb::VEC_INVARIANT);
    if (opt.fog) {
        out.density = out.surface->deepCopy();
        openvdb::tools::sdfToFogVolume(*out.density);
        out.density->setName("density");
    }
    st.assemblySeconds = since(t);
    st.seconds = since(start);
    progress("assembly", 1.0);
    return out;
}

}  // namespace cambium
