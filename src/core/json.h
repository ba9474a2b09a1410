// cambium — reading JSON input files: one parser for scenes and growth
// parameter files that names syntax errors by line and column, refuses
// duplicate keys and caps the nesting depth.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

namespace cambium {

/// Deeper nesting than this is refused (a scene node takes two levels: the
/// object and its "children" array).
constexpr int kMaxJsonDepth = 512;

/// Parses `text` (comments allowed) read from `source`.  InputError
/// "SOURCE: JSON syntax error: ... at line L, column C", "SOURCE: PATH: duplicate
/// key 'K' (JSON keeps one of them silently: remove the other)" or
/// "SOURCE: PATH: nested more than N levels deep".
nlohmann::json parseJson(const std::string& text, const std::string& source);

}  // namespace cambium
