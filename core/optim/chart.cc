#include "core/optim/chart.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/optim/chart_script.h"  // kChartScript, generated from core/optim/chart.py

extern char** environ;

namespace invr {

void drawConvergenceChart(const std::vector<std::filesystem::path>& csvs, const std::filesystem::path& out, const std::string& x,
                          const std::string& y) {
  const char* python = "/usr/bin/python3";  // Debian's, where python3-matplotlib lives
  if (access(python, X_OK) != 0) throw std::runtime_error("charts need /usr/bin/python3 with matplotlib (deploy/setup.sh installs them)");
  std::string ext = out.extension().string();
  if (ext != ".png" && ext != ".svg") throw InputError("-o: charts are .png or .svg (got '" + out.string() + "')");
  for (const auto& c : csvs)
    if (!std::filesystem::exists(c)) throw InputError("'" + c.string() + "': not found");
  std::vector<std::string> args = {python, "-c", kChartScript, out.string(), x, y};
  for (const auto& c : csvs) args.push_back(c.string());
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  // python's complaints come back through a file, to be reported as the error.
  std::filesystem::path err = std::filesystem::temp_directory_path() / ("invr-chart-" + std::to_string(getpid()) + ".err");
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
  pid_t pid = 0;
  int rc = posix_spawn(&pid, python, &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) throw std::runtime_error(std::string("cannot run /usr/bin/python3: ") + std::strerror(rc));
  int status = 0;
  waitpid(pid, &status, 0);
  std::ifstream in(err);
  std::stringstream ss;
  ss << in.rdbuf();
  std::error_code ec;
  std::filesystem::remove(err, ec);
  std::string msg = ss.str();
  while (!msg.empty() && (msg.back() == '\n' || msg.back() == ' ')) msg.pop_back();
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    if (msg.find("No module named 'matplotlib'") != std::string::npos)
      throw std::runtime_error("charts need python3-matplotlib (deploy/setup.sh installs it)");
    // The script's own messages are one line about the input; anything else is its last line.
    size_t nl = msg.rfind('\n');
    throw InputError("chart: " + (nl == std::string::npos ? msg : msg.substr(nl + 1)));
  }
}

}  // namespace invr
