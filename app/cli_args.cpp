#include "app/cli_args.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>

#include "core/error.h"

namespace lfgi::app {

worlds::CellCoord parseCellArg(const std::string& text, std::string_view flag) {
  int x = 0, z = 0;
  char comma = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &x, &comma, &z, &extra) != 3 || comma != ',')
    fail("{} '{}': expected X,Z (two integers)", flag, text);
  return {x, z};
}

std::vector<float> parseNumbers(const std::string& flag, const std::string& text, size_t count,
                                const char* what) {
  std::vector<float> v;
  size_t start = 0;
  while (start <= text.size()) {
    const size_t end = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, end - start);
    char* stop = nullptr;
    const float x = std::strtof(item.c_str(), &stop);
    if (item.empty() || stop != item.c_str() + item.size() || !std::isfinite(x))
      fail("{} '{}': expected {} ({} comma-separated numbers); '{}' is not a finite number", flag, text, what,
           count, item);
    v.push_back(x);
    start = end + 1;
  }
  if (v.size() != count) fail("{} '{}': expected {} ({} numbers), got {}", flag, text, what, count, v.size());
  return v;
}

void requireSaneNumbers(CLI::App& app) {
  const CLI::Validator finite(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const long double v = std::strtold(text.c_str(), &end);
        if (end != text.c_str() + text.size()) return {};  // not a number: CLI11's own conversion reports it
        if (!std::isfinite(v)) return "value " + text + " is not a finite number";
        if (std::fabs(v) > std::numeric_limits<float>::max()) return "value " + text + " is out of range";
        return {};
      },
      "");
  const CLI::Validator integer(
      [](std::string& text) -> std::string {
        if (text.find('-') != std::string::npos && text.find_first_not_of(" \t") == text.find('-'))
          return "value " + text + " is negative";
        errno = 0;
        char* end = nullptr;
        (void)std::strtoull(text.c_str(), &end, 0);
        if (end == text.c_str() + text.size() && errno == ERANGE) return "value " + text + " is out of range";
        return {};
      },
      "");
  const CLI::Validator signedInteger(
      [](std::string& text) -> std::string {
        errno = 0;
        char* end = nullptr;
        (void)std::strtoll(text.c_str(), &end, 0);
        if (end == text.c_str() + text.size() && errno == ERANGE) return "value " + text + " is out of range";
        return {};
      },
      "");
  for (CLI::Option* o : app.get_options()) {
    const std::string type = o->get_type_name().substr(0, o->get_type_name().find(':'));
    if (type == "FLOAT") o->check(finite);
    if (type == "UINT") o->check(integer);
    if (type == "INT") o->check(signedInteger);
  }
  for (CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) requireSaneNumbers(*sub);
}

std::optional<tbb::global_control> threadLimit(int threads) {
  if (threads <= 0) return std::nullopt;
  return std::make_optional<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                 size_t(threads));
}

}  // namespace lfgi::app
