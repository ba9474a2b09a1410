// cambium — bark colour from a photograph.
#include "bake/bark_photo.h"

#include "core/error.h"
#include "core/math.h"
#include "io/image_file.h"

#include <fmt/format.h>
#include <glm/gtc/noise.hpp>
#include <openvdb/tree/LeafManager.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>

namespace cambium {

namespace {

int quantise(double v)
{
    return std::clamp(int(std::floor(v * ColourHistogram::kLevels)), 0,
                      ColourHistogram::kLevels - 1);
}

int keyOf(const glm::dvec3& c)
{
    constexpr int L = ColourHistogram::kLevels;
    return (quantise(c.r) * L + quantise(c.g)) * L + quantise(c.b);
}

double luminance(const glm::dvec3& c)
{
    return 0.2126 * c.r + 0.7152 * c.g + 0.0722 * c.b;
}

uint64_t mix(uint64_t h)
{
    h ^= h >> 30;
    h *= 0xbf58476d1ce4e5b9ull;
    h ^= h >> 27;
    h *= 0x94d049bb133111ebull;
    return h ^ (h >> 31);
}

/// The coherent noise before its calibration: two octaves of Perlin noise on
/// a cylinder of the bark's coordinates (about 30 patches a turn, 25 cm long).
double coherentNoise(double s, double cosTheta, double sinTheta, uint64_t seed)
{
    const glm::vec3 offset(float(mix(seed) >> 40) * 1e-4f, float(mix(seed + 1) >> 40) * 1e-4f,
                           0.0f);
    float n = 0.0f, a = 1.0f, f = 1.0f;
    for (int o = 0; o < 2; ++o) {
        const glm::vec3 p(float(5.0 * cosTheta) * f, float(5.0 * sinTheta) * f, float(4.0 * s) * f);
        n += a * glm::perlin(p + offset);
        a *= 0.5f;
        f *= 2.0f;
    }
    return double(n);
}

/// The noise's distribution, measured once: 4096 quantiles of 2^18 samples.
const std::vector<double>& noiseQuantiles()
{
    static const std::vector<double> q = [] {
        std::vector<double> v(size_t(1) << 18);
        for (size_t i = 0; i < v.size(); ++i) {
            const double s = double(mix(i * 2 + 1) >> 11) * 0x1.0p-53 * 50.0;
            const double t = double(mix(i * 2 + 2) >> 11) * 0x1.0p-53 * 6.283185307179586;
            v[i] = coherentNoise(s, std::cos(t), std::sin(t), 1);
        }
        std::sort(v.begin(), v.end());
        std::vector<double> out(4097);
        for (size_t k = 0; k <= 4096; ++k)
            out[k] = v[std::min(v.size() - 1, k * (v.size() - 1) / 4096)];
        return out;
    }();
    return q;
}

/// A cone's axis and bark coordinates.
struct BarkCone {
    glm::dvec3 p0, axis, reference, side;
    double len, r0, r1, s0;
};

}  // namespace

ColourHistogram ColourHistogram::fromPhoto(const std::string& path)
{
    const Photo p = readPhoto(path);
    return fromPixels(p.rgb);
}

ColourHistogram ColourHistogram::fromPixels(const std::vector<float>& rgb)
{
    std::map<int, std::pair<double, glm::dvec3>> bins;  // key -> count, colour sum
    const size_t n = rgb.size() / 3;
    if (n == 0)
        throw InputError("a bark photo needs at least one pixel");
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 c(rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]);
        auto& b = bins[keyOf(c)];
        b.first += 1.0;
        b.second += c;
    }
    struct Bin {
        int key;
        double count;
        glm::dvec3 mean;
    };
    std::vector<Bin> order;
    for (const auto& [key, b] : bins)
        order.push_back({key, b.first, b.second / b.first});
    std::sort(order.begin(), order.end(), [](const Bin& a, const Bin& b) {
        const double la = luminance(a.mean), lb = luminance(b.mean);
        return la != lb ? la < lb : a.key < b.key;
    });
    ColourHistogram h;
    double sum = 0.0;
    for (const Bin& b : order) {
        h.colour_.push_back(b.mean);
        h.share_.push_back(b.count / double(n));
        h.key_.push_back(b.key);
        sum += b.count;
        h.cumulative_.push_back(sum / double(n));
    }
    h.cumulative_.back() = 1.0;
    return h;
}

size_t ColourHistogram::bin(double u) const
{
    const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), u);
    return std::min(size_t(it - cumulative_.begin()), cumulative_.size() - 1);
}

size_t ColourHistogram::binOf(const glm::dvec3& rgb) const
{
    const int key = keyOf(rgb);
    for (size_t i = 0; i < key_.size(); ++i)
        if (key_[i] == key)
            return i;
    return key_.size();
}

double randomDraw(const openvdb::Coord& v, uint64_t seed)
{
    const uint64_t h = mix(mix(mix(seed ^ 0x5eedull) ^ uint64_t(uint32_t(v.x()))) ^
                           uint64_t(uint32_t(v.y())) * 0x9e3779b97f4a7c15ull) ^
                       uint64_t(uint32_t(v.z()));
    return double(mix(h) >> 11) * 0x1.0p-53;
}

/// The noise mapped through its measured distribution to [0, 1).
static double calibrated(double n)
{
    const std::vector<double>& q = noiseQuantiles();
    const auto it = std::upper_bound(q.begin(), q.end(), n);
    const size_t k = size_t(it - q.begin());
    if (k == 0)
        return 0.0;
    if (k >= q.size())
        return std::nextafter(1.0, 0.0);
    // Linear between the quantiles around n.
    const double lo = q[k - 1], hi = q[k];
    const double f = hi > lo ? (n - lo) / (hi - lo) : 0.0;
    return std::min((double(k - 1) + f) / double(q.size() - 1), std::nextafter(1.0, 0.0));
}

double coherentDraw(double s, double theta, uint64_t seed)
{
    return calibrated(coherentNoise(s, std::cos(theta), std::sin(theta), seed));
}

bool isBarkShade(const glm::dvec3& c, const glm::dvec3& bark)
{
    const double bb = glm::dot(bark, bark);
    const double k = glm::dot(c, bark) / bb;
    return k > 0.05 && glm::length(c - k * bark) <= 0.01 * std::sqrt(bb);
}

bool hasBarkToPaint(const BlobTree& tree, const glm::dvec3& bark)
{
    for (const Node& n : tree.nodes())
        if ((n.type == NodeType::CONE || n.type == NodeType::SEGMENT) && n.prim().weight > 0.0 &&
            isBarkShade(n.shade, bark))
            return true;
    return false;
}

size_t colourBarkFromPhoto(BakedGrids& grids, const BlobTree& tree, const ColourHistogram& photo,
                           BarkColouring mode, const glm::dvec3& bark, uint64_t seed)
{
    if (!grids.color || !grids.surface)
        return 0;
    const double h = grids.surface->voxelSize()[0];
    // A model of one colour bakes Cd as a background alone: the band's
    // voxels take it, to be painted.
    grids.color->tree().topologyUnion(grids.surface->tree());
    // The cones and a hash of the cells they reach (32 voxels a side).
    std::vector<BarkCone> cones;
    for (const Node& n : tree.nodes()) {
        if (n.type != NodeType::CONE && n.type != NodeType::SEGMENT)
            continue;
        const Primitive& p = n.prim();
        const double len = glm::length(p.p1 - p.p0);
        if (!(len > 0.0) || p.weight <= 0.0)
            continue;
        BarkCone c;
        c.p0 = p.p0;
        c.axis = (p.p1 - p.p0) / len;
        c.len = len;
        c.r0 = p.r0;
        c.r1 = p.r1;
        const bool given = std::fabs(glm::dot(p.bark.reference, c.axis)) < 1e-6 &&
                           std::fabs(glm::length(p.bark.reference) - 1.0) < 1e-9;
        c.reference = given ? p.bark.reference : unitAcross(glm::dvec3(1, 0, 0), c.axis);
        c.side = glm::cross(c.axis, c.reference);
        c.s0 = given ? p.bark.s0 : 0.0;
        cones.push_back(c);
    }
    // Cells of the grid's leaves (8 voxels): each leaf looks its cones up once.
    const double cell = 8.0 * h;
    auto cellOf = [&](double x) { return int64_t(std::floor(x / cell + 0.5 / 8.0)); };
    auto key = [](int64_t x, int64_t y, int64_t z) {
        return (uint64_t(x & 0x1FFFFF) << 42) | (uint64_t(y & 0x1FFFFF) << 21) |
               uint64_t(z & 0x1FFFFF);
    };
    std::unordered_map<uint64_t, std::vector<uint32_t>> cells;
    if (mode == BarkColouring::Coherent)
        for (size_t i = 0; i < cones.size(); ++i) {
            const BarkCone& c = cones[i];
            const glm::dvec3 p1 = c.p0 + c.len * c.axis;
            const double pad = std::max(c.r0, c.r1) + 2.0 * h;
            const glm::dvec3 lo = glm::min(c.p0, p1) - pad, hi = glm::max(c.p0, p1) + pad;
            for (int64_t x = cellOf(lo.x); x <= cellOf(hi.x); ++x)
                for (int64_t y = cellOf(lo.y); y <= cellOf(hi.y); ++y)
                    for (int64_t z = cellOf(lo.z); z <= cellOf(hi.z); ++z)
                        cells[key(x, y, z)].push_back(uint32_t(i));
        }

    const double bb = glm::dot(bark, bark);
    openvdb::tree::LeafManager<openvdb::Vec3fTree> leaves(grids.color->tree());
    std::atomic<size_t> recoloured{0};
    tbb::parallel_for(leaves.leafRange(), [&](const auto& range) {
        auto phi = grids.surface->getConstAccessor();
        size_t count = 0;
        for (auto leaf = range.begin(); leaf; ++leaf) {
            const openvdb::Coord o = leaf->origin();
            const std::vector<uint32_t>* near = nullptr;
            if (mode == BarkColouring::Coherent) {
                const auto it = cells.find(key(o.x() >> 3, o.y() >> 3, o.z() >> 3));
                if (it == cells.end())
                    continue;
                near = &it->second;
            }
            for (auto v = leaf->beginValueOn(); v; ++v) {
                const openvdb::Coord ijk = v.getCoord();
                if (std::fabs(phi.getValue(ijk)) > 1.5 * h)
                    continue;
                const openvdb::Vec3f cv = v.getValue();
                const glm::dvec3 c(cv[0], cv[1], cv[2]);
                if (!isBarkShade(c, bark))
                    continue;  // not bark (a leaf, or bark blended with one)
                const double k = glm::dot(c, bark) / bb;
                double u;
                if (mode == BarkColouring::Random) {
                    u = randomDraw(ijk, seed);
                } else {
                    const openvdb::Vec3d w = grids.surface->indexToWorld(ijk);
                    const glm::dvec3 p(w[0], w[1], w[2]);
                    double best = 1e300, s = 0.0, ex = 1.0, ey = 0.0;
                    for (uint32_t i : *near) {
                        const BarkCone& cn = cones[i];
                        const glm::dvec3 d = p - cn.p0;
                        const double tt = glm::dot(d, cn.axis) / cn.len;
                        const double t = std::clamp(tt, 0.0, 1.0);
                        const glm::dvec3 e = d - t * cn.len * cn.axis;
                        // Beyond an end, a cone is as far as the point is past it
                        // (its continuation holds the point's bark).
                        const double gap = glm::length(e) - (cn.r0 + (cn.r1 - cn.r0) * t) +
                                           std::fabs(tt - t) * cn.len;
                        if (gap < best) {
                            best = gap;
                            s = cn.s0 + tt * cn.len;  // on past the ends, as the furrows
                            ex = glm::dot(e, cn.reference);
                            ey = glm::dot(e, cn.side);
                        }
                    }
                    if (best == 1e300)
                        continue;
                    const double len = std::hypot(ex, ey);
                    u = len > 0.0 ? calibrated(coherentNoise(s, ex / len, ey / len, seed))
                                  : coherentDraw(s, 0.0, seed);
                }
                const glm::dvec3 drawn = k * photo.colour(photo.bin(u));
                v.setValue(openvdb::Vec3f(float(drawn.r), float(drawn.g), float(drawn.b)));
                ++count;
            }
        }
        recoloured += count;
    });
    return recoloured;
}

}  // namespace cambium
