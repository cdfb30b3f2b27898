// Parsing of the CLI's compound option values, and the --threads limit every subcommand applies. Errors
// are lfgi::Error naming the flag and the value, so main() turns them into exit code 1 with a message a
// user can act on.
#pragma once

#include <tbb/global_control.h>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "worlds/synthetic_world.h"

namespace CLI {
class App;
}

namespace lfgi::app {

// Adds to every number option of app and its subcommands (recursively) the checks CLI11 2.1 lacks:
// floating-point values must be finite and within float range (CLI11 parses "nan" and "inf", and NaN
// passes its Range validators); unsigned values must not be negative (strtoull turns "-1" into 2^64 - 1);
// no integer may overflow. A failing value is a usage error (exit 2) naming the flag and the value.
void requireSaneNumbers(CLI::App& app);

// "X,Z" (two integers) -> cell coordinate; throws lfgi::Error "<flag> '<text>': expected X,Z ...".
worlds::CellCoord parseCellArg(const std::string& text, std::string_view flag);

// Comma-separated numbers; throws lfgi::Error naming flag unless there are exactly `count` finite ones
// (`what` describes them, e.g. "px,py,pz,tx,ty,tz").
std::vector<float> parseNumbers(const std::string& flag, const std::string& text, size_t count,
                                const char* what);

// --threads N: caps TBB's parallelism for as long as the returned object lives; N <= 0 leaves all cores.
std::optional<tbb::global_control> threadLimit(int threads);

}  // namespace lfgi::app
