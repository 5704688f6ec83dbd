#include "core/optim/results_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/image/image.h"
#include "core/lights/light_selection.h"
#include "core/scene/scene.h"

namespace invr {

namespace {

using Json = nlohmann::ordered_json;  // keys in the registry's order

// One line with ", " and ": " separators. nlohmann writes the strings (escaped; bytes that are
// not UTF-8 become U+FFFD) and integers; values with 6 significant digits, null if not finite.
std::string oneLine(const Json& j) {
  std::string o;
  if (j.is_object()) {
    for (const auto& [k, v] : j.items()) o += (o.empty() ? "" : ", ") + oneLine(Json(k)) + ": " + oneLine(v);
    return "{" + o + "}";
  }
  if (j.is_array()) {
    for (const auto& v : j) o += (o.empty() ? "" : ", ") + oneLine(v);
    return "[" + o + "]";
  }
  if (j.is_number_float()) {
    double v = j.get<double>();
    if (!std::isfinite(v)) return "null";
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.6g", v);
    return buf;
  }
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

}  // namespace

std::vector<std::string> writeParameters(const std::filesystem::path& dir, const ParameterRegistry& params,
                                         const std::vector<float>& theta) {
  std::vector<std::string> files{"parameters.json"};
  Json js = Json::object();
  for (const ParameterSlot& s : params.slots()) {
    if (s.width > 0) {
      std::string file = s.name;
      std::replace(file.begin(), file.end(), '/', '_');
      file += ".exr";
      Image im(s.width, s.height, 3);
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x)
          for (int c = 0; c < 3; ++c)
            im.at(x, y, c) = theta[s.offset + size_t((y * s.width + x) * s.channels + std::min(c, s.channels - 1))];
      writeImage(dir / file, im);
      files.push_back(file);
      js[s.name] = {{"texture", file}, {"width", s.width}, {"height", s.height}};
    } else {
      Json values = Json::array();
      for (uint32_t k = 0; k < s.size; ++k) values.push_back(double(theta[s.offset + k]));
      js[s.name] = std::move(values);
    }
  }
  // One parameter per line.
  std::string text = "{\n";
  size_t i = 0;
  for (const auto& [name, value] : js.items())
    text += "  " + oneLine(Json(name)) + ": " + oneLine(value) + (++i < js.size() ? ",\n" : "\n");
  text += "}\n";
  std::ofstream out(dir / "parameters.json");
  if (!out) throw InputError("cannot write '" + (dir / "parameters.json").string() + "'");
  out << text;
  if (!out.flush()) throw InputError("cannot write '" + (dir / "parameters.json").string() + "'");
  return files;
}

std::vector<std::string> writeSelectionResults(const std::filesystem::path& dir, const ParameterRegistry& params, Scene& scene,
                                               const std::vector<float>& theta) {
  std::vector<std::string> files;
  if (!params.hasSamplingParameters()) return files;
  params.write(theta, scene);
  {
    std::ofstream out(dir / "light_selection.csv");
    out << "light,probability\n";
    for (size_t i = 0; i < scene.lights.size(); ++i) out << scene.lights[i].name << "," << scene.lightSelection().pmf(i) << "\n";
    if (!out.flush()) throw InputError("cannot write '" + (dir / "light_selection.csv").string() + "'");
    files.push_back("light_selection.csv");
  }
  std::vector<std::string> names;
  for (const Light& l : scene.lights) names.push_back(l.name);
  for (size_t v = 0; v < scene.sampling.pixelLogits.size(); ++v) {
    const auto& map = scene.sampling.pixelLogits[v];
    if (map.empty()) continue;
    const size_t n = scene.lights.size();
    ExrLayer layer{"", names, Image(map.width, map.height, int(n))};
    for (size_t cell = 0; cell < size_t(map.width) * size_t(map.height); ++cell) {
      std::vector<float> pmf = softmax(std::span<const float>(map.logits.data() + cell * n, n));
      std::copy(pmf.begin(), pmf.end(), layer.image.data().begin() + std::ptrdiff_t(cell * n));
    }
    std::string file = "selection_view" + std::to_string(v) + ".exr";
    writeExrLayers(dir / file, {layer});
    files.push_back(file);
  }
  return files;
}

}  // namespace invr
