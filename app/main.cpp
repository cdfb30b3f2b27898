// lfgi: the command line. Subcommands are small functions in app/; library code does the work.
// Exit codes: 0 success, 1 runtime error (message names the file/device and the problem), 2 bad usage.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <string>

#include "app/commands.h"
#include "core/error.h"

int main(int argc, char** argv) {
  CLI::App app{"lfgi: streaming open-world global illumination from generative light fields"};
  app.set_version_flag("--version", std::string("lfgi ") + LFGI_VERSION);
  app.require_subcommand(0, 1);
  bool verbose = false;
  app.add_flag("-v,--verbose", verbose, "Log debug messages");

  lfgi::app::DeviceOptions deviceOpt;
  CLI::App* device = app.add_subcommand("device", "Print the Vulkan device lfgi would use and its limits");
  device->add_flag("--json", deviceOpt.json, "Print JSON instead of text");

  lfgi::app::DemoOptions demoOpt;
  CLI::App* demo = app.add_subcommand(
      "demo", "End-to-end check on this machine: GPU octahedral probe pass, SH vs brute-force irradiance, report");
  demo->add_option("--out", demoOpt.outDir, "Output directory")->capture_default_str();
  demo->add_option("--resolution", demoOpt.resolution, "Octahedral map resolution (texels per side)")
      ->check(CLI::Range(4, 512))
      ->capture_default_str();

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "lfgi: %s\nRun 'lfgi --help' for usage.\n", e.what());
    return 2;
  }
  spdlog::set_level(verbose ? spdlog::level::debug : spdlog::level::info);

  try {
    if (*device) return lfgi::app::runDevice(deviceOpt);
    if (*demo) return lfgi::app::runDemo(demoOpt);
    std::fputs(app.help().c_str(), stdout);
    return 0;
  } catch (const lfgi::Error& e) {
    std::fprintf(stderr, "lfgi: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "lfgi: internal error: %s\n", e.what());
    return 1;
  }
}
