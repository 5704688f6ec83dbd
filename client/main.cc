// invr: the command-line client (the lab's benchmarks are a separate executable, invr-lab).
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <memory>
#include <utility>
#include <vector>
#include <stdexcept>
#include <string>

#include "client/commands.h"
#include "client/common/cli_main.h"
#include "client/common/exit_codes.h"
#include "invr_version.h"

int main(int argc, char** argv) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("invr"));  // stdout is for results (and --json)
  CLI::App app{"invr: physics-based inverse rendering.\nStart with `invr run cornell` (a zoo job on an embedded server with local workers)."};
  app.require_subcommand(1);
  int exitCode = invr::exit_code::kOk;
  // Registration order is the order --help lists them in, within each group: `run` first.
  invr::cli::addServiceCommands(app, exitCode);
  invr::cli::addOptimizeCommands(app, exitCode);
  invr::cli::addZooCommand(app, exitCode);
  invr::cli::addRenderCommand(app, exitCode);
  invr::cli::addImportCommand(app, exitCode);
  invr::cli::addExportCommand(app, exitCode);
  // --help lists the commands by what a user is doing, in this order.
  static const std::vector<std::pair<std::string, std::vector<std::string>>> kGroups = {
      {"Run a job", {"run", "optimize", "plan"}},
      {"A server's jobs", {"submit", "watch", "status", "list", "cancel", "fetch"}},
      {"Scenes and results", {"zoo", "example", "params", "render", "import", "export", "chart"}},
      {"The service", {"workers"}},
  };
  for (CLI::App* sub : app.get_subcommands({})) {
    bool found = false;
    for (const auto& [group, names] : kGroups)
      if (std::find(names.begin(), names.end(), sub->get_name()) != names.end()) sub->group(group), found = true;
    if (!found) throw std::logic_error("invr: command '" + sub->get_name() + "' has no --help group");
  }
  struct GroupedHelp : CLI::Formatter {
    std::string make_subcommands(const CLI::App* a, CLI::AppFormatMode mode) const override {
      if (a->get_parent() != nullptr || mode == CLI::AppFormatMode::All) return CLI::Formatter::make_subcommands(a, mode);
      std::string out;
      for (const auto& [group, names] : kGroups) {
        out += "\n" + group + ":\n";
        for (const auto& n : names) out += make_subcommand(a->get_subcommand(n));
      }
      return out;
    }
  };
  app.formatter(std::make_shared<GroupedHelp>());
  app.footer("The service runs on its own as invr-server and invr-worker (each with --help); benchmarks and the\n"
             "evaluation suite are invr-lab's (invr-lab --help). Documentation: README.md and docs/cli.md.");
  app.set_version_flag("--version", "invr " INVR_VERSION);
  if (argc > 1 && (std::string(argv[1]) == "bench" || std::string(argv[1]) == "eval")) {
    std::cerr << "invr: '" << argv[1] << "' is the lab's: run `invr-lab " << argv[1] << " ...` (invr-lab --help)\n";
    return invr::exit_code::kUsage;
  }
  return invr::cli::runCommandLine(app, argc, argv, "invr", exitCode);
}
