// lfgi::Error: the one exception type for bad input and failed operations. Its message names the file
// (or device, or flag) and the problem, so a user can act on it without a debugger.
#pragma once

#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace lfgi {

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws lfgi::Error with a fmt-formatted message.
template <typename... Args>
[[noreturn]] void fail(fmt::format_string<Args...> format, Args&&... args) {
  throw Error(fmt::format(format, std::forward<Args>(args)...));
}

}  // namespace lfgi
