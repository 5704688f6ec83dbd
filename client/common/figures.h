// Figures drawn by matplotlib under Debian's /usr/bin/python3: convergence charts and
// side-by-side image grids, by the client only (the renderer and the server write CSVs and
// images; charts are drawn where someone looks at them). The script (client/common/figures.py) is
// compiled into the program, so nothing needs installing next to it.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace invr {

// x: "seconds" or "step"; y: "loss", "param_error", "image_error" or "shape_error". A CSV may hold several
// methods (one line each). Throws InputError with python's message when a CSV is unusable;
// std::runtime_error when python3 or matplotlib is missing.
void drawConvergenceChart(const std::vector<std::filesystem::path>& csvs, const std::filesystem::path& out,
                          const std::string& x = "seconds", const std::string& y = "param_error",
                          const std::string& title = "");

// A grid of PNG images with column titles, row labels and a caption under each cell (an empty
// image path leaves the cell blank).
struct GridCell {
  std::filesystem::path image;
  std::string caption;
};
struct GridRow {
  std::string label;
  std::vector<GridCell> cells;  // one per column
};
void drawImageGrid(const std::string& title, const std::vector<std::string>& columns, const std::vector<GridRow>& rows,
                   const std::filesystem::path& out);

}  // namespace invr
