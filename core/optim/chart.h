// Convergence charts (PNG or SVG) drawn by matplotlib under Debian's /usr/bin/python3: the script
// (core/optim/chart.py) is compiled into the program, so nothing needs installing next to it.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace invr {

// x: "seconds" or "step"; y: "loss" or "param_error". Throws InputError with python's message
// when a CSV is unusable; std::runtime_error when python3 or matplotlib is missing.
void drawConvergenceChart(const std::vector<std::filesystem::path>& csvs, const std::filesystem::path& out,
                          const std::string& x = "seconds", const std::string& y = "param_error");

}  // namespace invr
