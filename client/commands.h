// The user-facing commands of the CLI (the lab's are in client/lab/lab_commands.h).
#pragma once

#include <CLI/CLI.hpp>

namespace invr::cli {

// Each registers its subcommand on `app`; the callback runs the command and sets `exitCode`.
void addRenderCommand(CLI::App& app, int& exitCode);
void addZooCommand(CLI::App& app, int& exitCode);
void addOptimizeCommands(CLI::App& app, int& exitCode);
void addServiceCommands(CLI::App& app, int& exitCode);  // run, submit, watch, status, list, cancel, fetch, plan
void addImportCommand(CLI::App& app, int& exitCode);  // import: a Mitsuba 3 scene as job JSON
void addExportCommand(CLI::App& app, int& exitCode);  // export: a results folder as a Mitsuba 3 scene

}  // namespace invr::cli
