#include "client/common/figures.h"

#include <unistd.h>

#include <atomic>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "client/common/figures_script.h"  // kFiguresScript, generated from client/common/figures.py
#include "client/common/process.h"
#include "core/error.h"

namespace invr {

namespace {

void checkOutput(const std::filesystem::path& out) {
  std::string ext = out.extension().string();
  if (ext != ".png" && ext != ".svg") throw InputError("-o: figures are .png or .svg (got '" + out.string() + "')");
  std::error_code ec;
  if (out.has_parent_path()) std::filesystem::create_directories(out.parent_path(), ec);
  if (ec) throw InputError("-o: cannot create the folder '" + out.parent_path().string() + "': " + ec.message());
}

// Runs the figures script with `args` after the script; python's complaint becomes the error.
void runFiguresScript(const std::vector<std::string>& scriptArgs) {
  const char* python = "/usr/bin/python3";  // Debian's, where python3-matplotlib lives
  if (access(python, X_OK) != 0) throw std::runtime_error("figures need /usr/bin/python3 with matplotlib (deploy/setup.sh installs them)");
  std::vector<std::string> args = {python, "-c", kFiguresScript};
  args.insert(args.end(), scriptArgs.begin(), scriptArgs.end());
  // python's complaints come back through a file, to be reported as the error.
  static std::atomic<int> serial{0};
  std::filesystem::path err = std::filesystem::temp_directory_path() /
                              ("invr-figure-" + std::to_string(getpid()) + "-" + std::to_string(serial++) + ".err");
  const int status = cli::waitProcess(cli::spawnProcess(args, "/dev/null", err));
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  std::error_code ec;
  std::filesystem::remove(err, ec);
  std::string msg = ss.str();
  while (!msg.empty() && (msg.back() == '\n' || msg.back() == ' ')) msg.pop_back();
  if (status != 0) {
    if (msg.find("No module named 'matplotlib'") != std::string::npos)
      throw std::runtime_error("figures need python3-matplotlib (deploy/setup.sh installs it)");
    // The script's own messages are one line about the input; anything else is its last line.
    size_t nl = msg.rfind('\n');
    throw InputError("figure: " + (nl == std::string::npos ? msg : msg.substr(nl + 1)));
  }
}

}  // namespace

void drawConvergenceChart(const std::vector<std::filesystem::path>& csvs, const std::filesystem::path& out, const std::string& x,
                          const std::string& y, const std::string& title) {
  checkOutput(out);
  for (const auto& c : csvs)
    if (!std::filesystem::exists(c)) throw InputError("'" + c.string() + "': not found");
  std::vector<std::string> args = {"chart", out.string(), x, y, title};
  for (const auto& c : csvs) args.push_back(c.string());
  runFiguresScript(args);
}

void drawImageGrid(const std::string& title, const std::vector<std::string>& columns, const std::vector<GridRow>& rows,
                   const std::filesystem::path& out) {
  checkOutput(out);
  nlohmann::ordered_json grid = {{"title", title}, {"columns", columns}, {"rows", nlohmann::ordered_json::array()}};
  for (const GridRow& row : rows) {
    if (row.cells.size() != columns.size()) throw std::logic_error("image grid: row '" + row.label + "' has the wrong cell count");
    nlohmann::ordered_json cells = nlohmann::ordered_json::array();
    for (const GridCell& cell : row.cells)
      cells.push_back({{"image", cell.image.empty() ? nlohmann::ordered_json() : nlohmann::ordered_json(cell.image.string())},
                       {"caption", cell.caption}});
    grid["rows"].push_back({{"label", row.label}, {"cells", std::move(cells)}});
  }
  // ASCII only (non-ASCII escaped), so python reads it whatever its locale; bytes that are not
  // UTF-8 become U+FFFD rather than an error.
  const std::string js = grid.dump(-1, ' ', true, nlohmann::ordered_json::error_handler_t::replace);
  std::filesystem::path spec = out;
  spec += ".grid.json";
  {
    std::ofstream f(spec);
    if (!f) throw InputError("cannot write '" + spec.string() + "'");
    f << js;
  }
  runFiguresScript({"grid", out.string(), spec.string()});
  std::error_code ec;
  std::filesystem::remove(spec, ec);
}

}  // namespace invr
