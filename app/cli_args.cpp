#include "app/cli_args.h"

#include <cstdio>

#include "core/error.h"

namespace lfgi::app {

worlds::CellCoord parseCellArg(const std::string& text, std::string_view flag) {
  int x = 0, z = 0;
  char comma = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &x, &comma, &z, &extra) != 3 || comma != ',')
    fail("{} '{}': expected X,Z (two integers)", flag, text);
  return {x, z};
}

}  // namespace lfgi::app
