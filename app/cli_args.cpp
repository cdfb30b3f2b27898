#include "app/cli_args.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "core/error.h"

namespace lfgi::app {

worlds::CellCoord parseCellArg(const std::string& text, std::string_view flag) {
  int x = 0, z = 0;
  char comma = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &x, &comma, &z, &extra) != 3 || comma != ',')
    fail("{} '{}': expected X,Z (two integers)", flag, text);
  return {x, z};
}

std::vector<float> parseNumbers(const std::string& flag, const std::string& text, size_t count, const char* what) {
  std::vector<float> v;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, end - start);
    char* stop = nullptr;
    const float x = std::strtof(item.c_str(), &stop);
    if (item.empty() || stop != item.c_str() + item.size() || !std::isfinite(x))
      fail("{} '{}': expected {} ({} comma-separated numbers); '{}' is not a finite number", flag, text, what, count,
           item);
    v.push_back(x);
    start = end + 1;
  }
  if (v.size() != count) fail("{} '{}': expected {} ({} numbers), got {}", flag, text, what, count, v.size());
  return v;
}

}  // namespace lfgi::app
