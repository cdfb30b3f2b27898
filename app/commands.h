// Subcommand entry points of the lfgi CLI. Each returns the process exit code; errors are thrown as
// lfgi::Error and turned into exit code 1 by main().
#pragma once

#include <string>

namespace lfgi::app {

struct DeviceOptions {
  bool json = false;
};
int runDevice(const DeviceOptions& options);

struct DemoOptions {
  std::string outDir = "out/demo";
  int resolution = 64;
};
int runDemo(const DemoOptions& options);

}  // namespace lfgi::app
