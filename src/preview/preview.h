// cambium — the live preview's session (cambium preview): one long-lived
// state that keeps the sampling device, the compiled kernels, the ray
// marcher and the last bake's leaf values, and turns the model file as it is
// now into a picture: read (and grow), bake at the preview voxel size reusing
// the leaves whose programs did not change, render with a fixed camera,
// write the picture atomically.  A bad file leaves the last good picture.
// What watches the file and drives the session is preview/loop.h.
#pragma once

#include "bake/options.h"
#include "bake/thicken.h"
#include "core/system.h"
#include "model/load_model.h"

#include <atomic>
#include <memory>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace cambium {

struct BakedGrids;  // bake/levelset.h

struct PreviewSettings {
    std::string input;   ///< a scene, L-system, skeleton or growth parameter file
    ModelOptions model;  ///< --time / --year among them
    /// The preview's voxel size; unset: kPreviewVoxelsAcross voxels across
    /// the first good model's surface bounds, kept for every later picture
    /// (so that unchanged leaves are reused and the tree does not change
    /// resolution as it grows).
    std::optional<double> voxelSize;
    Device device = Device::OpenCL;              ///< the bake's sampler
    double minRadius = kDefaultMinRadiusVoxels;  ///< the bake's smallest radius (voxels)
    /// Hears each bake's stages (--once: its progress on stderr; a bake of
    /// many summed primitives ran past a minute in silence).
    std::function<void(const char* stage, double fraction)> progress;
    Device renderDevice =
        Device::Cpu;  ///< the march (the CPU's the faster here: docs/rendering.md)
    int width = 640, height = 480, spp = 1;
    std::string camera = "auto";  ///< parseCamera's spec, framed on the first good model
    std::string output = "preview.png";
    /// Times (years) to bake in the background once the first picture is
    /// made (prebake): a year slider on one of them shows it at once.
    std::vector<double> frames;
    /// Bytes the frames kept may take together (0: a quarter of the memory
    /// available when the session starts); the frames past it are baked
    /// when the slider reaches them, as without --frames.
    double framesMemory = 0.0;
};

/// The default preview resolution: voxels across the first model's bounds.
constexpr double kPreviewVoxelsAcross = 384.0;

/// What the page can change without touching the file: the time of a
/// growth model, and the camera's orbit about its target (degrees, from the
/// framed camera).
struct PreviewView {
    std::optional<double> time;  ///< years; none: the file's last year
    double azimuth = 0.0, elevation = 0.0;
};

/// What one update did.
struct PreviewUpdate {
    enum class Outcome {
        Rendered,     ///< a new picture was written
        Unchanged,    ///< the file's text and the view are the last picture's: nothing done
        Failed,       ///< the file (or the work) failed: `error`; the last picture kept
        Interrupted,  ///< the interrupt was raised: nothing written
    };
    Outcome outcome = Outcome::Unchanged;
    std::string error;        ///< Failed: the message, naming the file and the JSON path
    bool inputError = false;  ///< Failed: bad input (else a failure of the work)
    bool rebaked = false;     ///< Rendered: the model was read and baked (else only the view moved)
    bool regrown = false;     ///< rebaked: a growth parameter file's growth model run again
    bool prebaked = false;    ///< rebaked: the grids were baked in the background (--frames)
    /// Seconds of each stage: the model read (and grown), compiled, baked,
    /// rendered, the picture written; and all of it.
    double model = 0.0, compile = 0.0, bake = 0.0, render = 0.0, write = 0.0, total = 0.0;
    double voxelSize = 0.0;
    size_t leaves = 0, reusedLeaves = 0, activeVoxels = 0;
    size_t pictures = 0;  ///< pictures written by the session so far
    PreviewView view;     ///< the view the update worked from
};

class PreviewSession {
public:
    /// Checks the settings (InputError: before any work); the device is
    /// started by the first update.
    explicit PreviewSession(PreviewSettings settings);
    ~PreviewSession();
    PreviewSession(const PreviewSession&) = delete;
    PreviewSession& operator=(const PreviewSession&) = delete;

    /// Reads the file as it is now and, unless its text and the view are the
    /// last picture's, makes and writes a new picture (a moved camera alone
    /// renders the last bake again).  Never throws for a bad file or a
    /// failed bake: the outcome says so and the last picture stays.
    /// `interrupt`, when raised, stops the work at the next stage or layer
    /// of leaves: nothing is written.
    PreviewUpdate update(const std::atomic<bool>* interrupt = nullptr);

    /// The view the next update works from; any thread (the change that
    /// makes the loop update is the caller's to signal).  InputError for a
    /// time that is not a finite number >= 0 or angles that are not finite.
    void setView(const PreviewView& view);
    PreviewView view() const;

    /// Background work between updates: bakes the next of the settings'
    /// frames not baked for the file's text as it is now.  True when one was
    /// baked (more may remain); false when none is left, the first picture
    /// is not made yet, the file does not read, or `interrupt` stopped it.
    /// The loop's thread only, as update.
    bool prebake(const std::atomic<bool>* interrupt = nullptr);
    /// The frames baked in the background and kept, and their bytes.
    size_t prebakedFrames() const;
    double prebakedBytes() const;
    /// Whether prebake stopped at the settings' framesMemory (until the
    /// file's text changes).
    bool prebakeFull() const;

    const PreviewSettings& settings() const { return settings_; }

private:
    /// The model at `time` from `text` (the file's), grown (a kept growth
    /// model when the text is its) and baked; `known`: the model is the
    /// text's (else the file changed while it was read).
    BakedGrids bakeText(const std::string& text, std::optional<double> time,
                        const std::atomic<bool>* interrupt, PreviewUpdate& u, bool& known);

    /// A changed bark photo: the picture and the background frames that
    /// hold its old colours are forgotten.  Before every bake.
    void forgetStalePhoto();

    struct State;
    PreviewSettings settings_;
    std::unique_ptr<State> state_;
};

}  // namespace cambium
