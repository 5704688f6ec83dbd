// invr: the command-line client.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <iostream>
#include <string>
#include <vector>

#include "client/commands.h"
#include "client/common/exit_codes.h"
#include "client/lab/lab_commands.h"
#include "core/error.h"
#include "core/io/suggest.h"
#include "invr_version.h"

int main(int argc, char** argv) {
  spdlog::set_default_logger(spdlog::stderr_color_mt("invr"));  // stdout is for results (and --json)
  CLI::App app{"invr: physics-based inverse rendering"};
  app.require_subcommand(1);
  int exitCode = invr::exit_code::kOk;
  invr::cli::addRenderCommand(app, exitCode);
  invr::cli::addZooCommand(app, exitCode);
  invr::cli::addBenchCommand(app, exitCode);
  invr::cli::addOptimizeCommands(app, exitCode);
  invr::cli::addServiceCommands(app, exitCode);
  invr::cli::addEvalCommand(app, exitCode);
  invr::cli::addImportCommand(app, exitCode);
  invr::cli::addExportCommand(app, exitCode);
  app.set_version_flag("--version", "invr " INVR_VERSION);
  // CLI11 answers an unknown first word with "a subcommand is required": name it instead.
  if (argc > 1 && argv[1][0] != '-') {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands({})) names.push_back(sub->get_name());
    if (std::find(names.begin(), names.end(), argv[1]) == names.end()) {
      std::string all;
      for (const auto& n : names) all += (all.empty() ? "" : ", ") + n;
      std::cerr << "invr: unknown command '" << argv[1] << "'" << invr::didYouMean(argv[1], names) << " (the commands are: " << all
                << "; invr --help)\n";
      return invr::exit_code::kUsage;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return invr::exit_code::kUsage;
  } catch (const invr::cli::ExitError& e) {
    if (*e.what()) std::cerr << "invr: " << e.what() << "\n";
    return e.code;
  } catch (const invr::InputError& e) {
    std::cerr << "invr: error: " << e.what() << "\n";
    return invr::exit_code::kInputError;
  } catch (const std::exception& e) {
    std::cerr << "invr: internal error: " << e.what() << "\n";
    return invr::exit_code::kInternal;
  }
  return exitCode;
}
