// cambium — the 3D turtle.
#include "model/turtle.h"

#include "core/error.h"
#include "core/math.h"

#include <fmt/format.h>

#include <cmath>

namespace cambium {

namespace {


struct TurtleState {
    glm::dvec3 pos{0.0}, H{0.0, 1.0, 0.0}, L{1.0, 0.0, 0.0}, U{0.0, 0.0, -1.0};
    double width = 0.1;
    long long last = -1;  ///< the last internode drawn on the way here
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

}  // namespace

Skeleton interpretTurtle(const LSystem& sys, const ModuleString& modules)
{
    Skeleton out;
    TurtleState t;
    t.width = sys.width;
    std::vector<TurtleState> stack;
    const glm::dvec3 T(sys.tropism[0], sys.tropism[1], sys.tropism[2]);
    const double e = sys.tropism[3];
    auto param = [&](const Module& m, double fallback) { return m.params.empty() ? fallback : m.params[0]; };
    auto bad = [&](size_t i, const std::string& what) {
        return InputError(fmt::format("{}: module {} of the derived string ({}): {}", sys.source, i,
                                      formatModules({modules[i]}), what));
    };
    for (size_t i = 0; i < modules.size(); ++i) {
        const Module& m = modules[i];
        switch (m.name) {
        case 'F':
        case 'f': {
            const double l = param(m, sys.step);
            if (!(l >= 0.0) || !std::isfinite(l))
                throw bad(i, "a length must be a number not below zero");
            if (l == 0.0)
                break;
            const glm::dvec3 p1 = t.pos + l * t.H;
            if (m.name == 'F') {
                if (!(t.width > 0.0))
                    throw bad(i, fmt::format("the width is {}: set a positive one with !(w) or width:", t.width));
                Internode n;
                n.id = (long long)out.internodes.size();
                n.parent = t.last;
                n.p0 = t.pos;
                n.p1 = p1;
                n.r0 = n.r1 = 0.5 * t.width;
                n.order = t.order;
                n.module = (long long)i;
                out.internodes.push_back(n);
                t.last = n.id;
                t.drewInBranch = true;
                if (e != 0.0) {
                    const glm::dvec3 axis = glm::cross(t.H, T);
                    const double len = glm::length(axis);
                    if (len > 1e-12) {
                        const glm::dvec3 a = axis / len;
                        const double angle = e * len;
                        t.H = glm::normalize(rotateAbout(t.H, a, angle));
                        t.L = glm::normalize(rotateAbout(t.L, a, angle));
                        t.U = glm::cross(t.H, t.L);
                    }
                }
            }
            t.pos = p1;
            break;
        }
        case '+': turn(t, param(m, sys.angle)); break;
        case '-': turn(t, -param(m, sys.angle)); break;
        case '&': pitch(t, param(m, sys.angle)); break;
        case '^': pitch(t, -param(m, sys.angle)); break;
        case '\\': roll(t, param(m, sys.angle)); break;
        case '/': roll(t, -param(m, sys.angle)); break;
        case '|': turn(t, 180.0); break;
        case '$': {
            const glm::dvec3 l = glm::cross(glm::dvec3(0.0, 1.0, 0.0), t.H);
            if (glm::length(l) > 1e-12) {
                t.L = glm::normalize(l);
                t.U = glm::cross(t.H, t.L);
            }
            break;
        }
        case '!':
            if (m.params.empty())
                throw bad(i, "'!' needs the new width: !(w)");
            if (!(m.params[0] > 0.0) || !std::isfinite(m.params[0]))
                throw bad(i, "a width must be a positive number");
            t.width = m.params[0];
            break;
        case '[': {
            stack.push_back(t);
            ++t.order;
            t.drewInBranch = false;
            break;
        }
        case ']':
            if (stack.empty())
                throw bad(i, "']' without a matching '['");
            t = stack.back();
            stack.pop_back();
            break;
        case '%': {
            // A saw cut: the branch's last internode ends in a flat cut, and
            // the rest of the branch (if the string still has it) is skipped.
            if (t.drewInBranch && t.last >= 0) {
                out.internodes[size_t(t.last)].cut = true;
            } else if (t.last >= 0) {
                // Cut before it drew anything: the organ was shed at its base,
                // a scar on the internode it grew from, along its heading.
                const Internode& parent = out.internodes[size_t(t.last)];
                const double rp = std::max(parent.r0, parent.r1), rs = 0.5 * t.width;
                Scar scar;
                scar.base = t.pos;
                scar.tip = t.pos + rp * t.H;
                scar.radius = rs;
                scar.parent = parent.id;
                out.scars.push_back(scar);
            }
            i = branchEnd(modules, i) - 1;  // the branch's ']' comes next
            break;
        }
        default:
            break;  // symbols the turtle does not know (A, L, {, }, ...)
        }
    }
    return out;
}

int runLSystemCommand(const LSystemRequest& req)
{
    const LSystem sys = loadLSystem(req.input);
    const int steps = req.steps >= 0 ? req.steps : sys.derivationLength;
    const ModuleString s = derive(sys, steps, req.seed >= 0 ? uint64_t(req.seed) : sys.seed, req.maxModules);
    const Skeleton sk = interpretTurtle(sys, s);
    if (req.printString)
        fmt::print("{}\n", formatModules(s));
    if (req.printSkeleton) {
        fmt::print("# {} after {} steps: id parent x0 y0 z0 x1 y1 z1 r0 r1  # order module [cut]\n", req.input, steps);
        for (const Internode& n : sk.internodes)
            fmt::print("{} {} {} {} {} {} {} {} {} {}  # {} {}{}\n", n.id, n.parent, n.p0.x, n.p0.y, n.p0.z, n.p1.x,
                       n.p1.y, n.p1.z, n.r0, n.r1, n.order, n.module, n.cut ? " cut" : "");
    }
    if (!req.printString && !req.printSkeleton) {
        int maxOrder = 0;
        for (const Internode& n : sk.internodes)
            maxOrder = std::max(maxOrder, n.order);
        fmt::print("{}: {} steps, {} modules, {} internodes, branch orders 0-{}\n", req.input, steps, s.size(),
                   sk.internodes.size(), maxOrder);
    }
    return 0;
}

}  // namespace cambium
