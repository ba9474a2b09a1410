// cambium — frame sequences: file-name patterns with `#` runs and frame ranges.
#pragma once

#include <string>
#include <functional>
#include <utility>
#include <vector>

namespace cambium {

/// Whether `pattern` holds a run of `#` (the frame number's place).
bool isFramePattern(const std::string& pattern);

/// Where the (single) run of `#` of `pattern` lies: [first, last).  Throws
/// InputError when the pattern has more than one run of `#` or none.
std::pair<size_t, size_t> frameRun(const std::string& pattern);

/// `pattern` with its (single) run of `#` replaced by `frame`, zero-padded to
/// the run's length: "tree.####.vdb", 12 -> "tree.0012.vdb".  Throws
/// InputError when the pattern has more than one run of `#` or none.
std::string framePath(const std::string& pattern, long long frame);

/// The most frames one range may hold.
constexpr long long kMaxFrames = 1'000'000;

/// The frames of a range "A", "A-B" or "A-B:STEP" (A <= B, STEP >= 1), in
/// order.  Throws InputError naming `option` for anything else.
/// At most `most` indices of [0, n), evenly spread, the first and last among
/// them (all when n <= most): the frames a plan samples.
std::vector<size_t> spreadIndices(size_t n, size_t most);

std::vector<long long> parseFrames(const std::string& range,
                                   const std::string& option = "--frames");

/// Runs one(input, output) for a single file, or, when input or output holds
/// a run of `#` or `frames` is given, for every frame of `frames` with the
/// frame number in both names; first checks every input exists and passes
/// checkInput (each frame's, a sequence's middle frame damaged was found
/// after the frames before it were written), calls checkOutput on the first
/// output and refuses an output that is an input or a link (checkSequenceTargets),
/// so that bad input fails before any work.
void forEachFile(const std::string& input, const std::string& output, const std::string& frames,
                 const std::function<void(const std::string&)>& checkInput,
                 const std::function<void(const std::string&)>& checkOutput,
                 const std::function<void(const std::string&, const std::string&)>& one);

}  // namespace cambium
