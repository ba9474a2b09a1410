// cambium — the JSON scene format (docs/scene-format.md).
#pragma once

#include "blobtree/blobtree.h"

#include <string>

namespace cambium {

/// Parses a scene.  `source` names it in error messages (usually the file
/// name).  Throws InputError with "<source>: <json path>: <problem>" for a
/// malformed scene, or "<source>:<line>:<column>: ..." for a JSON syntax error.
/// The returned tree is finalized.
BlobTree parseScene(const std::string& text, const std::string& source);

/// Reads and parses a scene file.
BlobTree loadScene(const std::string& path);

}  // namespace cambium
