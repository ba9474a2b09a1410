// cambium — error types.
#pragma once

#include <stdexcept>
#include <string>

namespace cambium {

/// Bad input from a user: a malformed file, an impossible parameter.  The
/// message names the problem and where it is; the CLI prints it and exits
/// with status 2 before touching any output.
class InputError : public std::runtime_error {
public:
    using std::runtime_error::runtime_error;
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

/// The whole text of a file; InputError "<path>: cannot read the <what>: <reason>".
std::string readTextFile(const std::string& path, const char* what);

}  // namespace cambium
