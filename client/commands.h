#pragma once

#include <CLI/CLI.hpp>

namespace invr::cli {

// Each registers its subcommand on `app`; the callback runs the command and sets `exitCode`.
void addRenderCommand(CLI::App& app, int& exitCode);
void addZooCommand(CLI::App& app, int& exitCode);
void addBenchCommand(CLI::App& app, int& exitCode);
void addBenchGradientCommands(CLI::App& bench, int& exitCode);
void addOptimizeCommands(CLI::App& app, int& exitCode);
void addServiceCommands(CLI::App& app, int& exitCode);  // run, submit, watch, status, list, cancel, fetch, plan
void addBenchServiceCommand(CLI::App& bench, int& exitCode);
void addBenchFakeWorkerCommand(CLI::App& bench, int& exitCode);
void addBenchPixelCommand(CLI::App& bench, int& exitCode);
void addBenchVarianceCommand(CLI::App& bench, int& exitCode);
void addEvalCommand(CLI::App& app, int& exitCode);  // eval: the speed-against-accuracy suite
void addImportCommand(CLI::App& app, int& exitCode);  // import: a Mitsuba 3 scene as job JSON

}  // namespace invr::cli
