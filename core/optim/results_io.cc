#include "core/optim/results_io.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/image/image.h"
#include "core/io/mesh_io.h"
#include "core/math/decimal.h"
#include "core/lights/light_selection.h"
#include "core/scene/scene.h"
#include "core/diff/parameter_kind.h"

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

std::vector<std::pair<std::string, std::vector<double>>> smallParameterValues(const ParameterRegistry& params, const std::vector<float>& theta,
                                                                               uint32_t maxValues) {
  std::vector<std::pair<std::string, std::vector<double>>> out;
  for (const ParameterSlot& s : params.slots()) {
    if (s.kind->isMesh() || s.width > 0 || s.size > maxValues || s.offset + s.size > theta.size()) continue;
    std::vector<double> v;
    for (uint32_t k = 0; k < s.size; ++k) v.push_back(shortestDecimal(theta[s.offset + k]));
    out.emplace_back(s.name, std::move(v));
  }
  return out;
}

std::vector<std::string> writeParameters(const std::filesystem::path& dir, const ParameterRegistry& params,
                                         const std::vector<float>& theta, const Scene& scene) {
  std::vector<std::string> files{"parameters.json"};
  Json js = Json::object();
  for (const ParameterSlot& s : params.slots()) {
    if (s.kind->isMesh()) {
      const std::string file = "mesh_" + scene.meshNames[size_t(s.shape)] + ".ply";
      const TriangleMesh mesh = params.vertexMesh(scene, s, theta.data() + s.offset);
      writePly(dir / file, mesh);
      files.push_back(file);
      js[s.name] = {{"mesh", file}, {"vertices", mesh.positions.size()}, {"triangles", mesh.triangleCount()}};
      continue;
    }
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

void readParameters(const std::filesystem::path& dir, const ParameterRegistry& params, std::vector<float>& theta) {
  const auto path = dir / "parameters.json";
  std::ifstream in(path);
  if (!in) throw InputError("'" + path.string() + "': cannot read it");
  Json js;
  try {
    js = Json::parse(in);
  } catch (const Json::exception& e) {
    throw InputError("'" + path.string() + "': not JSON (" + e.what() + ")");
  }
  if (!js.is_object()) throw InputError("'" + path.string() + "': expected an object of parameters");
  theta.resize(params.size());
  for (const ParameterSlot& s : params.slots()) {
    const std::string where = "'" + path.string() + "': parameter '" + s.name + "'";
    if (!js.contains(s.name)) throw InputError(where + " is missing (the results are of another job?)");
    const Json& v = js[s.name];
    float* out = theta.data() + s.offset;
    auto fileOf = [&](const char* key) {
      if (!v[key].is_string()) throw InputError(where + ": '" + key + "' must name a file");
      return dir / v[key].get<std::string>();
    };
    if (v.is_object() && v.contains("mesh")) {
      const TriangleMesh mesh = loadMesh(fileOf("mesh"));
      if (mesh.positions.size() * 3 != s.size)
        throw InputError(where + ": its mesh has " + std::to_string(mesh.positions.size()) + " vertices, the parameter " +
                         std::to_string(s.size / 3));
      for (size_t i = 0; i < mesh.positions.size(); ++i)
        for (int c = 0; c < 3; ++c) out[3 * i + size_t(c)] = mesh.positions[i][c];
    } else if (v.is_object() && v.contains("texture")) {
      const Image im = readImage(fileOf("texture"), false);
      if (im.width() != s.width || im.height() != s.height)
        throw InputError(where + ": its texture is " + std::to_string(im.width()) + "x" + std::to_string(im.height()) + ", the parameter " +
                         std::to_string(s.width) + "x" + std::to_string(s.height));
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x)
          for (int c = 0; c < s.channels; ++c) out[size_t((y * s.width + x) * s.channels + c)] = im.at(x, y, std::min(c, im.channels() - 1));
    } else if (v.is_array() && v.size() == s.size) {
      for (uint32_t k = 0; k < s.size; ++k) {
        if (!v[k].is_number()) throw InputError(where + ": value " + std::to_string(k) + " is not a number");
        out[k] = v[k].get<float>();
      }
    } else {
      throw InputError(where + ": expected " + std::to_string(s.size) + " numbers, a texture or a mesh");
    }
  }
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

namespace {

namespace pb = google::protobuf;

std::string number(double v) {
  if (!std::isfinite(v)) return "";
  char b[32];
  std::snprintf(b, sizeof b, "%.9g", v);
  return b;
}

// Every scalar of `m` as (column, text), fields in declaration order, map entries by key in the
// order they are stored (the writer keeps the first-seen order across rows).
void flatten(const pb::Message& m, const std::string& prefix, std::vector<std::pair<std::string, std::string>>& out) {
  const pb::Descriptor* d = m.GetDescriptor();
  const pb::Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    const std::string name = prefix + f->name();
    if (f->is_map()) {
      std::vector<std::pair<std::string, const pb::Message*>> entries;
      for (int k = 0; k < r->FieldSize(m, f); ++k) {
        const pb::Message& e = r->GetRepeatedMessage(m, f, k);
        entries.emplace_back(e.GetReflection()->GetString(e, f->message_type()->map_key()), &e);
      }
      std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      for (const auto& [key, e] : entries) {
        const pb::FieldDescriptor* vf = f->message_type()->map_value();
        if (vf->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE)
          flatten(e->GetReflection()->GetMessage(*e, vf), name + "." + key + ".", out);
        else
          out.emplace_back(name + "." + key, std::to_string(e->GetReflection()->GetUInt64(*e, vf)));
      }
      continue;
    }
    switch (f->cpp_type()) {
      case pb::FieldDescriptor::CPPTYPE_MESSAGE: flatten(r->GetMessage(m, f), name + ".", out); break;
      case pb::FieldDescriptor::CPPTYPE_DOUBLE: out.emplace_back(name, number(r->GetDouble(m, f))); break;
      case pb::FieldDescriptor::CPPTYPE_FLOAT: out.emplace_back(name, number(double(r->GetFloat(m, f)))); break;
      case pb::FieldDescriptor::CPPTYPE_UINT64: out.emplace_back(name, std::to_string(r->GetUInt64(m, f))); break;
      case pb::FieldDescriptor::CPPTYPE_UINT32: out.emplace_back(name, std::to_string(r->GetUInt32(m, f))); break;
      case pb::FieldDescriptor::CPPTYPE_INT64: out.emplace_back(name, std::to_string(r->GetInt64(m, f))); break;
      case pb::FieldDescriptor::CPPTYPE_INT32: out.emplace_back(name, std::to_string(r->GetInt32(m, f))); break;
      default: break;  // no strings or lists in the statistics
    }
  }
}

std::string csvText(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

}  // namespace

void ConvergenceCsv::write() const {
  std::vector<std::string> columns;
  std::map<std::string, size_t> index;
  std::vector<std::vector<std::pair<std::string, std::string>>> cells(rows_.size());
  for (size_t i = 0; i < rows_.size(); ++i) {
    if (!rows_[i].stats) continue;
    const invr::v1::GradientStats& stats = *rows_[i].stats;
    flatten(stats, "", cells[i]);
    // The statistics' loss is the row's own loss column.
    std::erase_if(cells[i], [](const auto& cell) { return cell.first == "loss"; });
    for (const auto& [c, v] : cells[i])
      if (index.emplace(c, columns.size()).second) columns.push_back(c);
  }
  bool shapes = false, imageLosses = false;
  for (const ConvergenceRow& r : rows_) {
    shapes = shapes || r.shapeError >= 0;
    imageLosses = imageLosses || std::isfinite(r.imageLoss);
  }
  std::string text = shapes ? "method,step,seconds,loss,param_error,image_error,shape_error" : "method,step,seconds,loss,param_error,image_error";
  if (imageLosses) text += ",image_loss";
  for (const std::string& c : columns) text += "," + c;
  text += "\n";
  for (size_t i = 0; i < rows_.size(); ++i) {
    const ConvergenceRow& r = rows_[i];
    text += csvText(r.method) + "," + std::to_string(r.step) + "," + number(r.seconds) + "," + number(r.loss) + "," + number(r.paramError) + "," +
            number(r.imageError);
    if (shapes) text += "," + number(r.shapeError);
    if (imageLosses) text += "," + number(r.imageLoss);
    std::vector<std::string> row(columns.size());
    for (const auto& [c, v] : cells[i]) row[index[c]] = v;
    for (const std::string& v : row) text += "," + v;
    text += "\n";
  }
  std::error_code ec;
  if (path_.has_parent_path()) std::filesystem::create_directories(path_.parent_path(), ec);
  std::ofstream out(path_);
  if (!out) throw InputError("cannot write '" + path_.string() + "'");
  out << text;
  if (!out.flush()) throw InputError("cannot write '" + path_.string() + "'");
}

}  // namespace invr
