// cambium — JSON scene reader.
#include "blobtree/scene_io.h"

#include "core/error.h"
#include "core/json.h"
#include "core/math.h"

#include <fmt/format.h>

#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

namespace cambium {

namespace {

using json = nlohmann::json;

constexpr double kDegree = M_PI / 180.0;

std::vector<std::string> fieldsOf(NodeType t)
{
    switch (t) {
        case NodeType::SPHERE:
            return {"center", "radius", "support", "weight"};
        case NodeType::SEGMENT:
            return {"p0", "p1", "radius", "support", "weight"};
        case NodeType::CONE:
            return {"p0", "p1", "r0", "r1", "support", "weight"};
        case NodeType::CONVOLUTION_SEGMENT:
            return {"p0", "p1", "r0", "r1", "kernel_width", "support", "weight"};
        case NodeType::BLEND:
        case NodeType::UNION:
        case NodeType::INTERSECTION:
        case NodeType::DIFFERENCE:
            return {"children"};
        case NodeType::RICCI:
            return {"children", "n"};
        case NodeType::PCM:
            return {"children", "width", "attenuation", "darken"};
        case NodeType::BETTER_BLEND:
            return {"children", "k"};
        case NodeType::GBB:
            return {"children", "bound", "b1", "b2"};
        case NodeType::TRANSFORM:
            return {"children", "translate", "rotate", "scale", "matrix"};
        case NodeType::BEND:
            return {"children", "p0", "p1", "direction", "angle"};
        case NodeType::TWIST:
            return {"children", "origin", "axis", "rate"};
        case NodeType::TAPER:
            return {"children", "origin", "axis", "length", "scale0", "scale1"};
    }
    return {};
}

/// Reads a scene's nodes into a BlobTree, checking each value on the way
/// (the shared JSON checks, and the node types' own).
class SceneReader : private JsonValidator {
public:
    explicit SceneReader(std::string source) : JsonValidator(std::move(source)) {}

    BlobTree read(const json& doc)
    {
        object(doc, "(top level)", "must be an object with a \"root\"");
        // (a shape file was named by its first key: "base: unknown field")
        if (doc.contains("base") && !doc.contains("root"))
            throw InputError(
                fmt::format("{}: a shape file (docs/shape-format.md), not a model: "
                            "`cambium shape` synthesises it",
                            source()));
        checkKeys(doc, "", {"threshold", "root", "name", "description", "comment", "bark"});
        double threshold = 0.5;
        if (doc.contains("threshold"))
            threshold = number(doc["threshold"], "threshold");
        const json& root = required(doc, "root", "", "a scene needs a root node");
        try {
            tree_ = BlobTree(threshold);
        } catch (const ParameterError& e) {
            fail("threshold", e.what());
        }
        tree_.setRoot(node(root, "root"));
        if (doc.contains("bark"))
            tree_.setBarkLook(barkLook(doc["bark"]));
        tree_.finalize();
        return std::move(tree_);
    }

private:
    /// "bark": {"photo": FILE, "color": [r, g, b], "colouring": ...}: the
    /// primitives of that colour take the photo's colours when baked.
    BarkLook barkLook(const json& j)
    {
        object(j, "bark",
               "must be {\"photo\": \"bark.jpg\", \"color\": [r, g, b]} (the colour of the "
               "primitives the photo recolours)");
        checkKeys(j, "bark", {"photo", "color", "colouring"});
        BarkLook look;
        look.photo =
            inputFile(required(j, "photo", "bark"), "bark.photo",
                      std::filesystem::path(source()).parent_path().string(), "bark photo");
        const glm::dvec3 c =
            vec3(required(j, "color", "bark", "the colour of the bark's primitives"), "bark.color");
        for (int k = 0; k < 3; ++k)
            if (!(c[k] >= 0.0 && c[k] <= 1.0))
                fail(fmt::format("bark.color[{}]", k), "must be from 0 to 1");
        look.color = c;
        if (j.contains("colouring"))
            look.coherent = choice(j["colouring"], "bark.colouring", kBarkColourings) == 0;
        return look;
    }

    glm::dvec3 vec3(const json& j, const std::string& path)
    {
        array(j, path, 3, "must be an array of 3 numbers");
        return {number(j[0], path + "[0]"), number(j[1], path + "[1]"), number(j[2], path + "[2]")};
    }

    glm::dvec3 reqVec3(const json& obj, const char* key, const std::string& path)
    {
        return vec3(required(obj, key, path), jsonPath(path, key));
    }

    std::optional<glm::dvec3> optVec3(const json& obj, const char* key, const std::string& path)
    {
        if (!obj.contains(key))
            return std::nullopt;
        return vec3(obj[key], jsonPath(path, key));
    }

    /// Reads the parameters of a blending operator from `obj` into `c`.
    /// Defaults that depend on the threshold stay valid for any threshold:
    /// a PCM width of at most T, a better-blend cut-off below T.
    void combinerParams(const json& obj, const std::string& path, Combiner& c)
    {
        const double T = tree_.threshold();
        if (c.type == NodeType::RICCI)
            c.n = optNumber(obj, "n", path).value_or(c.n);
        if (c.type == NodeType::PCM) {
            c.width = optNumber(obj, "width", path).value_or(std::min(c.width, T));
            c.attenuation = optNumber(obj, "attenuation", path).value_or(c.attenuation);
            c.darken = optNumber(obj, "darken", path).value_or(c.darken);
        }
        if (c.type == NodeType::BETTER_BLEND)
            c.k = optNumber(obj, "k", path).value_or(std::min(c.k, 0.6 * T));
    }

    /// A GBB side: {"type": "pcm", "width": ...}, a blending operator without children.
    Combiner combinerSpec(const json& j, const std::string& path)
    {
        const NodeType t = nodeType(j, path);
        static const std::set<NodeType> blending = {
            NodeType::BLEND,      NodeType::RICCI, NodeType::UNION,       NodeType::INTERSECTION,
            NodeType::DIFFERENCE, NodeType::PCM,   NodeType::BETTER_BLEND};
        if (!blending.count(t))
            fail(jsonPath(path, "type"),
                 fmt::format("'{}' cannot blend a GBB's children; use blend, ricci, union, "
                             "intersection, difference, pcm or better_blend",
                             typeName(t)));
        std::vector<std::string> allowed = fieldsOf(t);
        allowed.erase(std::remove(allowed.begin(), allowed.end(), "children"), allowed.end());
        allowed.insert(allowed.begin(), "type");
        checkKeys(j, path, allowed);
        Combiner c;
        c.type = t;
        combinerParams(j, path, c);
        return c;
    }

    NodeType nodeType(const json& j, const std::string& path)
    {
        object(j, path, "must be an object with a \"type\"");
        const std::string tpath = jsonPath(path, "type");
        const std::string name =
            string(required(j, "type", path, "every node needs a type"), tpath);
        if (auto type = typeFromName(name))
            return *type;
        std::vector<std::string> names;
        for (NodeType k : allNodeTypes())
            names.push_back(typeName(k));
        fail(tpath, fmt::format("unknown node type '{}'{}; known types: {}", name,
                                didYouMean(name, names), joinWords(names)));
    }

    std::vector<int> children(const json& j, const std::string& path, NodeType t)
    {
        const std::string cpath = jsonPath(path, "children");
        if (!j.contains("children"))
            fail(cpath, fmt::format("missing: a '{}' needs children", typeName(t)));
        const json& c = j["children"];
        if (!c.is_array())
            fail(cpath, fmt::format("must be an array of nodes (got {})", jsonKind(c)));
        if (c.empty())
            fail(cpath, fmt::format("is empty: a '{}' needs at least one child", typeName(t)));
        if (kindOf(t) == NodeKind::Warp && c.size() != 1)
            fail(cpath, fmt::format("a '{}' warps exactly one child (got {}); put several in a "
                                    "blend",
                                    typeName(t), c.size()));
        std::vector<int> out;
        for (size_t i = 0; i < c.size(); ++i)
            out.push_back(node(c[i], fmt::format("{}[{}]", cpath, i)));
        return out;
    }

    glm::dmat4 transformMatrix(const json& j, const std::string& path)
    {
        const bool parts = j.contains("translate") || j.contains("rotate") || j.contains("scale");
        if (j.contains("matrix")) {
            if (parts)
                fail(jsonPath(path, "matrix"),
                     "give either a matrix or translate/rotate/scale, not both");
            const json& m = j["matrix"];
            const std::string mpath = jsonPath(path, "matrix");
            if (!m.is_array() || m.size() != 4)
                fail(mpath, "must be 4 rows of 4 numbers (row-major)");
            glm::dmat4 out(1.0);
            for (int r = 0; r < 4; ++r) {
                const std::string rpath = fmt::format("{}[{}]", mpath, r);
                if (!m[size_t(r)].is_array() || m[size_t(r)].size() != 4)
                    fail(rpath, "must be a row of 4 numbers");
                for (int c = 0; c < 4; ++c)
                    out[c][r] = number(m[size_t(r)][size_t(c)], fmt::format("{}[{}]", rpath, c));
            }
            return out;
        }
        glm::dmat4 m(1.0);
        if (auto t = optVec3(j, "translate", path))
            m = glm::translate(m, *t);
        if (j.contains("rotate")) {
            const json& r = j["rotate"];
            const std::string rpath = jsonPath(path, "rotate");
            if (!r.is_object())
                fail(rpath, "must be an object {\"axis\": [x, y, z], \"angle\": degrees}");
            checkKeys(r, rpath, {"axis", "angle"});
            const glm::dvec3 axis = unitDirection(reqVec3(r, "axis", rpath));
            if (axis == glm::dvec3(0.0))
                fail(jsonPath(rpath, "axis"), "must not be zero");
            m = glm::rotate(m, reqNumber(r, "angle", rpath) * kDegree, axis);
        }
        if (j.contains("scale")) {
            const json& s = j["scale"];
            const std::string spath = jsonPath(path, "scale");
            const glm::dvec3 v = s.is_number() ? glm::dvec3(number(s, spath)) : vec3(s, spath);
            if (v.x == 0.0 || v.y == 0.0 || v.z == 0.0)
                fail(spath, "must not be 0: a transform must be invertible");
            for (double f : {v.x, v.y, v.z})
                if (!(std::abs(f) >= 1.0 / kFarthestCoordinate &&
                      std::abs(f) <= kFarthestCoordinate))
                    fail(spath,
                         fmt::format("{:g} is beyond the scales cambium bakes ({:g} to {:g})", f,
                                     1.0 / kFarthestCoordinate, kFarthestCoordinate));
            m = glm::scale(m, v);
        }
        return m;
    }

    int node(const json& j, const std::string& path)
    {
        const NodeType t = nodeType(j, path);
        std::vector<std::string> allowed = fieldsOf(t);
        for (const char* common : {"type", "color", "name", "comment"})
            allowed.push_back(common);
        checkKeys(j, path, allowed);

        // Children first: the builders need them to exist.
        std::vector<int> kids;
        if (kindOf(t) != NodeKind::Primitive)
            kids = children(j, path, t);

        int index = -1;
        try {
            switch (t) {
                case NodeType::SPHERE: {
                    PrimitiveOptions o;
                    o.weight = optNumber(j, "weight", path).value_or(1.0);
                    o.support = optNumber(j, "support", path);
                    index =
                        tree_.sphere(reqVec3(j, "center", path), reqNumber(j, "radius", path), o);
                    break;
                }
                case NodeType::SEGMENT:
                case NodeType::CONE: {
                    PrimitiveOptions o;
                    o.weight = optNumber(j, "weight", path).value_or(1.0);
                    o.support = optNumber(j, "support", path);
                    const glm::dvec3 p0 = reqVec3(j, "p0", path), p1 = reqVec3(j, "p1", path);
                    if (t == NodeType::CONE && p0 == p1)
                        fail(jsonPath(path, "p1"),
                             "is equal to p0: a cone needs a length (a "
                             "point's field is the 'sphere' type)");
                    index = t == NodeType::SEGMENT
                                ? tree_.segment(p0, p1, reqNumber(j, "radius", path), o)
                                : tree_.cone(p0, p1, reqNumber(j, "r0", path),
                                             reqNumber(j, "r1", path), o);
                    break;
                }
                case NodeType::CONVOLUTION_SEGMENT: {
                    ConvolutionOptions o;
                    o.weight = optNumber(j, "weight", path).value_or(1.0);
                    o.kernelWidth = optNumber(j, "kernel_width", path);
                    o.support = optNumber(j, "support", path);
                    index = tree_.convolutionSegment(reqVec3(j, "p0", path), reqVec3(j, "p1", path),
                                                     reqNumber(j, "r0", path),
                                                     reqNumber(j, "r1", path), o);
                    break;
                }
                case NodeType::GBB: {
                    const int bound =
                        node(required(j, "bound", path, "a gbb needs a bounding field"),
                             jsonPath(path, "bound"));
                    Combiner b1{NodeType::PCM}, b2{NodeType::BLEND};
                    // (the default PCM took its width 0.25 whatever the
                    // threshold: refused at T = 0.2, naming an unwritten b1)
                    combinerParams(json::object(), jsonPath(path, "b1"), b1);
                    if (j.contains("b1"))
                        b1 = combinerSpec(j["b1"], jsonPath(path, "b1"));
                    if (j.contains("b2"))
                        b2 = combinerSpec(j["b2"], jsonPath(path, "b2"));
                    index = tree_.gbb(bound, kids, b1, b2);
                    break;
                }
                case NodeType::TRANSFORM:
                    index = tree_.transform(transformMatrix(j, path), kids[0]);
                    break;
                case NodeType::BEND:
                    index = tree_.bend(reqVec3(j, "p0", path), reqVec3(j, "p1", path),
                                       reqVec3(j, "direction", path),
                                       reqNumber(j, "angle", path) * kDegree, kids[0]);
                    break;
                case NodeType::TWIST:
                    index = tree_.twist(reqVec3(j, "origin", path), reqVec3(j, "axis", path),
                                        reqNumber(j, "rate", path) * kDegree, kids[0]);
                    break;
                case NodeType::TAPER:
                    index = tree_.taper(reqVec3(j, "origin", path), reqVec3(j, "axis", path),
                                        reqNumber(j, "length", path), reqNumber(j, "scale0", path),
                                        reqNumber(j, "scale1", path), kids[0]);
                    break;
                default: {
                    Combiner c;
                    c.type = t;
                    combinerParams(j, path, c);
                    index = tree_.op(c, kids);
                    break;
                }
            }
            if (j.contains("color"))
                tree_.setColor(index, vec3(j["color"], jsonPath(path, "color")));
        } catch (const ParameterError& e) {
            fail(jsonPath(path, e.field()), e.what());
        }
        return index;
    }

    BlobTree tree_;
};

}  // namespace

BlobTree parseScene(const std::string& text, const std::string& source)
{
    const json doc = parseJson(text, source);
    return SceneReader(source).read(doc);
}

BlobTree loadScene(const std::string& path)
{
    return parseScene(readTextFile(path, "scene file"), path);
}

}  // namespace cambium
