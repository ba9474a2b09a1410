// cambium — frame sequences.
#include "core/frames.h"

#include "core/error.h"
#include "core/files.h"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <regex>

namespace cambium {

bool isFramePattern(const std::string& pattern)
{
    return pattern.find('#') != std::string::npos;
}

std::pair<size_t, size_t> frameRun(const std::string& pattern)
{
    const size_t a = pattern.find('#');
    if (a == std::string::npos)
        throw InputError(fmt::format("{}: no run of '#' for the frame number", pattern));
    size_t b = a;
    while (b < pattern.size() && pattern[b] == '#')
        ++b;
    if (pattern.find('#', b) != std::string::npos)
        throw InputError(
            fmt::format("{}: more than one run of '#' (one frame number per name)", pattern));
    return {a, b};
}

std::string framePath(const std::string& pattern, long long frame)
{
    const auto [a, b] = frameRun(pattern);
    const std::string digits =
        frame < 0 ? fmt::format("-{:0{}}", -frame, b - a) : fmt::format("{:0{}}", frame, b - a);
    return pattern.substr(0, a) + digits + pattern.substr(b);
}

std::vector<long long> parseFrames(const std::string& range, const std::string& option)
{
    static const std::regex form(
        R"(\s*(-?\d{1,15})\s*(?:-\s*(-?\d{1,15})\s*(?::\s*(\d{1,15})\s*)?)?)");
    std::smatch m;
    if (!std::regex_match(range, m, form))
        throw InputError(
            fmt::format("{} {}: expected FRAME, FIRST-LAST or FIRST-LAST:STEP", option, range));
    const long long first = std::stoll(m[1]);
    const long long last = m[2].matched ? std::stoll(m[2]) : first;
    const long long step = m[3].matched ? std::stoll(m[3]) : 1;
    if (last < first || step < 1)
        throw InputError(fmt::format(
            "{} {}: the last frame must not come before the first, and the step must be "
            "at least 1",
            option, range));
    if ((last - first) / step >= kMaxFrames)
        throw InputError(
            fmt::format("{} {}: {} frames, more than cambium plans at once ({}); split the range",
                        option, range, (last - first) / step + 1, kMaxFrames));
    std::vector<long long> frames;
    for (long long f = first; f <= last; f += step)
        frames.push_back(f);
    return frames;
}

void forEachFile(const std::string& input, const std::string& output, const std::string& frames,
                 const std::function<void(const std::string&)>& checkInput,
                 const std::function<void(const std::string&)>& checkOutput,
                 const std::function<void(const std::string&, const std::string&)>& one)
{
    if (!isFramePattern(input) && !isFramePattern(output) && frames.empty()) {
        checkOutput(output);
        checkOutputIsNoInput(output, {input});
        one(input, output);
        return;
    }
    if (!isFramePattern(input) || !isFramePattern(output) || frames.empty())
        throw InputError(fmt::format(
            "a sequence needs an input and an output with a run of '#' for the frame "
            "number, and --frames (e.g. out/tree.####.vdb --frames 1-10 -o {})",
            isFramePattern(output)
                ? output
                : "out/tree.####" + std::filesystem::path(output).extension().string()));
    const std::vector<long long> list = parseFrames(frames);
    std::vector<std::string> ins, outs;
    for (long long f : list) {
        ins.push_back(framePath(input, f));
        outs.push_back(framePath(output, f));
        if (!std::filesystem::exists(ins.back()))
            throw InputError(
                fmt::format("{}: no such file (frame {} of --frames {})", ins.back(), f, frames));
    }
    for (const std::string& in : ins)
        checkInput(in);
    // Every output's path (a directory where frame 3's should be was found
    // after frames 1 and 2 were written); the first's directory probed.
    checkOutput(outs.front());
    for (size_t i = 1; i < outs.size(); ++i)
        checkOutputPath(outs[i], /*probe=*/false);
    checkSequenceTargets(outs, ins);
    for (size_t i = 0; i < ins.size(); ++i)
        one(ins[i], outs[i]);
}

std::vector<size_t> spreadIndices(size_t n, size_t most)
{
    std::vector<size_t> out;
    if (n <= most) {
        for (size_t i = 0; i < n; ++i)
            out.push_back(i);
        return out;
    }
    for (size_t k = 0; k < most; ++k)
        out.push_back(size_t(std::llround(double(k) * double(n - 1) / double(most - 1))));
    return out;
}

}  // namespace cambium
