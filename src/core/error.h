// cambium — error types.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace cambium {

/// Bad input from a user: a malformed file, an impossible parameter.  The
/// message names the problem and where it is; the CLI prints it and exits
/// with status 2 before touching any output.
class InputError : public std::runtime_error {
public:
    /// (A NUL the message quotes from a file is written \x00: what() is a C
    /// string, and the rest of the line would be lost after it.)
    explicit InputError(const std::string& what) : std::runtime_error(withoutNul(what)) {}
    explicit InputError(const char* what) : std::runtime_error(what) {}

private:
    static std::string withoutNul(const std::string& text);
};

/// A parameter of a node that is out of its domain, raised by the BlobTree
/// builders.  `field` names the parameter (for example "r0"), so that a scene
/// reader can turn it into a path such as root.children[1].r0.
class ParameterError : public InputError {
public:
    ParameterError(std::string field, const std::string& what)
        : InputError(what), field_(std::move(field))
    {
    }
    const std::string& field() const { return field_; }

private:
    std::string field_;
};

/// The index of `value` among an option's `names`, or InputError
/// "OPTION must be a, b or c (got 'VALUE')": the one parser of every option
/// that takes one of a few words (--device, --junctions, --colour, ...).
size_t optionChoice(const std::string& value, const std::vector<std::string>& names,
                    const char* option);

/// InputError "WHAT reaches FAR from the origin, N voxels of H: beyond
/// 1048576 voxels, ..." unless `far` (a distance from the origin, in the
/// model's units) is within kMaxVoxelsFromOrigin voxels of size `h`: the
/// one float-precision bound of bakes, meshes baked to level sets, shape
/// output and the level sets mesh and render read.
void checkVoxelsFromOrigin(double far, double h, const std::string& what);

/// A number as a message names it: "not a number" for a NaN (which {:g}
/// writes as "nan" or "-nan" by its sign bit), else as {:g} writes it.
std::string numberText(double v);

/// `text` as a message may show it: each control character (a newline, an
/// escape) written as \xHH, so that a line of output stays one line, and
/// each bidirectional control as \u{HHHH}, so that it reads as written.
std::string printable(const std::string& text);

/// `text` whole when it has at most `most` bytes, else its first two thirds
/// and last third of that with how much was left out between: an error that
/// quotes a 5 MB key stays a line (the file, the place and the problem are
/// at its ends).
std::string shortened(const std::string& text, size_t most);

/// Checks that `path` names a regular file that can be read, and returns its
/// size: InputError "PATH: cannot read the WHAT: REASON", "PATH: is a
/// directory, not a WHAT" or "PATH: is a device, FIFO or socket, not a WHAT".
uint64_t checkInputFile(const std::string& path, const char* what);

/// The largest text input read (a scene, L-system, skeleton or parameter file).
constexpr uint64_t kMaxTextFileBytes = uint64_t(1) << 30;

/// The whole text of a file (checkInputFile, at most kMaxTextFileBytes),
/// without a UTF-8 byte-order mark; a binary file is refused by name ("PATH: is a .vdb file (a
/// baked level set), not a WHAT", "PATH: a binary file, not a WHAT").
std::string readTextFile(const std::string& path, const char* what);

}  // namespace cambium
