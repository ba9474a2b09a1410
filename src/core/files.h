// cambium — output files that appear whole or not at all.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace cambium {

/// The name of the temporary file that writeAtomically writes before renaming.
std::string temporaryPathFor(const std::string& path);

/// Fails early, before any work, when `path` cannot be created (missing
/// directory, no permission): creates and removes a temporary file beside it.
void checkWritable(const std::string& path);

/// The lower-case extension of `path` (without the dot) when it is one of
/// `allowed`; else InputError "PATH: unknown KIND format '.EXT' (use .A or .B)".
std::string fileFormat(const std::string& path, const std::vector<std::string>& allowed, const char* kind);

/// Calls write(tmp) to write the file to a temporary name beside `path`, then
/// renames it over `path`: a crash or an error never leaves a half-written
/// file.  An exception from `write` removes the temporary file and is
/// reported as an InputError naming `path`.
void writeAtomically(const std::string& path, const std::function<void(const std::string& tmp)>& write);

}  // namespace cambium
