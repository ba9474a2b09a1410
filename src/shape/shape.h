// cambium — shape files (docs/shape-format.md): a base shape, a number of
// subdivision levels, procedural multi-scale details (paper 004, section
// 4), where they are placed (section 5.1), local detail edits (section 5.2)
// and the colour of the result.
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace cambium {

enum class BaseType { Cube, Sphere, Torus, Plane, Fuse, Mesh, LevelSet, Model };

struct BaseSpec {
    BaseType type = BaseType::Cube;
    double size = 2.0;                    ///< cube edge, plane width
    double radius = 1.0;                  ///< sphere radius, fuse's largest radius
    double major = 1.0, minor = 0.35;     ///< torus
    double length = 3.0;                  ///< fuse
    int around = 8, tube = 6, rings = 8;  ///< torus and fuse control grids
    int cells = 4;                        ///< plane
    int sphereCells = 1;                  ///< sphere: quads along a cube face
    int terms = 2;                        ///< fuse profile
    std::string file;                     ///< mesh, vdb or model file (absolute or as given)
    double coarseVoxelSize = 0.0;         ///< vdb, model: the base's voxel size (0: automatic)
    double fineVoxelSize = 0.0;           ///< model: the analysed bake's voxel size (0: automatic)
    double year = -1.0;                   ///< model: a growth file's year (< 0: its last)
    bool analyse = false;                 ///< mesh: the file is a fine surface to analyse
    std::string control;  ///< mesh, vdb, model: the coarse control mesh to analyse onto
};

enum class DetailType { Rock, Berry, Tentacle, Mushroom, Spur };

/// Where a local feature's size and distances come from (section 5.1): the
/// control points of its level (topological rings, the vertex normal: the
/// parametrisation shows) or a chart on the tangent plane at the seed (metric
/// distances, the seed's normal: independent of the parametrisation).
enum class Placement { ControlPoints, Chart };

struct DetailSpec {
    DetailType type = DetailType::Rock;
    std::string path;         ///< its JSON path, for messages
    std::vector<int> levels;  ///< the levels it acts at, ascending
    uint32_t seed = 0;
    double amplitude = 0.05;       ///< rock: the first level's amplitude (halving per level)
    double frequency = 2.0;        ///< rock: the first level's noise frequency (doubling per level)
    bool perControlPoint = false;  ///< rock: the two-pass form (a random value per point)
    double radius = 0.2;           ///< berry, spur, mushroom: the first level's feature radius
    double height = 0.3;           ///< spur, mushroom: feature height
    double length = 0.02;          ///< tentacle: reference length
    double angle = 0.0;            ///< tentacle: rotation angle theta (radians)
    int children = 3;              ///< berry: child seeds per seed and level
    // Seeds: given points (projected onto the surface) or a Poisson-disk set.
    std::vector<glm::dvec3> at;
    double spacing = 0.0;  ///< Poisson-disk minimum spacing (global placement)
    Placement placement = Placement::ControlPoints;
    double scalar = 1.0;    ///< weight of its normal displacement in the scalar channel
    double displace = 1.0;  ///< weight of its displacement of the surface (0: the scalar only)
};

/// Local detail modification: details of `levels` near `at` scaled by
/// 1 + (gain - 1) k(d / radius), k(s) = (1 - s)^2 (1 + 2 s) (C1, zero at the radius).
struct EditSpec {
    std::string path;
    glm::dvec3 at{0.0};
    double radius = 0.1, gain = 0.0;
    std::vector<int> levels;
    bool topological = false;  ///< edge hops times the level's mean edge length, else metric
};

/// The colour of the baked Cd: one colour, or a ramp over the scalar
/// channel; for a blend, one of these per side mixed by the blend parameter.
struct ColorSpec {
    glm::dvec3 color{0.75, 0.72, 0.68};
    bool ramp = false;
    double low = 0.0, high = 1.0;  ///< the scalar range of the ramp
    glm::dvec3 lowColor{0.0}, highColor{1.0};
    std::vector<ColorSpec> sides;  ///< none, or A's and B's
};

/// An alpha signal (section 3): the weight of shape A in a blend, in [0, 1],
/// at the subdivided points of each level.  Plane, sphere and noise are
/// signed functions s(x) (positive on A's side) turned into a weight by the
/// level's transition of width w: 0 for s <= -w/2, 1 for s >= w/2, smooth
/// (3u^2 - 2u^3) between.  Strokes and painted alphas are weights as painted;
/// the compositing operators combine signals.
enum class AlphaType {
    Constant,
    Plane,
    Sphere,
    Noise,
    Strokes,
    Painted,
    Multiply,
    Screen,
    Max,
    Min,
    Invert
};

struct Stroke {
    glm::dvec3 at{0.0};
    double radius = 0.1;
    double value = 1.0;
};

struct AlphaSpec {
    AlphaType type = AlphaType::Constant;
    std::string path;                              ///< its JSON path, for messages
    double value = 1.0;                            ///< constant
    glm::dvec3 normal{1.0, 0.0, 0.0}, point{0.0};  ///< plane (point on it); sphere (centre)
    double radius = 1.0;                           ///< sphere
    double frequency = 1.0, threshold = 0.0;       ///< noise
    uint32_t seed = 0;                             ///< noise
    std::vector<Stroke> strokes;                   ///< strokes, composited in order
    double background = 0.0;                       ///< strokes: the weight where none reaches
    std::string file;  ///< painted: a PLY with a vertex alpha; strokes: their JSON file, if any
    std::vector<AlphaSpec> of;  ///< compositing operators' operands
};

/// One side of a blend: the details and edits of one multi-scale shape on
/// the shared base, and whether the base's own (analysed) details belong to it.
struct BlendSide {
    bool baseDetail = true;
    std::vector<DetailSpec> details;
    std::vector<EditSpec> edits;
};

/// Multi-scale blending (section 6, after Burt): at each level l, the
/// detail coefficients of A and B combined linearly by the alpha signal with
/// a transition of width `width` / 2^(l-1) (or `width` at every level).
struct BlendSpec {
    bool enabled = false;
    BlendSide a, b;
    AlphaSpec alpha;
    double width = 0.0;
    bool constantWidth = false;
};

/// The post-blend shader (section 6.3): the blended scalar s and blend
/// parameter beta of each point of the finest level mapped to a height along
/// the normal and a colour.  Terrain: height relief * max(s, sea level)
/// (oceans flattened); colour ocean below the sea level (deep to shallow over
/// `depth`), lowland to mountain from the sea level to the snow line, snow
/// above; each from palette A and palette B mixed by beta.
struct ShaderSpec {
    bool enabled = false;
    double seaLevel = 0.0, snowLine = 0.1, relief = 1.0, depth = 0.05;
    struct Palette {
        glm::dvec3 deep{0.02, 0.07, 0.25}, shallow{0.10, 0.35, 0.55}, lowland{0.20, 0.45, 0.15},
            mountain{0.45, 0.37, 0.28}, snow{0.95, 0.95, 0.97};
    } a, b;
};

struct ShapeSpec {
    std::string source;     ///< the file, for messages
    double time = 0.0;      ///< the animation time its keyframed numbers were read at
    bool animated = false;  ///< whether any number is keyframed
    BaseSpec base;
    int levels = 5;
    std::vector<DetailSpec> details;  ///< with a blend: added to both sides' blend
    std::vector<EditSpec> edits;      ///< with a blend: applied to the blended details
    BlendSpec blend;
    ShaderSpec shader;
    ColorSpec color;
};

/// Reads a shape file at animation time `time`: InputError "FILE: PATH:
/// PROBLEM" (unknown keys with suggestions, missing or out-of-range values,
/// levels beyond 15, a detail level beyond the shape's, unreadable base
/// files) before any work.  Any number outside the base and the levels may
/// be keyframed, {"keys": [[t, v], ...], "interpolation": "linear" |
/// "smooth"}: its value at `time` (held before the first key and after the
/// last; smooth: monotone cubic Hermite, no overshoot).
/// `levels` >= 0 replaces the file's "levels" (--levels) before the details,
/// edits and blend are read, so that their default levels follow it.
ShapeSpec readShapeFile(const std::string& path, double time = 0.0, int levels = -1);
/// The same from text; relative base files are taken from `directory`.
ShapeSpec parseShape(const std::string& text, const std::string& source,
                     const std::string& directory = "", double time = 0.0, int levels = -1);

/// Whether a .json file's top level is a shape (it has "base").
bool looksLikeShapeFile(const std::string& path);

}  // namespace cambium
