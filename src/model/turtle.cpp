// cambium — the 3D turtle.
#include "model/turtle.h"

#include "core/error.h"
#include "core/math.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace cambium {

namespace {

struct TurtleState {
    glm::dvec3 pos{0.0}, H{0.0, 1.0, 0.0}, L{1.0, 0.0, 0.0}, U{0.0, 0.0, -1.0};
    double width = 0.1;
    int colour = 0;             ///< colour index
    long long last = -1;        ///< the last internode drawn on the way here
    bool drewInBranch = false;  ///< whether `last` was drawn in the current branch
    int order = 0;
};

/// Rotates the frame about U (turn), L (pitch) or H (roll) by `deg`, as
/// ABOP's R_U, R_L and R_H act on [H L U].
void turn(TurtleState& t, double deg)
{
    const double c = std::cos(deg * kDegree), s = std::sin(deg * kDegree);
    const glm::dvec3 H = t.H * c - t.L * s, L = t.H * s + t.L * c;
    t.H = H;
    t.L = L;
}
void pitch(TurtleState& t, double deg)
{
    const double c = std::cos(deg * kDegree), s = std::sin(deg * kDegree);
    const glm::dvec3 H = t.H * c + t.U * s, U = -t.H * s + t.U * c;
    t.H = H;
    t.U = U;
}
void roll(TurtleState& t, double deg)
{
    const double c = std::cos(deg * kDegree), s = std::sin(deg * kDegree);
    const glm::dvec3 L = t.L * c + t.U * s, U = -t.L * s + t.U * c;
    t.L = L;
    t.U = U;
}

/// A filled polygon as a leaf blade: the flat ellipsoid from its first
/// vertex to the vertex farthest from it, as wide on each side as the
/// farthest vertex from that axis, across the polygon's normal (Newell).
Organ polygonLeaf(const std::vector<glm::dvec3>& v, const glm::dvec3& colour)
{
    Organ leaf;
    leaf.kind = Organ::Kind::Leaf;
    leaf.p0 = leaf.p1 = v.front();
    for (const glm::dvec3& p : v)
        if (glm::length(p - leaf.p0) > glm::length(leaf.p1 - leaf.p0))
            leaf.p1 = p;
    const glm::dvec3 axis = glm::normalize(leaf.p1 - leaf.p0);
    for (const glm::dvec3& p : v) {
        const glm::dvec3 d = p - leaf.p0;
        leaf.radius = std::max(leaf.radius, glm::length(d - glm::dot(d, axis) * axis));
    }
    glm::dvec3 n(0.0);
    for (size_t i = 0; i < v.size(); ++i) {
        const glm::dvec3 &a = v[i], &b = v[(i + 1) % v.size()];
        n += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x),
                        (a.x - b.x) * (a.y + b.y));
    }
    leaf.normal = glm::length(n) > 0.0 ? glm::normalize(n) : glm::dvec3(0.0, 0.0, 1.0);
    leaf.thickness = 0.1 * leaf.radius;
    leaf.colour = colour;
    return leaf;
}

}  // namespace

glm::dvec3 paletteColour(const LSystem& sys, int index)
{
    if (const auto c = sys.colours.find(index); c != sys.colours.end())
        return c->second;
    // Bark at 0, then greens from dark to light, then flower colours.
    static const glm::dvec3 palette[] = {
        {0.36, 0.28, 0.22}, {0.30, 0.30, 0.16}, {0.22, 0.34, 0.12}, {0.20, 0.42, 0.12},
        {0.26, 0.52, 0.16}, {0.36, 0.62, 0.20}, {0.50, 0.72, 0.26}, {0.66, 0.80, 0.32},
        {0.90, 0.85, 0.30}, {0.95, 0.60, 0.20}, {0.85, 0.25, 0.25}, {0.95, 0.95, 0.92}};
    constexpr int n = int(sizeof palette / sizeof palette[0]);
    return palette[std::clamp(index, 0, n - 1)];
}

namespace {

/// The module's first parameter, or `fallback` without one.
double param(const Module& m, double fallback)
{
    return m.params.empty() ? fallback : m.params[0];
}

/// Interprets a derived string module by module (interpretTurtle): the
/// turtle, its stack of branches and its open polygons.
class TurtleInterpreter {
public:
    TurtleInterpreter(const LSystem& sys, const ModuleString& modules)
        : sys_(sys),
          modules_(modules),
          increment_(sys.widthIncrement ? *sys.widthIncrement : 0.1 * sys.width),
          T_(sys.tropism[0], sys.tropism[1], sys.tropism[2]),
          e_(sys.tropism[3])
    {
        t_.width = sys.width;
    }

    Skeleton run()
    {
        for (size_t i = 0; i < modules_.size(); ++i) {
            const Module& m = modules_[i];
            switch (m.name) {
                case 'F':
                case 'f':
                case 'G':
                case 'g':
                    forward(i, m);
                    break;
                case '+':
                    turn(t_, param(m, sys_.angle));
                    break;
                case '-':
                    turn(t_, -param(m, sys_.angle));
                    break;
                case '&':
                    pitch(t_, param(m, sys_.angle));
                    break;
                case '^':
                    pitch(t_, -param(m, sys_.angle));
                    break;
                case '\\':
                    roll(t_, param(m, sys_.angle));
                    break;
                case '/':
                    roll(t_, -param(m, sys_.angle));
                    break;
                case '|':
                    turn(t_, 180.0);
                    break;
                case '$': {
                    const glm::dvec3 l = glm::cross(glm::dvec3(0.0, 1.0, 0.0), t_.H);
                    if (glm::length(l) > 1e-12) {
                        t_.L = glm::normalize(l);
                        t_.U = glm::cross(t_.H, t_.L);
                    }
                    break;
                }
                case '!':
                case '#':
                    setWidth(i, m);
                    break;
                case '\'':
                case ';':
                    setColour(i, m);
                    break;
                case '{':
                    polygons_.emplace_back();
                    vertex();
                    break;
                case '.':
                    if (polygons_.empty())
                        throw bad(i, "'.' records a polygon vertex: only between '{' and '}'");
                    vertex();
                    break;
                case '}':
                    closePolygon(i);
                    break;
                case '~':
                case '@':
                    throw bad(
                        i, fmt::format(
                               "cpfg's '{}' (predefined surfaces and @ commands) is not supported "
                               "(docs/lsystem-format.md lists the turtle's symbols)",
                               m.name));
                case '[': {
                    stack_.push_back(t_);
                    ++t_.order;
                    t_.drewInBranch = false;
                    break;
                }
                case ']':
                    if (stack_.empty())
                        throw bad(i, "']' without a matching '['");
                    t_ = stack_.back();
                    stack_.pop_back();
                    break;
                case '%':
                    i = cut(i);
                    break;
                default:
                    break;  // modules that are not turtle commands (A, B, L, ...)
            }
        }
        if (!polygons_.empty())
            throw InputError(
                fmt::format("{}: {} '{{' without a matching '}}' in the derived string",
                            sys_.source, polygons_.size()));
        return std::move(out_);
    }

private:
    InputError bad(size_t i, const std::string& what) const
    {
        return InputError(fmt::format("{}: module {} of the derived string ({}): {}", sys_.source,
                                      i, formatModules({modules_[i]}), what));
    }

    /// Records the turtle's position as a vertex of the innermost open
    /// polygon, unless it is where the last one is.
    void vertex()
    {
        if (!polygons_.empty() &&
            (polygons_.back().empty() || glm::length(polygons_.back().back() - t_.pos) > 0.0))
            polygons_.back().push_back(t_.pos);
    }

    /// F, f, G or g (module i): forward, drawing an internode (F, G) or not;
    /// in a polygon F and f record a vertex instead.
    void forward(size_t i, const Module& m)
    {
        const double l = param(m, sys_.step);
        if (!(l >= 0.0) || !std::isfinite(l))
            throw bad(i, "a length must be a number not below zero");
        if (l == 0.0)
            return;
        const glm::dvec3 p1 = t_.pos + l * t_.H;
        const double far = std::max({std::abs(p1.x), std::abs(p1.y), std::abs(p1.z)});
        if (!(far <= kFarthestCoordinate))  // (NaN too: a heading turned by a NaN angle)
            throw bad(i, fmt::format("the turtle reaches {:g} from the origin, beyond the {:g} "
                                     "cambium draws",
                                     far, kFarthestCoordinate));
        if (!polygons_.empty()) {
            // In a polygon F and f move and record a vertex; G and g only move.
            t_.pos = p1;
            if (m.name == 'F' || m.name == 'f')
                vertex();
            return;
        }
        if (m.name == 'F' || m.name == 'G')
            drawInternode(i, p1);
        t_.pos = p1;
    }

    /// The internode from the turtle's position to p1 (module i), then the
    /// heading bent by tropism.
    void drawInternode(size_t i, const glm::dvec3& p1)
    {
        if (!(t_.width > 0.0))
            throw bad(i, fmt::format("the width is {}: set a positive one with !(w) or width:",
                                     t_.width));
        Internode n;
        n.id = (long long)out_.internodes.size();
        n.parent = t_.last;
        n.p0 = t_.pos;
        n.p1 = p1;
        n.r0 = n.r1 = 0.5 * t_.width;
        n.order = t_.order;
        n.module = (long long)i;
        if (t_.colour != 0)
            n.colour = paletteColour(sys_, t_.colour);
        out_.internodes.push_back(n);
        t_.last = n.id;
        t_.drewInBranch = true;
        if (e_ != 0.0) {
            const glm::dvec3 axis = glm::cross(t_.H, T_);
            const double len = glm::length(axis);
            if (len > 1e-12) {
                const glm::dvec3 a = axis / len;
                const double angle = e_ * len;
                t_.H = glm::normalize(rotateAbout(t_.H, a, angle));
                t_.L = glm::normalize(rotateAbout(t_.L, a, angle));
                t_.U = glm::cross(t_.H, t_.L);
            }
        }
    }

    /// ! or # (module i).
    void setWidth(size_t i, const Module& m)
    {
        // With a parameter: the new width; without: cpfg's decrement ('!')
        // or increment ('#') by the width increment.
        const double w =
            !m.params.empty() ? m.params[0] : t_.width + (m.name == '!' ? -increment_ : increment_);
        if (!(w > 0.0) || !std::isfinite(w))
            throw bad(i, m.params.empty()
                             ? fmt::format("the width {} less the width increment {} is not "
                                           "positive: a smaller 'width increment:' or !(w)",
                                           t_.width, increment_)
                             : std::string("a width must be a positive number"));
        t_.width = w;
    }

    /// ' or ; (module i).
    void setColour(size_t i, const Module& m)
    {
        // The colour index: with a parameter, set; without, one more.
        const double c = m.params.empty() ? t_.colour + 1.0 : m.params[0];
        if (!(c >= 0.0 && c <= 255.0) || std::trunc(c) != c)
            throw bad(i, "a colour index must be a whole number from 0 to 255");
        t_.colour = int(c);
    }

    /// } (module i): the innermost open polygon into a leaf blade.
    void closePolygon(size_t i)
    {
        if (polygons_.empty())
            throw bad(i, "'}' without a matching '{'");
        std::vector<glm::dvec3> v = std::move(polygons_.back());
        polygons_.pop_back();
        if (v.size() > 1 && glm::length(v.back() - v.front()) == 0.0)
            v.pop_back();  // closed by returning to its start
        if (v.size() < 3)
            throw bad(i,
                      fmt::format(
                          "a polygon needs 3 vertices or more (this one has {}): its vertices are "
                          "where '{{' starts, each F or f inside, and each '.'",
                          v.size()));
        const Organ leaf = polygonLeaf(v, paletteColour(sys_, t_.colour));
        if (!(leaf.radius > 1e-6 * glm::length(leaf.p1 - leaf.p0)))
            throw bad(i, "a polygon with no area (its vertices lie on a line)");
        out_.organs.push_back(leaf);
    }

    /// % (module i): a saw cut.  The index to go on from: the rest of the
    /// branch (if the string still has it) is skipped.
    size_t cut(size_t i)
    {
        // The branch's last internode ends in a flat cut.
        if (t_.drewInBranch && t_.last >= 0) {
            out_.internodes[size_t(t_.last)].cut = true;
        } else if (t_.last >= 0) {
            // Cut before it drew anything: the organ was shed at its base,
            // a scar on the internode it grew from, along its heading.
            const Internode& parent = out_.internodes[size_t(t_.last)];
            const double rp = std::max(parent.r0, parent.r1), rs = 0.5 * t_.width;
            Scar scar;
            scar.base = t_.pos;
            scar.tip = t_.pos + rp * t_.H;
            scar.radius = rs;
            scar.parent = parent.id;
            out_.scars.push_back(scar);
        }
        return branchEnd(modules_, i) - 1;  // the branch's ']' comes next
    }

    const LSystem& sys_;
    const ModuleString& modules_;
    const double increment_;  ///< the width increment of ! and # without a parameter
    const glm::dvec3 T_;      ///< tropism: the direction the heading bends towards
    const double e_;          ///< and how much
    Skeleton out_;
    TurtleState t_;
    std::vector<TurtleState> stack_;
    std::vector<std::vector<glm::dvec3>> polygons_;  // open polygons, innermost last
};

}  // namespace

Skeleton interpretTurtle(const LSystem& sys, const ModuleString& modules)
{
    return TurtleInterpreter(sys, modules).run();
}

}  // namespace cambium
