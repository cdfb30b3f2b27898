// Parsing of the CLI's compound option values. Errors are lfgi::Error naming the flag and the value, so
// main() turns them into exit code 1 with a message a user can act on.
#pragma once

#include <string>
#include <string_view>

#include "worlds/synthetic_world.h"

namespace lfgi::app {

// "X,Z" (two integers) -> cell coordinate; throws lfgi::Error "<flag> '<text>': expected X,Z ...".
worlds::CellCoord parseCellArg(const std::string& text, std::string_view flag);

}  // namespace lfgi::app
