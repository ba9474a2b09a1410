// cambium — what the commands share: model options, reports, progress.
#include "app/app.h"

#include "bake/options.h"

#include <fmt/format.h>

#include <cctype>
#include <chrono>
#include <cstdio>
#include <unistd.h>

namespace cambium {

ModelOptions ModelFlags::options() const
{
    ModelOptions o;
    if (!junctions.empty())
        o.junctions = parseJunctions(junctions);
    o.bendDegrees = bendDegrees;
    o.primitives = parsePrimitives(primitives);
    o.regrowth = regrowth;
    o.leaves = !noLeaves;
    if (timeOption && timeOption->count())
        o.time = time;
    return o;
}

void addModelFlags(CLI::App* cmd, ModelFlags& flags)
{
    cmd->add_option(
        "--junctions", flags.junctions,
        "L-systems and skeletons: pcm (the papers' junction rules, PCM between branches), smooth "
        "(the rules, summation only) or blend (a cone per internode, summed); default pcm for "
        "L-systems, blend for skeleton files");
    cmd->add_option(
        "--bend", flags.bendDegrees,
        "Bend lateral internodes by this many degrees, keeping their ends (pcm, smooth)");
    cmd->add_option(
           "--primitives", flags.primitives,
           "cone (papers 001/003), convolution (segments with linear density, paper 002) or mixed "
           "(cone axes, convolution laterals, better blending between)")
        ->capture_default_str();
    cmd->add_option("--regrowth", flags.regrowth,
                    "Callus over saw cuts, from 0 (a bare cut) to 1 (paper 002's regrowth bulge)");
    cmd->add_flag("--no-leaves", flags.noLeaves, "Growth parameter files: leave the leaves out");
    flags.timeOption = cmd->add_option(
        "--time,--year", flags.time,
        "Growth parameter files: the tree at this time in years (default: the last)");
}

void addMinRadiusFlag(CLI::App* cmd, double& voxels)
{
    cmd->add_option("--min-radius", voxels,
                    "The smallest radius baked, in voxels: thinner parts (twigs, leaves) are "
                    "thickened to it, as a level set holds no thinner feature; 0 bakes them as "
                    "they are")
        ->capture_default_str();
}

void checkOptionValues(CLI::App& app)
{
    for (CLI::Option* opt : app.get_options()) {
        if (opt->get_type_size() == 0)
            continue;  // a flag
        // (an empty value was taken as no option: --frames '' baked one
        // frame, --tile '' the whole frame, --junctions '' the default)
        opt->check(CLI::Validator(
            [](std::string& text) {
                return text.empty() ? std::string("an empty value") : std::string();
            },
            "", "not empty"));
        const std::string type = opt->get_type_name();
        if (type.find("FLOAT") == std::string::npos && type.find("INT") == std::string::npos)
            continue;
        opt->transform(CLI::Validator(
            [](std::string& text) -> std::string {
                // [sign] digits [. digits] [e [sign] digits], or a word
                // (inf, nan) left to the option's own check
                if (text.empty())
                    return std::string("an empty value");
                size_t i = text[0] == '+' || text[0] == '-' ? 1 : 0;
                if (i < text.size() && std::isalpha(static_cast<unsigned char>(text[i])))
                    return text.find_first_of("0123456789") == std::string::npos
                               ? std::string()
                               : "'" + text + "' is not a decimal number";
                const size_t digits = text.find_first_not_of('0', i);
                size_t j = i, mantissa = 0;
                while (j < text.size() && std::isdigit(static_cast<unsigned char>(text[j])))
                    ++j, ++mantissa;
                if (j < text.size() && text[j] == '.')
                    for (++j; j < text.size() && std::isdigit(static_cast<unsigned char>(text[j]));
                         ++j)
                        ++mantissa;
                if (mantissa > 0 && j < text.size() && (text[j] == 'e' || text[j] == 'E')) {
                    size_t k = j + 1;
                    if (k < text.size() && (text[k] == '+' || text[k] == '-'))
                        ++k;
                    const size_t exponent = k;
                    while (k < text.size() && std::isdigit(static_cast<unsigned char>(text[k])))
                        ++k;
                    if (k > exponent)
                        j = k;
                }
                if (mantissa == 0 || j != text.size())
                    return "'" + text + "' is not a decimal number";
                // leading zeros dropped, one digit kept before a point
                if (digits != std::string::npos && digits > i) {
                    const size_t keep =
                        digits < text.size() &&
                                std::isdigit(static_cast<unsigned char>(text[digits]))
                            ? digits
                            : digits - 1;
                    text.erase(i, keep - i);
                }
                return std::string();
            },
            "", "decimal"));
    }
    for (CLI::App* sub : app.get_subcommands({}))
        checkOptionValues(*sub);
}

std::string formatVec(const glm::dvec3& v)
{
    return fmt::format("({:.6g}, {:.6g}, {:.6g})", v.x, v.y, v.z);
}

void notePlanning(size_t frames)
{
    if (frames >= 100000)
        fmt::print(stderr, "cambium: planning {} frames\n", formatCount(double(frames)));
}

void printNotice(const std::string& line)
{
    fmt::print("note: {}\n", line);
    std::fflush(stdout);
}

ProgressBar::ProgressBar() : tty_(::isatty(2) != 0), start_(std::chrono::steady_clock::now()) {}

ProgressBar::~ProgressBar()
{
    clear();
}

void ProgressBar::operator()(const char* stage, double fraction)
{
    std::lock_guard<std::mutex> lock(mutex_);
    if (!tty_) {
        // Not a terminal (a log, a farm's task): a line for each stage still
        // running once the command has worked kLineAfter seconds (a bake
        // of three minutes said nothing until it was done).
        constexpr double kLineAfter = 5.0;
        if (stage == stage_ ||
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count() <
                kLineAfter)
            return;
        stage_ = stage;
        fmt::print(stderr, "cambium: working: {} ({:.0f} % done)\n", stage_, 100.0 * fraction);
        std::fflush(stderr);
        return;
    }
    const int percent = int(100.0 * fraction);
    if (stage == stage_ && percent == percent_)
        return;
    stage_ = stage;
    percent_ = percent;
    const int filled = percent * 30 / 100;
    fmt::print(stderr, "\r{:<9} [{}{}] {:3d}%", stage_, std::string(size_t(filled), '#'),
               std::string(size_t(30 - filled), ' '), percent);
    std::fflush(stderr);
    shown_ = true;
}

void ProgressBar::clear()
{
    if (shown_)
        fmt::print(stderr, "\r\033[K");
    shown_ = false;
}

bool timingsAsked(bool flag)
{
    return flag || std::getenv("CAMBIUM_TIMING");
}

void printTimings(const BakeStats& s)
{
    const BakeTimings& t = s.timings;
    fmt::print(stderr,
               "timings: topology {:.3f} s; values {:.3f} s; neighbours {:.3f} s, inside bits "
               "{:.3f} s, sign "
               "changes and queries {:.3f} s; surface samples {:.3f} s ({} points), their points "
               "{:.3f} s; propagation "
               "and leaves {:.3f} s "
               "(thread time: halos {:.3f} s, points {:.3f} s, sweeps {:.3f} s (x {:.3f}, y "
               "{:.3f}, z {:.3f}), "
               "leaves {:.3f} s; {} tiles, {} leaves with halos for {} leaves); freeing {:.3f} s, "
               "tree {:.3f} s, "
               "flood fill {:.3f} s; the first leaf sampled {:.2f} s after the process "
               "started; held at once: the values of {} leaves, {} surface points\n",
               s.topologySeconds, t.values, t.neighbours, t.insideBits, t.signChanges,
               t.surfaceSamples, s.surfacePoints, t.surfacePoints, t.propagation, t.halos, t.points,
               t.sweeps, t.sweepAxis[0], t.sweepAxis[1], t.sweepAxis[2], t.leaves, t.tiles,
               t.tileLeaves, s.candidateLeaves, t.freeing, t.tree, t.floodFill, t.startToSampling,
               s.heldLeaves, s.heldSurfacePoints);
}

}  // namespace cambium
