// cambium — triangle mesh files: OBJ and binary PLY written, OBJ and PLY read.
#include "io/mesh_file.h"

#include "core/error.h"
#include "core/files.h"
#include "core/math.h"

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <ostream>
#include <sstream>

namespace cambium {

void TriangleMesh::addPolygon(const uint32_t* c, size_t n)
{
    polygons.sizes.push_back(uint32_t(n));
    polygons.corners.insert(polygons.corners.end(), c, c + n);
    for (size_t k = 1; k + 1 < n; ++k)
        triangles.push_back({c[0], c[k], c[k + 1]});
}

namespace {

[[noreturn]] void fail(const std::string& path, size_t line, const std::string& what)
{
    throw InputError(line ? fmt::format("{}:{}: {}", path, line, what)
                          : fmt::format("{}: {}", path, what));
}

/// Refuses a vertex value that is not finite, or a coordinate beyond
/// kFarthestCoordinate (no tool here draws, meshes or bakes one; Embree's
/// builds overflow on them).  `name()` names the vertex as the file counts
/// (made only for a message: this runs for every value of a mesh).
template <class Name>
void checkVertexValue(double v, bool coordinate, const std::string& path, size_t line,
                      const Name& name)
{
    if (std::isfinite(v) && (!coordinate || std::abs(v) <= kFarthestCoordinate))
        return;
    const std::string vertex = name();
    if (!std::isfinite(v))
        fail(path, line, fmt::format("{} has a value {} (not a finite number)", vertex, v));
    if (coordinate && std::abs(v) > kFarthestCoordinate)
        fail(path, line,
             fmt::format("{} lies {:g} from the origin, beyond the {:g} cambium reads", vertex,
                         std::abs(v), kFarthestCoordinate));
}

/// The next whitespace-separated token of `s` as a number (strtod's: "inf",
/// "nan" and 1e300 are numbers, for the checks after to name); false when
/// there is none or it is not a number (0x10 is not: strtod reads it as 16).
bool readNumber(std::istream& s, double& v)
{
    std::string token;
    if (!(s >> token))
        return false;
    char* end = nullptr;
    v = std::strtod(token.c_str(), &end);
    return end != token.c_str() && *end == '\0' && !writtenInHex(token.c_str(), end);
}

/// The lines of a text file (an OBJ, a PLY header or ASCII body), counted
/// from 1: a line ends at LF, CRLF or, where `bareCr`, a lone CR (old Mac
/// files); a UTF-8 byte-order mark before the first line is read past.  A
/// NUL byte is refused with its line: a text line holds none, and strtol
/// and strtod would stop at it and take what went before as the value.
class TextLines {
public:
    TextLines(std::istream& in, const std::string& path, bool bareCr)
        : in_(in), path_(path), bareCr_(bareCr)
    {
    }
    bool next(std::string& text)
    {
        if (!more_) {
            if (!std::getline(in_, chunk_))
                return false;
            if (!chunk_.empty() && chunk_.back() == '\r')
                chunk_.pop_back();
            if (line_ == 0 && chunk_.rfind("\xEF\xBB\xBF", 0) == 0)
                chunk_.erase(0, 3);
            pos_ = 0;
            more_ = true;
        }
        ++line_;
        const size_t cr = chunk_.find('\r', pos_);
        if (cr == std::string::npos) {
            text.assign(chunk_, pos_, std::string::npos);
            more_ = false;
        } else {
            if (!bareCr_)
                fail(path_, line_, "the line ends with a lone carriage return (lines end with LF)");
            text.assign(chunk_, pos_, cr - pos_);
            pos_ = cr + 1;
        }
        if (text.find('\0') != std::string::npos)
            fail(path_, line_, "the line holds a NUL byte (a text file has none)");
        return true;
    }
    size_t line() const { return line_; }

private:
    std::istream& in_;
    const std::string& path_;
    bool bareCr_;
    std::string chunk_;
    size_t pos_ = 0, line_ = 0;
    bool more_ = false;
};

/// Fans a polygon (indices into the points, checked) into triangles.  A
/// bad one is named as the file wrote it: `written` (its indices as
/// written), `where` (" (face 3)" for a PLY face; OBJ names the line).
void addPolygon(TriangleMesh& m, const std::vector<int64_t>& poly,
                const std::vector<int64_t>& written, const std::string& path, size_t line,
                const std::string& where)
{
    if (poly.size() < 3)
        fail(path, line,
             fmt::format("a face needs at least 3 vertices (got {}){}", poly.size(), where));
    for (size_t i = 0; i < poly.size(); ++i)
        if (poly[i] < 0 || size_t(poly[i]) >= m.points.size())
            fail(path, line,
                 fmt::format("vertex index {} out of range (the file has {} vertices{}){}",
                             written[i], m.points.size(), line ? " before it" : "", where));
    std::vector<uint32_t> corners(poly.begin(), poly.end());
    m.addPolygon(corners.data(), corners.size());
}

TriangleMesh readObj(std::istream& in, const std::string& path)
{
    TriangleMesh m;
    std::vector<openvdb::math::Vec3s> normals;
    std::vector<std::pair<size_t, int64_t>> cornerNormals;  // (point, normal) pairs from the faces
    std::string text;
    TextLines lines(in, path, true);
    std::vector<int64_t> poly, written;
    while (lines.next(text)) {
        const size_t line = lines.line();
        std::istringstream s(text);
        std::string tag;
        if (!(s >> tag) || tag[0] == '#')
            continue;
        if (tag == "v" || tag == "vn") {
            double x[6];
            int n = 0;
            while (n < 6 && readNumber(s, x[n]))
                ++n;
            if (n < 3 || (tag == "v" && n != 3 && n != 4 && n != 6) || (tag == "vn" && n != 3))
                fail(path, line,
                     fmt::format("'{}' expects 3 numbers{}", tag,
                                 tag == "v" ? " (4 with a weight, which polygons ignore, or 6 "
                                              "with a colour)"
                                            : ""));
            for (int k = 0; k < n; ++k)
                checkVertexValue(x[k], tag == "v" && k < 3, path, line, [&] {
                    return tag == "v" ? fmt::format("vertex {}", m.points.size() + 1)
                                      : fmt::format("normal {}", normals.size() + 1);
                });
            if (tag == "vn") {
                normals.emplace_back(float(x[0]), float(x[1]), float(x[2]));
                continue;
            }
            m.points.emplace_back(float(x[0]), float(x[1]), float(x[2]));
            if (n == 6) {
                if (m.colors.size() + 1 != m.points.size())
                    fail(path, line, "some vertices have colours and others not");
                // (a colour of 1e30 made a picture of 1e30 with exit 0)
                for (int k = 3; k < 6; ++k)
                    if (!(x[k] >= 0.0 && x[k] <= 1.0))
                        fail(path, line,
                             fmt::format("vertex {}: colour {:g} is outside 0-1", m.points.size(),
                                         x[k]));
                m.colors.emplace_back(float(x[3]), float(x[4]), float(x[5]));
            }
        } else if (tag == "f") {
            poly.clear();
            written.clear();
            std::string corner;
            while (s >> corner) {
                // v, v/vt, v/vt/vn or v//vn; negative indices count from the end.
                char* end = nullptr;
                errno = 0;
                const long v = std::strtol(corner.c_str(), &end, 10);
                if (end == corner.c_str() || v == 0 || errno == ERANGE ||
                    (*end != '\0' && *end != '/'))
                    fail(path, line, fmt::format("bad face corner '{}'", corner));
                const int64_t vi = v > 0 ? v - 1 : int64_t(m.points.size()) + v;
                poly.push_back(vi);
                written.push_back(v);
                const auto slash1 = corner.find('/');
                const auto slash2 =
                    slash1 == std::string::npos ? slash1 : corner.find('/', slash1 + 1);
                if (slash2 != std::string::npos && slash2 + 1 < corner.size()) {
                    const long n = std::strtol(corner.c_str() + slash2 + 1, &end, 10);
                    if (n == 0 || *end != '\0')
                        fail(path, line, fmt::format("bad normal index in '{}'", corner));
                    cornerNormals.emplace_back(size_t(vi),
                                               n > 0 ? n - 1 : int64_t(normals.size()) + n);
                }
            }
            addPolygon(m, poly, written, path, line, "");
        }
        // Other statements (vt, o, g, s, usemtl, mtllib, l, ...) do not change the surface.
    }
    if (!m.colors.empty() && m.colors.size() != m.points.size())
        fail(path, 0, "some vertices have colours and others not");
    if (!cornerNormals.empty()) {
        m.normals.assign(m.points.size(), openvdb::math::Vec3s(0.0f));
        for (const auto& [p, n] : cornerNormals) {
            if (n < 0 || size_t(n) >= normals.size())
                fail(path, 0,
                     fmt::format("normal index {} out of range ({} normals)", n + 1,
                                 normals.size()));
            m.normals[p] = normals[size_t(n)];
        }
    }
    return m;
}

/// A PLY scalar type: its size in bytes, whether it is a floating-point
/// type, and its little-endian reader.
struct PlyType {
    int size = 0;
    bool real = false;
    double (*read)(const char*) = nullptr;
};

template <class T>
double readAs(const char* p)
{
    T v;
    std::memcpy(&v, p, sizeof(T));
    return double(v);
}

PlyType plyType(const std::string& name, const std::string& path, size_t line)
{
    static const struct {
        const char *name, *alias;
        PlyType type;
    } types[] = {{"char", "int8", {1, false, readAs<int8_t>}},
                 {"uchar", "uint8", {1, false, readAs<uint8_t>}},
                 {"short", "int16", {2, false, readAs<int16_t>}},
                 {"ushort", "uint16", {2, false, readAs<uint16_t>}},
                 {"int", "int32", {4, false, readAs<int32_t>}},
                 {"uint", "uint32", {4, false, readAs<uint32_t>}},
                 {"float", "float32", {4, true, readAs<float>}},
                 {"double", "float64", {8, true, readAs<double>}}};
    for (const auto& t : types)
        if (name == t.name || name == t.alias)
            return t.type;
    fail(path, line, fmt::format("unknown PLY type '{}'", name));
}

struct PlyProperty {
    std::string name;
    PlyType type, countType;  // countType.size > 0 for a list
};
struct PlyElement {
    std::string name;
    size_t count = 0;
    std::vector<PlyProperty> properties;
};

/// A PLY header: its format and its elements, in order.
struct PlyHeader {
    std::string format;
    std::vector<PlyElement> elements;
};

PlyHeader readPlyHeader(TextLines& lines, const std::string& path)
{
    PlyHeader h;
    std::string text;
    if (!lines.next(text) || text != "ply")
        fail(path, 1, "not a PLY file (its first line is not 'ply')");
    while (true) {
        if (!lines.next(text))
            fail(path, lines.line(), "the header has no end_header");
        const size_t line = lines.line();
        std::istringstream s(text);
        std::string tag;
        s >> tag;
        if (tag == "end_header")
            break;
        if (tag == "format") {
            std::string version;
            s >> h.format >> version;
            if (h.format != "ascii" && h.format != "binary_little_endian")
                fail(path, line,
                     fmt::format("PLY format '{}' is not read (ascii and binary_little_endian are)",
                                 printable(h.format)));
            if (version != "1.0")
                fail(path, line,
                     fmt::format("PLY version '{}' is not read (1.0 is)", printable(version)));
        } else if (tag == "element") {
            PlyElement e;
            std::string count;
            if (!(s >> e.name >> count))
                fail(path, line, "expected 'element NAME COUNT'");
            errno = 0;
            char* end = nullptr;
            e.count = std::strtoull(count.c_str(), &end, 10);
            if (!std::isdigit(static_cast<unsigned char>(count[0])) || *end != '\0' ||
                errno == ERANGE)
                fail(path, line,
                     fmt::format("element '{}' has count '{}' (not a whole number of items)",
                                 printable(e.name), printable(count)));
            for (const PlyElement& before : h.elements)
                if (before.name == e.name && (e.name == "vertex" || e.name == "face"))
                    fail(path, line, fmt::format("a second '{}' element (a mesh has one)", e.name));
            h.elements.push_back(e);
        } else if (tag == "property") {
            if (h.elements.empty())
                fail(path, line, "a property before any element");
            PlyProperty p;
            std::string type;
            s >> type;
            if (type == "list") {
                std::string countType, itemType;
                s >> countType >> itemType;
                p.countType = plyType(countType, path, line);
                p.type = plyType(itemType, path, line);
            } else
                p.type = plyType(type, path, line);
            if (!(s >> p.name))
                fail(path, line, "a property without a name");
            PlyElement& e = h.elements.back();
            for (const PlyProperty& before : e.properties)
                if (before.name == p.name)
                    fail(path, line,
                         fmt::format("element '{}' has a second property '{}'", printable(e.name),
                                     printable(p.name)));
            e.properties.push_back(p);
        }
        // comment, obj_info: nothing to do.
    }
    if (h.format.empty())
        fail(path, lines.line(), "the header has no format line");
    return h;
}

/// Reads the items of element `e` (ASCII lines or binary records) into `m`:
/// the vertices' positions, normals and colours, the faces' polygons; the
/// values of other elements are read past.
void readPlyElement(std::istream& in, TextLines& lines, const std::string& path,
                    const PlyElement& e, bool ascii, TriangleMesh& m)
{
    std::string text;
    std::vector<double> values;
    std::vector<int64_t> poly;
    auto index = [&](const char* name) -> int {
        for (size_t i = 0; i < e.properties.size(); ++i)
            if (e.properties[i].name == name)
                return int(i);
        return -1;
    };
    const int x = index("x"), y = index("y"), z = index("z"), nx = index("nx"), ny = index("ny"),
              nz = index("nz"), r = index("red"), g = index("green"), b = index("blue");
    int list = index("vertex_indices");
    if (list < 0)
        list = index("vertex_index");
    if (e.name == "vertex" && (x < 0 || y < 0 || z < 0))
        fail(path, 0, "the vertex element has no x, y, z");
    if (e.name == "face" && list < 0)
        fail(path, 0, "the face element has no vertex_indices list");
    const bool colours = e.name == "vertex" && r >= 0 && g >= 0 && b >= 0;
    // Integer colours and alpha are on the 0-255 scale of the uchar every
    // tool writes, whatever their type; real ones on 0-1.
    const double colourScale = colours && e.properties[size_t(r)].type.real ? 1.0 : 1.0 / 255.0;
    const int a = e.name == "vertex" ? index("alpha") : -1;
    const double alphaScale = a < 0 || e.properties[size_t(a)].type.real ? 1.0 : 1.0 / 255.0;
    // (an integer colour beyond 255 is of a scale not read here: 16-bit, or
    // a typo; a real one beyond 1 made a picture of 1e30 with exit 0)
    auto checkScale = [&](size_t item, int k, double v) {
        const PlyProperty& p = e.properties[size_t(k)];
        const double most = p.type.real ? 1.0 : 255.0;
        if (v >= 0.0 && v <= most && (p.type.real || v == std::trunc(v)))
            return;
        fail(path, 0,
             fmt::format("vertex {} ('{}'): {:g} is not within 0-{:g} (PLY {} are whole numbers "
                         "0-255 as integers, 0-1 as reals)",
                         item, p.name, v, most, k == a ? "alphas" : "colours"));
    };
    // A binary item of no properties takes no bytes: its count, however
    // large, reads nothing (and must not loop over 2^64 items).
    if (!ascii && e.properties.empty())
        return;
    for (size_t item = 0; item < e.count; ++item) {
        values.assign(e.properties.size(), 0.0);
        poly.clear();
        std::istringstream s;
        if (ascii) {
            if (!lines.next(text))
                fail(path, 0,
                     fmt::format("the file ends inside element '{}' ({} of {})", e.name, item,
                                 e.count));
            s.str(text);
        }
        for (size_t k = 0; k < e.properties.size(); ++k) {
            const PlyProperty& p = e.properties[k];
            auto one = [&](const PlyType& t) {
                double v = 0.0;
                if (ascii) {
                    if (!readNumber(s, v))
                        fail(path, 0,
                             fmt::format("element '{}' {}: too few values, or one not a number",
                                         e.name, item));
                } else {
                    char buf[8];
                    if (!in.read(buf, t.size))
                        fail(path, 0,
                             fmt::format("the file ends inside element '{}' ({} of {})", e.name,
                                         item, e.count));
                    v = t.read(buf);
                }
                return v;
            };
            if (p.countType.size == 0) {
                values[k] = one(p.type);
                continue;
            }
            const double n = one(p.countType);
            if (!(n >= 0.0 && n < 1e6) || n != std::trunc(n))
                fail(path, 0,
                     fmt::format("element '{}' {}: a list of {} items (a count is a whole "
                                 "number below a million)",
                                 e.name, item, n));
            for (int i = 0; i < int(n); ++i) {
                const double v = one(p.type);
                if (int(k) != list)
                    continue;
                if (!(std::abs(v) < 1e18) || v != std::trunc(v))
                    fail(path, 0,
                         fmt::format("element '{}' {}: vertex index {} is not a whole number",
                                     e.name, item, v));
                poly.push_back(int64_t(v));
            }
        }
        if (e.name == "vertex") {
            for (size_t k = 0; k < values.size(); ++k)
                checkVertexValue(
                    values[k], int(k) == x || int(k) == y || int(k) == z, path, 0,
                    [&] { return fmt::format("vertex {} ('{}')", item, e.properties[k].name); });
            m.points.emplace_back(float(values[size_t(x)]), float(values[size_t(y)]),
                                  float(values[size_t(z)]));
            if (nx >= 0 && ny >= 0 && nz >= 0)
                m.normals.emplace_back(float(values[size_t(nx)]), float(values[size_t(ny)]),
                                       float(values[size_t(nz)]));
            if (colours)
                for (int k : {r, g, b})
                    checkScale(item, k, values[size_t(k)]);
            if (a >= 0)
                checkScale(item, a, values[size_t(a)]);
            if (colours)
                m.colors.emplace_back(float(values[size_t(r)] * colourScale),
                                      float(values[size_t(g)] * colourScale),
                                      float(values[size_t(b)] * colourScale));
            if (a >= 0)
                m.alpha.push_back(float(values[size_t(a)] * alphaScale));
        } else if (e.name == "face") {
            addPolygon(m, poly, poly, path, 0, fmt::format(" (face {})", item));
        }
    }
}

TriangleMesh readPly(std::istream& in, const std::string& path)
{
    TextLines lines(in, path, false);
    const PlyHeader h = readPlyHeader(lines, path);
    TriangleMesh m;
    const bool ascii = h.format == "ascii";
    for (const PlyElement& e : h.elements)
        readPlyElement(in, lines, path, e, ascii, m);
    return m;
}

/// Unit vertex normals, area-weighted from the triangles (outward for
/// counter-clockwise triangles).
std::vector<openvdb::math::Vec3s> vertexNormals(const TriangleMesh& m)
{
    std::vector<openvdb::math::Vec3s> n(m.points.size(), openvdb::math::Vec3s(0.0f));
    for (const auto& t : m.triangles) {
        const openvdb::math::Vec3s c =
            (m.points[t[1]] - m.points[t[0]]).cross(m.points[t[2]] - m.points[t[0]]);
        for (uint32_t v : t)
            n[v] += c;
    }
    for (auto& v : n)
        v.normalize();
    return n;
}

}  // namespace

TriangleMesh parseMesh(std::istream& in, const std::string& name, const std::string& format)
{
    TriangleMesh m = format == "obj" ? readObj(in, name) : readPly(in, name);
    if (m.triangles.empty())
        fail(name, 0, "the mesh has no faces");
    // (A mesh of no area draws, frames and bakes as nothing, with exit 0.)
    // The largest face's area, exactly (double) and as the float
    // arithmetic of every later stage sees it.
    double largest = 0.0;
    bool flat = true;
    for (const auto& t : m.triangles) {
        const auto e1 = m.points[t[1]] - m.points[t[0]], e2 = m.points[t[2]] - m.points[t[0]];
        flat = flat && !(e1.cross(e2).lengthSqr() > 0.0f);
        largest = std::max(largest,
                           0.5 * openvdb::math::Vec3d(e1).cross(openvdb::math::Vec3d(e2)).length());
    }
    if (!(largest > 0.0))
        fail(name, 0, "the mesh has no area: every face's corners lie on one line or at one point");
    if (flat)
        fail(name, 0,
             fmt::format("the mesh is too small for single precision: its largest face's area "
                         "is {:.3g}, below the about 1e-19 that float arithmetic resolves",
                         largest));
    if (m.normals.size() != m.points.size())
        m.normals = vertexNormals(m);
    return m;
}

TriangleMesh readMesh(const std::string& path)
{
    const std::string ext = fileFormat(path, {"obj", "ply"}, "mesh");
    checkInputFile(path, "mesh file");
    std::ifstream in(path, std::ios::binary);
    if (!in)
        fail(path, 0, "cannot open it");
    return parseMesh(in, path, ext);
}

namespace {

size_t faceCount(const TriangleMesh& m)
{
    return m.polygons.empty() ? m.triangles.size() : m.polygons.sizes.size();
}

/// Each face as the file should hold it: the polygons when there are, else
/// the triangles.
template <class F>
void forEachFace(const TriangleMesh& m, const F& f)
{
    if (m.polygons.empty()) {
        for (const auto& t : m.triangles)
            f(t.data(), size_t(3));
        return;
    }
    size_t c = 0;
    for (uint32_t n : m.polygons.sizes) {
        f(m.polygons.corners.data() + c, size_t(n));
        c += n;
    }
}

uint8_t toByte(float v)
{
    return uint8_t(std::lround(255.0f * std::clamp(v, 0.0f, 1.0f)));
}

void writeObj(const TriangleMesh& m, std::ostream& out)
{
    fmt::memory_buffer buf;
    auto drain = [&](bool last) {
        if (last || buf.size() > (size_t(1) << 20)) {
            out.write(buf.data(), std::streamsize(buf.size()));
            buf.clear();
        }
    };
    fmt::format_to(std::back_inserter(buf), "# cambium mesh: {} vertices, {} {}\n", m.points.size(),
                   faceCount(m), m.polygons.empty() ? "triangles" : "faces");
    for (size_t i = 0; i < m.points.size(); ++i) {
        const auto& p = m.points[i];
        if (m.colors.empty())
            fmt::format_to(std::back_inserter(buf), "v {} {} {}\n", p[0], p[1], p[2]);
        else
            fmt::format_to(std::back_inserter(buf), "v {} {} {} {:.4g} {:.4g} {:.4g}\n", p[0], p[1],
                           p[2], m.colors[i][0], m.colors[i][1], m.colors[i][2]);
        drain(false);
    }
    for (const auto& nrm : m.normals) {
        fmt::format_to(std::back_inserter(buf), "vn {:.5g} {:.5g} {:.5g}\n", nrm[0], nrm[1],
                       nrm[2]);
        drain(false);
    }
    forEachFace(m, [&](const uint32_t* c, size_t n) {
        buf.push_back('f');
        for (size_t k = 0; k < n; ++k)  // OBJ counts from 1
            fmt::format_to(std::back_inserter(buf), " {}//{}", c[k] + 1, c[k] + 1);
        buf.push_back('\n');
        drain(false);
    });
    drain(true);
}

void writePlyHeader(const TriangleMesh& m, std::ostream& out)
{
    const bool rgb = !m.colors.empty();
    out << "ply\nformat binary_little_endian 1.0\ncomment cambium mesh\n"
        << "element vertex " << m.points.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\n"
        << "property float nx\nproperty float ny\nproperty float nz\n";
    if (rgb)
        out << "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    out << "element face " << faceCount(m)
        << "\nproperty list uchar uint vertex_indices\nend_header\n";
}

/// The binary PLY's vertices and faces after its header (`at` bytes), made
/// and written a piece at a time on all cores (pwrite at each piece's place:
/// the kernel's copies into the page cache, a second a 500 MB mesh on one
/// core, run side by side too).
void writePlyBody(const TriangleMesh& m, WrittenFile& file, uint64_t at)
{
    static_assert(sizeof(float) == 4 && sizeof(uint32_t) == 4, "PLY float and uint are 4 bytes");
    static_assert(sizeof(std::array<uint32_t, 3>) == 12, "triangles lie one after another");
    // x86 and ARM are little-endian: the values are written as they are.
    const bool rgb = !m.colors.empty();
    const size_t vsize = 24 + (rgb ? 3 : 0), nv = m.points.size();
    constexpr size_t kPiece = size_t(1) << 16;  // vertices or faces a piece (1-2 MB)
    tbb::enumerable_thread_specific<std::vector<char>> buffers;
    tbb::parallel_for(size_t(0), (nv + kPiece - 1) / kPiece, [&](size_t k) {
        std::vector<char>& buf = buffers.local();
        const size_t begin = k * kPiece, end = std::min(nv, begin + kPiece);
        buf.resize((end - begin) * vsize);
        for (size_t i = begin; i < end; ++i) {
            char* v = buf.data() + (i - begin) * vsize;
            std::memcpy(v, m.points[i].asPointer(), 12);
            std::memcpy(v + 12, m.normals[i].asPointer(), 12);
            if (rgb)
                for (int c = 0; c < 3; ++c)
                    v[24 + c] = char(toByte(m.colors[i][c]));
        }
        file.write(at + begin * vsize, buf.data(), buf.size());
    });
    at += nv * vsize;
    // Faces: a count byte and the corners; each piece's place from the
    // corners before it.
    const size_t nf = faceCount(m), pieces = (nf + kPiece - 1) / kPiece;
    const bool triangles = m.polygons.empty();
    std::vector<uint64_t> corner(pieces + 1, 0);  // corners before each piece
    for (size_t k = 0; k < pieces; ++k) {
        uint64_t n = 0;
        for (size_t f = k * kPiece; f < std::min(nf, (k + 1) * kPiece); ++f)
            n += triangles ? 3 : m.polygons.sizes[f];
        corner[k + 1] = corner[k] + n;
    }
    tbb::parallel_for(size_t(0), pieces, [&](size_t k) {
        std::vector<char>& buf = buffers.local();
        const size_t begin = k * kPiece, end = std::min(nf, begin + kPiece);
        buf.resize((end - begin) + 4 * (corner[k + 1] - corner[k]));
        char* o = buf.data();
        const uint32_t* c =
            triangles ? m.triangles[0].data() + 3 * begin : m.polygons.corners.data() + corner[k];
        for (size_t f = begin; f < end; ++f) {
            const size_t n = triangles ? 3 : m.polygons.sizes[f];
            *o++ = char(uint8_t(n));
            std::memcpy(o, c, 4 * n);
            o += 4 * n;
            c += n;
        }
        file.write(at + begin + 4 * corner[k], buf.data(), buf.size());
    });
}

}  // namespace

void checkMeshOutput(const std::string& path)
{
    fileFormat(path, {"obj", "ply"}, "mesh");
    checkOutputPath(path);
}

void writeMesh(const TriangleMesh& mesh, const std::string& path)
{
    const std::string ext = fileFormat(path, {"obj", "ply"}, "mesh");
    if (ext == "obj") {
        writeFile(path, [&](std::ostream& out) { writeObj(mesh, out); });
        return;
    }
    writeFile(
        path, [&](std::ostream& out) { writePlyHeader(mesh, out); },
        [&](WrittenFile& file) { writePlyBody(mesh, file, file.size()); });
}

}  // namespace cambium
