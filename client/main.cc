// invr: the command-line client.
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <iostream>

#include "client/commands.h"
#include "client/common/exit_codes.h"
#include "client/lab/lab_commands.h"
#include "core/error.h"

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
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
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
