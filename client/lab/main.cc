// invr-lab: the research lab's executable: benchmarks (`invr-lab bench ...`) and the
// speed-against-accuracy suite (`invr-lab eval`). The user's commands are invr's.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>

#include "client/common/cli_main.h"
#include "client/common/exit_codes.h"
#include "client/lab/lab_commands.h"
#include "invr_version.h"

int main(int argc, char** argv) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("invr-lab"));  // stdout is for figures (and --json)
  CLI::App app{"invr-lab: invr's benchmarks and evaluation suite (figures, ratios measured in one run; docs/lab.md)"};
  app.require_subcommand(1);
  int exitCode = invr::exit_code::kOk;
  invr::cli::addBenchCommand(app, exitCode);
  invr::cli::addEvalCommand(app, exitCode);
  app.set_version_flag("--version", "invr-lab " INVR_VERSION);
  return invr::cli::runCommandLine(app, argc, argv, "invr-lab", exitCode);
}
