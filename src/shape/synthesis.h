// cambium — a shape file made into a multi-resolution surface: its base
// (built in, a mesh file, or analysed from a level set or a cambium model),
// the details of every level (the base's own, then the procedural ones, then
// the local edits) and the mesh and colours of the result.
#pragma once

#include "core/system.h"
#include "io/mesh_file.h"
#include "shape/base_shapes.h"
#include "shape/blend.h"
#include "shape/details.h"
#include "shape/shape.h"
#include "subdiv/multires.h"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace cambium {

/// Every detail of a shape: its own and both blend sides'.
std::vector<DetailSpec> allDetails(const ShapeSpec& spec);

/// InputError when a detail or edit of `spec` acts at a level finer than
/// `levels`.
void checkShapeLevels(const ShapeSpec& spec, int levels);

/// InputError when a rock detail would fold the surface onto itself on a
/// plane of `base`'s mean edge length (rockFoldsOnAPlane), naming about the
/// largest amplitude that would not.
void checkShapeDetails(const ShapeSpec& spec, const ControlMesh& base);

/// The memory a shape's synthesis needs at `levels` levels of a base whose
/// faces have `baseCorners` corners in all (bytes, estimated), to refuse
/// what cannot fit.
double estimateSynthesisBytes(size_t baseCorners, int levels);

class ShapeSurface {
public:
    /// Builds the base (makeBase: InputError naming the file for a bad mesh
    /// or base file) and the surface's topology; `levels` overrides the
    /// file's when >= 0.  Nothing is synthesised yet.
    ShapeSurface(const ShapeSpec& spec, int levels = -1, Device device = Device::OpenCL);
    /// The same from a base already made.
    ShapeSurface(const ShapeSpec& spec, int levels, const BaseShape& base);
    ~ShapeSurface();

    /// Another time of the same shape (an animation's frame): its details,
    /// blend and shader replace this one's, on the same base and refinement
    /// (the caller keeps the base and levels; the details are checked
    /// unless `checked` says the caller ran checkShapeLevels and
    /// checkShapeDetails on it).  Synthesise again after.
    void setSpec(const ShapeSpec& spec, bool checked = false);

    /// Synthesis of every level; `progress` is told the fraction done (by
    /// vertices) after each level.
    void synthesize(const std::function<void(double)>& progress = {});
    /// Synthesis from level l on (after an edit of level l's details or
    /// parameters: the coarser levels stay).
    void synthesizeFrom(int l, const std::function<void(double)>& progress = {});

    const ShapeSpec& spec() const { return spec_; }
    int levels() const { return surface_->levels(); }
    const MultiresSurface& surface() const { return *surface_; }
    MultiresSurface& surface() { return *surface_; }
    /// Level l's details as the base gives them (empty: none).
    const std::vector<glm::dvec3>& baseDetail(int l) const { return baseDetail_[size_t(l)]; }

    /// The finest level as a mesh (quads kept, normals, the colour of each
    /// point from the file's colour or ramp of the scalar channel; with a
    /// shader, its points moved along their normals by the shader's height
    /// and coloured by it).
    TriangleMesh mesh() const;

    /// A blend's alpha at level l's vertices (empty without a blend).
    const std::vector<double>& alpha(int l) const { return alpha_[size_t(l)]; }
    /// The blend parameter at each vertex of the finest level (section 6.3):
    /// A's share of the details that made it, each level's detail weighted
    /// by its alpha and carried through the subdivision like the scalar
    /// channel; the finest alpha where no detail acted; 1 without a blend.
    std::vector<double> blendParameter() const;

private:
    void makeDetails();
    void hook(int l, SubdivLevel& level);
    /// Level l's details set to the base's (`base` and the base has them)
    /// or zero.
    void resetDetails(int l, SubdivLevel& level, bool base) const;
    /// `details` (at least at `mask`'s vertices) and `edits` added to level l's.
    void addDetails(int l, SubdivLevel& level, const std::vector<std::unique_ptr<Detail>>& details,
                    const std::vector<EditSpec>& edits, const VertexMask* mask);
    const Adjacency& adjacency(int l);

    ShapeSpec spec_;
    ControlMesh base_;
    std::unique_ptr<MultiresSurface> surface_;
    std::vector<std::vector<glm::dvec3>> baseDetail_;
    std::vector<std::unique_ptr<Detail>> details_;
    std::vector<std::unique_ptr<Adjacency>> adjacency_;
    // A blend's sides, signal, and per level its alpha and the sides'
    // influence (x: A, y: B).
    std::vector<std::unique_ptr<Detail>> sideDetails_[2];
    std::unique_ptr<AlphaSignal> alphaSignal_;
    std::vector<std::vector<double>> alpha_;
    std::vector<std::vector<glm::dvec2>> influence_;
};

/// The colour a shape's colour spec gives a point of scalar s and blend
/// parameter beta (without a shader).
glm::dvec3 shapeColor(const ColorSpec& color, double s, double beta = 1.0);

/// InputError naming `what` when synthesising `levels` levels of `base`
/// would need more memory than the machine has available.
void checkSynthesisMemory(const ControlMesh& base, int levels, const std::string& what);

/// The base of a shape file as a control mesh and the exact surface it is
/// fitted to (mesh files read; built-in shapes made; level sets and models
/// captured on `device`, shape/capture.h).
BaseShape makeBase(const BaseSpec& base, const std::string& source, Device device,
                   const std::function<void(const char*, double)>& progress = {});

}  // namespace cambium
