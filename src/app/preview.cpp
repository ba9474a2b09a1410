// cambium preview FILE — the live preview: one process that keeps its
// device, kernels and leaf values, watches the model file and writes a new
// picture on every change (src/preview), a line per picture.
#include "app/app.h"

#include "core/error.h"
#include "core/frames.h"
#include "preview/loop.h"
#include "preview/preview.h"
#include "preview/server.h"

#include <fmt/format.h>

#include <atomic>
#include <cstdio>

namespace cambium {

namespace {

/// An update in one line: its stages, or why there is no new picture.
void report(const PreviewSettings& settings, const PreviewUpdate& u)
{
    using O = PreviewUpdate::Outcome;
    switch (u.outcome) {
        case O::Rendered: {
            const std::string view =
                u.view.time ? fmt::format("year {:g}, ", *u.view.time) : std::string();
            std::string made;
            if (!u.rebaked)
                made = "the view moved: the last bake";
            else if (u.prebaked)
                made = "baked in the background";
            else
                made = fmt::format(
                    "read {}{:.2f} s, compile {:.2f} s, bake {:.2f} s: {} leaves, {} reused",
                    u.regrown ? "and grow " : "", u.model, u.compile, u.bake,
                    formatCount(double(u.leaves)), formatCount(double(u.reusedLeaves)));
            fmt::print(
                "picture {}: {:.2f} s -> {} ({}{}, voxel size {:g}; render {:.2f} s, write "
                "{:.2f} s)\n",
                u.pictures, u.total, settings.output, view, made, u.voxelSize, u.render, u.write);
            break;
        }
        case O::Failed:
            // (on stderr as every error, the session going on)
            std::fflush(stdout);
            std::fprintf(stderr, "cambium: error: %s (%s)\n",
                         shortened(printable(u.error), 900).c_str(),
                         u.pictures ? "the last picture kept"
                                    : "no picture yet: the next change of the file tries again");
            break;
        case O::Interrupted:
            fmt::print("interrupted after {:.2f} s: the file changed again\n", u.total);
            break;
        case O::Unchanged:
            break;
    }
    std::fflush(stdout);
}

}  // namespace

void addPreviewCommand(CLI::App& app, Action& action)
{
    struct Options {
        PreviewSettings settings;
        ModelFlags model;
        double voxelSize = 0.0;
        std::string device = "opencl", renderDevice = "cpu";
        bool once = false;
        int port = 0;
        std::string frames;
        double framesMemoryGB = 0.0;
    };
    auto o = std::make_shared<Options>();
    auto* cmd = app.add_subcommand(
        "preview",
        "Watch a model file and write a new picture on every change (docs/preview.md): one "
        "process that keeps its device, kernels and unchanged leaves between pictures");
    cmd->add_option("input", o->settings.input,
                    "A growth parameter file, scene, L-system or skeleton file")
        ->required();
    addModelFlags(cmd, o->model);
    auto* voxelOpt = cmd->add_option(
        "--voxel-size", o->voxelSize,
        fmt::format("The preview's voxel size (default: {:g} voxels across the first picture's "
                    "model, kept)",
                    kPreviewVoxelsAcross));
    cmd->add_option("-o,--output", o->settings.output, "The picture (.png), written atomically")
        ->capture_default_str();
    cmd->add_option("--width", o->settings.width, "Picture width in pixels")->capture_default_str();
    cmd->add_option("--height", o->settings.height, "Picture height in pixels")
        ->capture_default_str();
    cmd->add_option("--spp", o->settings.spp, "Samples per pixel")->capture_default_str();
    cmd->add_option("--camera", o->settings.camera,
                    "auto, turntable:ANGLE or look:EX,EY,EZ:TX,TY,TZ[:FOV], framed on the first "
                    "picture's model and kept")
        ->capture_default_str();
    addMinRadiusFlag(cmd, o->settings.minRadius);
    cmd->add_option("--device", o->device, "The bake's device: opencl or cpu")
        ->capture_default_str();
    cmd->add_option("--render-device", o->renderDevice, "The march's device: cpu or opencl")
        ->capture_default_str();
    auto* portOpt =
        cmd->add_option("--port", o->port,
                        "The page's port on 127.0.0.1 (default: a free one); its URL, with a "
                        "random token, is the first line printed");
    auto* framesOpt = cmd->add_option(
        "--frames", o->frames,
        "Years A-B[:STEP] of a growth parameter file to bake in the background "
        "after the first picture, so that the page's year slider shows them at once");
    auto* framesMemoryOpt = cmd->add_option(
        "--frames-memory", o->framesMemoryGB,
        "GB the --frames kept may take; the years past it are baked when the "
        "slider reaches them (default: a quarter of the memory available at start)");
    auto* onceFlag =
        cmd->add_flag("--once", o->once,
                      "One picture, then exit (2: bad input, 1: a failure): what scripts and "
                      "tests run");
    // (what only the page and its background bakes use)
    onceFlag->excludes(portOpt)->excludes(framesOpt)->excludes(framesMemoryOpt);
    cmd->callback([o, voxelOpt, &action] {
        action = [o, voxelOpt] {
            PreviewSettings& s = o->settings;
            if (o->port < 0 || o->port > 65535)
                throw InputError(fmt::format(
                    "--port must be from 1 to 65535, or 0 for a free one (got {})", o->port));
            if (voxelOpt->count())
                s.voxelSize = o->voxelSize;
            s.model = o->model.options();
            s.device = parseDevice(o->device);
            s.renderDevice = parseDevice(o->renderDevice, "--render-device");
            if (!o->frames.empty())
                for (long long year : parseFrames(o->frames, "--frames"))
                    s.frames.push_back(double(year));
            s.framesMemory = o->framesMemoryGB * 1e9;
            ProgressBar bar;
            if (o->once)
                s.progress = [&](const char* stage, double f) { bar(stage, f); };
            PreviewSession session(s);
            if (o->once) {
                const PreviewUpdate u = session.update();
                bar.clear();
                // (a failure is the command's error: exit 2 or 1)
                if (u.outcome == PreviewUpdate::Outcome::Failed && u.inputError)
                    throw InputError(u.error);
                if (u.outcome == PreviewUpdate::Outcome::Failed)
                    throw std::runtime_error(u.error);
                report(s, u);
                return 0;
            }
            InotifyChanges changes(s.input);
            PreviewServer server(session, changes, o->port);
            fmt::print("{}\n", server.url());
            fmt::print(
                "preview of {}: a new {} on every change of the file, shown on the page "
                "above (Ctrl-C stops)\n",
                s.input, s.output);
            std::fflush(stdout);
            const std::atomic<bool> never{false};  // (a signal ends the process)
            PreviewLoopOptions loop;
            bool first = true;
            bool toldFull = false;
            loop.idle = [&](const std::atomic<bool>* interrupt) {
                const bool more = session.prebake(interrupt);
                if (session.prebakeFull() && !toldFull)
                    fmt::print(
                        "--frames: {} years kept ({}), the most --frames-memory allows; "
                        "the others are baked when shown\n",
                        session.prebakedFrames(), formatBytes(session.prebakedBytes()));
                toldFull = session.prebakeFull();
                std::fflush(stdout);
                return more;
            };
            loop.updated = [&](const PreviewUpdate& u) {
                // A first picture the work could not make (not the file's
                // fault): the preview cannot start (said once, as the
                // command's failure).
                if (first && u.outcome == PreviewUpdate::Outcome::Failed && !u.inputError)
                    throw std::runtime_error(u.error);
                report(s, u);
                server.publish(u);
                first = first && u.outcome != PreviewUpdate::Outcome::Rendered;
            };
            runPreviewLoop(session, changes, never, loop);
            return 0;
        };
    });
}

}  // namespace cambium
