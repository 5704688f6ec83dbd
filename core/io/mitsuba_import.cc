#include "core/io/mitsuba_import.h"

#include <pugixml.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/math/affine.h"
#include "core/io/job_io.h"
#include "core/limits.h"

namespace invr {

namespace fs = std::filesystem;

bool isMitsubaSceneFile(const std::string& path) {
  if (path.size() < 4) return false;
  std::string ext = path.substr(path.size() - 4);
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext == ".xml";
}

namespace {

constexpr double kPiD = 3.14159265358979323846;
// Scene files describe; meshes and images carry the bulk. Anything larger is a mistake (or
// /dev/zero named in an <include>).
constexpr uintmax_t kMaxSceneFileBytes = uintmax_t(64) << 20;

std::string readSceneFile(const fs::path& p, const std::string& what) {
  std::error_code ec;
  if (!fs::is_regular_file(p, ec)) throw InputError(what + " '" + p.string() + "': not a readable file");
  const uintmax_t size = fs::file_size(p, ec);
  if (ec) throw InputError(what + " '" + p.string() + "': cannot be read");
  if (size > kMaxSceneFileBytes)
    throw ResourceError(what + " '" + p.string() + "': " + humanBytes(size) + " (scene files are limited to " + humanBytes(kMaxSceneFileBytes) + ")");
  std::ifstream in(p, std::ios::binary);
  if (!in) throw InputError(what + " '" + p.string() + "': cannot be read");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}


using D3 = std::array<double, 3>;
// Mitsuba composes to_world in double: points and directions through it, kept in double.
D3 applyPoint(const Affine3d& a, D3 p) {
  return {a.m[0][0] * p[0] + a.m[0][1] * p[1] + a.m[0][2] * p[2] + a.m[0][3], a.m[1][0] * p[0] + a.m[1][1] * p[1] + a.m[1][2] * p[2] + a.m[1][3],
          a.m[2][0] * p[0] + a.m[2][1] * p[1] + a.m[2][2] * p[2] + a.m[2][3]};
}
D3 applyVector(const Affine3d& a, D3 v) {
  return {a.m[0][0] * v[0] + a.m[0][1] * v[1] + a.m[0][2] * v[2], a.m[1][0] * v[0] + a.m[1][1] * v[1] + a.m[1][2] * v[2],
          a.m[2][0] * v[0] + a.m[2][1] * v[1] + a.m[2][2] * v[2]};
}
D3 sub(D3 a, D3 b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
D3 add(D3 a, D3 b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
D3 crossD(D3 a, D3 b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double dotD(D3 a, D3 b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double lenD(D3 a) { return std::sqrt(dotD(a, a)); }
D3 scaleD(D3 a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }

v1::Vec3 toVec(D3 a) {
  v1::Vec3 v;
  v.set_x(a[0]);
  v.set_y(a[1]);
  v.set_z(a[2]);
  return v;
}
v1::Rgb toRgb(D3 a) {
  v1::Rgb c;
  c.set_r(a[0]);
  c.set_g(a[1]);
  c.set_b(a[2]);
  return c;
}

// Named indices of refraction (Mitsuba accepts these names for int_ior / ext_ior).
const std::map<std::string, double>& iorTable() {
  static const std::map<std::string, double> t = {
      {"vacuum", 1.0},          {"helium", 1.00004},      {"hydrogen", 1.00013},    {"air", 1.000277},
      {"carbon dioxide", 1.00045}, {"water", 1.333},      {"acetone", 1.36},        {"ethanol", 1.361},
      {"carbon tetrachloride", 1.461}, {"glycerol", 1.4729}, {"benzene", 1.501},    {"silicone oil", 1.52045},
      {"bromine", 1.661},       {"water ice", 1.31},      {"fused quartz", 1.458},  {"pyrex", 1.470},
      {"acrylic glass", 1.49},  {"polypropylene", 1.49},  {"bk7", 1.5046},          {"sodium chloride", 1.544},
      {"amber", 1.55},          {"pet", 1.5750},          {"diamond", 2.419}};
  return t;
}

// RGB fits of conductors' complex index of refraction (red, green, blue near 650, 550, 450 nm).
struct ConductorIor {
  D3 eta, k;
};
const std::map<std::string, ConductorIor>& conductorTable() {
  static const std::map<std::string, ConductorIor> t = {
      {"Al", {{1.657, 0.880, 0.521}, {9.224, 6.270, 4.837}}},  {"Ag", {{0.155, 0.117, 0.138}, {4.828, 3.122, 2.147}}},
      {"Au", {{0.143, 0.374, 1.442}, {3.983, 2.385, 1.603}}},  {"Cu", {{0.200, 0.924, 1.102}, {3.912, 2.452, 2.142}}},
      {"Cr", {{4.360, 2.910, 1.650}, {5.200, 4.230, 3.750}}},  {"Fe", {{2.870, 2.950, 2.650}, {3.120, 2.930, 2.810}}},
      {"Ti", {{2.740, 2.540, 2.270}, {3.820, 3.430, 3.040}}},  {"W", {{4.370, 3.300, 2.990}, {3.500, 2.730, 2.520}}}};
  return t;
}

struct Source {
  std::string name;
  fs::path dir;
  std::string text;
  std::vector<size_t> lineStarts;
  int line(ptrdiff_t offset) const {
    if (offset < 0) return 0;
    return int(std::upper_bound(lineStarts.begin(), lineStarts.end(), size_t(offset)) - lineStarts.begin());
  }
};

// The properties of one plugin element: its named children, which the plugin consumes one by one;
// whatever is left afterwards is reported (never silently ignored).
struct Props {
  pugi::xml_node node;
  std::map<std::string, pugi::xml_node> named;
  std::set<std::string> used;
  std::vector<pugi::xml_node> unnamed;  // nested objects without a name (bsdf, emitter, rfilter, ...)
  bool has(const std::string& n) const { return named.count(n) > 0; }
  pugi::xml_node get(const std::string& n) {
    auto it = named.find(n);
    if (it == named.end()) return {};
    used.insert(n);
    return it->second;
  }
};

class Importer {
 public:
  explicit Importer(const MitsubaImportOptions& o) : opt_(o) {}

  MitsubaImport run(const std::string& text, const fs::path& dir, const std::string& name) {
    pugi::xml_node scene = load(text, dir, name, true);
    out_.job.set_name(fs::path(name).stem().string());
    out_.job.mutable_scene()->set_name(out_.job.name());
    collectTopLevel(scene);
    for (auto n : topLevel_) topLevelObject(n);
    finish(scene);
    return std::move(out_);
  }

 private:
  const MitsubaImportOptions& opt_;
  MitsubaImport out_;
  std::vector<std::unique_ptr<pugi::xml_document>> docs_;
  std::map<const void*, std::unique_ptr<Source>> sources_;  // by document
  std::map<std::string, std::string> defaults_;
  std::vector<pugi::xml_node> topLevel_;
  std::map<std::string, pugi::xml_node> ids_;
  std::set<std::string> resolving_;               // ids being resolved (cycle detection)
  std::map<std::string, std::string> bsdfMaterial_;  // bsdf id -> material name
  std::set<std::string> wrapped_;                    // bsdf ids used inside a twosided
  std::set<std::string> usedTextures_;               // texture ids looked up
  std::vector<fs::path> includeStack_;
  std::set<std::string> materialNames_, shapeNames_, lightNames_;
  int sensors_ = 0, integrators_ = 0, anonymous_ = 0, includes_ = 0;
  uintmax_t includedBytes_ = 0;

  // ------------------------------------------------------------------ locations and errors
  const Source& sourceOf(pugi::xml_node n) const {
    auto it = n ? sources_.find(n.root().internal_object()) : sources_.end();
    if (it != sources_.end()) return *it->second;
    static const Source unknown{"<scene>", {}, {}, {0}};  // a null node: no line to name (a bug if ever seen)
    return unknown;
  }
  std::string where(pugi::xml_node n) const {
    const Source& s = sourceOf(n);
    std::string e = "<" + std::string(n.name());
    for (const char* a : {"type", "name", "id"})
      if (n.attribute(a)) e += std::string(" ") + a + "=\"" + n.attribute(a).value() + "\"";
    e += ">";
    return s.name + ":" + std::to_string(s.line(n.offset_debug())) + ": " + e;
  }
  [[noreturn]] void fail(pugi::xml_node n, const std::string& why) const { throw InputError(where(n) + ": " + why); }
  void warn(pugi::xml_node n, const std::string& why) { out_.warnings.push_back(where(n) + ": " + why); }

  // ------------------------------------------------------------------ loading and substitution
  pugi::xml_node load(const std::string& text, const fs::path& dir, const std::string& name, bool isRoot) {
    auto doc = std::make_unique<pugi::xml_document>();
    auto src = std::make_unique<Source>();
    src->name = name;
    src->dir = dir;
    src->text = text;
    src->lineStarts.push_back(0);
    for (size_t i = 0; i < text.size(); ++i)
      if (text[i] == '\n') src->lineStarts.push_back(i + 1);
    pugi::xml_parse_result r = doc->load_buffer(src->text.data(), src->text.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!r) throw InputError(name + ":" + std::to_string(src->line(r.offset)) + ": malformed XML: " + r.description());
    pugi::xml_node scene = doc->document_element();
    sources_[doc->internal_object()] = std::move(src);
    docs_.push_back(std::move(doc));
    if (std::string(scene.name()) != "scene") fail(scene, "the root element must be <scene version=\"3.0.0\">");
    pugi::xml_attribute version = scene.attribute("version");
    if (!version) fail(scene, "missing the version attribute (Mitsuba 3 scenes say version=\"3.0.0\")");
    std::string v = version.value();
    int major = std::atoi(v.c_str());
    if (v.empty() || !std::isdigit(static_cast<unsigned char>(v[0])) || (major != 2 && major != 3) ||
        v.find_first_not_of("0123456789.") != std::string::npos || std::count(v.begin(), v.end(), '.') != 2 || v.back() == '.' ||
        v.find("..") != std::string::npos)
      fail(scene, "version \"" + v + "\" is not a Mitsuba 2 or 3 scene version (e.g. 3.0.0); Mitsuba 0.x scenes need upgrading");
    // <default> values first (options override them), then $name substitution everywhere.
    for (auto d : scene.children("default")) {
      std::string dn = d.attribute("name").value();
      if (dn.empty() || !d.attribute("value")) fail(d, "<default> needs name and value attributes");
      if (isRoot || !defaults_.count(dn)) defaults_[dn] = d.attribute("value").value();
    }
    if (isRoot)
      for (const auto& [k, val] : opt_.defaults) defaults_[k] = val;
    substitute(scene);
    return scene;
  }

  void substitute(pugi::xml_node n) {
    for (pugi::xml_attribute a : n.attributes()) {
      std::string v = a.value();
      if (v.find('$') == std::string::npos) continue;
      std::string r;
      for (size_t i = 0; i < v.size();) {
        if (v[i] == '\\' && i + 1 < v.size() && v[i + 1] == '$') {  // \$ is a literal $
          r += '$';
          i += 2;
          continue;
        }
        if (v[i] != '$') {
          r += v[i++];
          continue;
        }
        // Like Mitsuba: the longest defined name that follows the '$' ($name_diffuse with only
        // 'name' defined is $name followed by "_diffuse").
        const std::string* best = nullptr;
        for (const auto& [k, val] : defaults_)
          if (v.compare(i + 1, k.size(), k) == 0 && (!best || k.size() > best->size())) best = &k;
        if (!best) {
          size_t j = i + 1;
          while (j < v.size() && (std::isalnum(static_cast<unsigned char>(v[j])) || v[j] == '_')) ++j;
          std::string key = v.substr(i + 1, j - i - 1);
          if (key.empty()) fail(n, "'$' in attribute " + std::string(a.name()) + " is not followed by a parameter name");
          fail(n, "attribute " + std::string(a.name()) + " uses $" + key + ", which no <default> defines");
        }
        r += defaults_.at(*best);
        i += 1 + best->size();
      }
      a.set_value(r.c_str());
    }
    for (auto c : n.children())
      if (c.type() == pugi::node_element) substitute(c);
  }

  void collectTopLevel(pugi::xml_node scene) {
    for (auto c : scene.children()) {
      if (c.type() != pugi::node_element) continue;
      std::string tag = c.name();
      if (tag == "default") continue;
      if (tag == "include") {
        include(c);
        continue;
      }
      registerIds(c);
      topLevel_.push_back(c);
    }
  }

  // Every object with an id can be referenced, nested ones too (a bsdf defined inside a shape).
  void registerIds(pugi::xml_node c) {
    if (std::string(c.name()) == "ref") return;  // its id names another object
    if (c.attribute("id")) {
      std::string id = c.attribute("id").value();
      if (id.empty()) fail(c, "empty id");
      if (id.size() > inputLimits().maxNameBytes) fail(c, "id longer than " + std::to_string(inputLimits().maxNameBytes) + " bytes");
      if (!ids_.emplace(id, c).second) fail(c, "id \"" + id + "\" is used twice (first at " + where(ids_[id]) + ")");
    }
    for (auto k : c.children())
      if (k.type() == pugi::node_element) registerIds(k);
  }

  void include(pugi::xml_node n) {
    std::string file = n.attribute("filename").value();
    if (file.empty()) fail(n, "<include> needs a filename");
    fs::path p = resolvePath(n, file);
    if (opt_.missingFiles && !fs::exists(p)) {
      recordMissing(p);
      return;
    }
    for (const auto& q : includeStack_)
      if (fs::weakly_canonical(q) == fs::weakly_canonical(p)) fail(n, "includes '" + file + "' recursively");
    if (includeStack_.size() > 16) fail(n, "includes nested more than 16 deep");
    if (++includes_ > 256) fail(n, "more than 256 included files");
    std::string text;
    try {
      text = readSceneFile(p, "included file");
    } catch (const InputError& e) {
      rethrowWithMessage(e, where(n) + ": " + e.what());
    }
    includedBytes_ += text.size();
    if (includedBytes_ > kMaxSceneFileBytes) fail(n, "included files exceed " + humanBytes(kMaxSceneFileBytes) + " together");
    includeStack_.push_back(p);
    pugi::xml_node scene = load(text, p.parent_path(), p.string(), false);
    collectTopLevel(scene);
    includeStack_.pop_back();
  }

  void recordMissing(const fs::path& p) const {
    const fs::path rootDir = sources_.begin() != sources_.end() ? rootSource().dir : fs::path(".");
    fs::path rel = fs::absolute(p).lexically_normal().lexically_relative(fs::absolute(rootDir).lexically_normal());
    const std::string name = rel.empty() ? p.generic_string() : rel.generic_string();
    auto& list = *opt_.missingFiles;
    if (std::find(list.begin(), list.end(), name) == list.end()) list.push_back(name);
  }
  fs::path resolvePath(pugi::xml_node n, const std::string& file) const {
    fs::path p(file);
    if (p.is_absolute()) return p;
    return sourceOf(n).dir / p;
  }
  // An asset path as the job stores it: relative to the root file's folder where possible.
  std::string assetPath(pugi::xml_node n, const std::string& file) const {
    fs::path p = resolvePath(n, file);
    if (!fs::exists(p)) {
      if (!opt_.missingFiles) fail(n, "file '" + file + "' not found (looked for '" + p.string() + "')");
      recordMissing(p);
    }
    const fs::path rootDir = sources_.begin() != sources_.end() ? rootSource().dir : fs::path(".");
    if (fs::path(file).is_absolute()) return p.string();
    fs::path rel = fs::absolute(p).lexically_normal().lexically_relative(fs::absolute(rootDir).lexically_normal());
    return rel.empty() ? p.string() : rel.string();
  }
  const Source& rootSource() const { return sourceOf(docs_.front()->document_element()); }

  // ------------------------------------------------------------------ properties
  Props props(pugi::xml_node n) {
    Props p;
    p.node = n;
    static const std::set<std::string> objects = {"bsdf", "emitter", "shape", "sensor", "film", "sampler", "rfilter", "integrator"};
    for (auto c : n.children()) {
      if (c.type() != pugi::node_element) continue;
      std::string nm = c.attribute("name").value(), tag = c.name();
      // Nested objects (and references to them) count by their kind, named or not
      // (<ref name="bsdf" id="m"/>); textures stay properties of their name.
      bool object = objects.count(tag) > 0;
      if (tag == "ref") {
        auto it = ids_.find(c.attribute("id").value());
        object = it != ids_.end() && objects.count(it->second.name()) > 0;
      }
      if (nm.empty() || object) {
        p.unnamed.push_back(c);
        continue;
      }
      if (p.named.count(nm)) fail(c, "property '" + nm + "' is given twice");
      p.named[nm] = c;
    }
    return p;
  }
  // An emitter's share of light samples changes the noise, not the image, unless it is 0 on a
  // delta light, which no other strategy reaches: that light is then missing from Mitsuba's image.
  void samplingWeight(Props& p, bool deltaLight) {
    if (!p.named.count("sampling_weight")) return;
    const double w = floatProp(p, "sampling_weight", 1.0);
    if (!(w >= 0)) fail(p.named["sampling_weight"], "sampling_weight must be >= 0");
    if (w == 0 && deltaLight) fail(p.named["sampling_weight"], "sampling_weight 0 removes this light from Mitsuba's image; leave the light out instead");
    warn(p.named["sampling_weight"], "sampling_weight: ignored (invr chooses lights by power; the noise differs, not the image)");
  }
  // Properties left over after a plugin took what it supports: harmless ones warn, others fail.
  void finishProps(Props& p, const std::set<std::string>& harmless = {}) {
    for (const auto& [nm, c] : p.named) {
      if (p.used.count(nm)) continue;
      if (harmless.count(nm)) warn(c, "ignored (it does not change what invr renders)");
      else fail(c, "property '" + nm + "' is not supported by invr's import of " + std::string(p.node.name()) + " '" +
                       p.node.attribute("type").value() + "' (docs/mitsuba-import.md lists what is)");
    }
  }

  double number(pugi::xml_node n, const std::string& text, const std::string& what) const {
    const char* s = text.c_str();
    while (std::isspace(static_cast<unsigned char>(*s))) ++s;
    char* end = nullptr;
    double v = std::strtod(s, &end);
    if (end == s) fail(n, "malformed number '" + text + "' in " + what);
    while (std::isspace(static_cast<unsigned char>(*end))) ++end;
    if (*end != '\0') fail(n, "malformed number '" + text + "' in " + what);
    if (!std::isfinite(v)) fail(n, what + " is not a finite number ('" + text + "')");
    return v;
  }
  std::vector<double> numbers(pugi::xml_node n, const std::string& text, const std::string& what) const {
    std::string t = text;
    std::replace(t.begin(), t.end(), ',', ' ');
    std::istringstream in(t);
    std::vector<double> r;
    std::string tok;
    while (in >> tok) r.push_back(number(n, tok, what));
    return r;
  }
  std::string attr(pugi::xml_node n, const char* a) const {
    if (!n.attribute(a)) fail(n, std::string("missing attribute '") + a + "'");
    return n.attribute(a).value();
  }
  void expectTag(pugi::xml_node n, std::initializer_list<const char*> tags) const {
    for (const char* t : tags)
      if (std::string(n.name()) == t) return;
    std::string list;
    for (const char* t : tags) list += std::string(list.empty() ? "" : " or ") + "<" + t + ">";
    fail(n, "expected " + list);
  }

  double floatProp(Props& p, const std::string& nm, double dflt) {
    pugi::xml_node n = p.get(nm);
    if (!n) return dflt;
    expectTag(n, {"float", "integer"});
    return number(n, attr(n, "value"), "'" + nm + "'");
  }
  int intProp(Props& p, const std::string& nm, int dflt) {
    pugi::xml_node n = p.get(nm);
    if (!n) return dflt;
    expectTag(n, {"integer"});
    double v = number(n, attr(n, "value"), "'" + nm + "'");
    if (v != std::floor(v) || std::abs(v) > 1e9) fail(n, "'" + nm + "' must be an integer");
    return int(v);
  }
  bool boolProp(Props& p, const std::string& nm, bool dflt) {
    pugi::xml_node n = p.get(nm);
    if (!n) return dflt;
    expectTag(n, {"boolean"});
    std::string v = attr(n, "value");
    if (v == "true") return true;
    if (v == "false") return false;
    fail(n, "'" + nm + "' must be true or false (got '" + v + "')");
  }
  std::string stringProp(Props& p, const std::string& nm, const std::string& dflt) {
    pugi::xml_node n = p.get(nm);
    if (!n) return dflt;
    expectTag(n, {"string"});
    return attr(n, "value");
  }
  D3 pointOf(pugi::xml_node n) const {
    if (n.attribute("value")) {
      auto v = numbers(n, n.attribute("value").value(), "'" + std::string(n.attribute("name").value()) + "'");
      if (v.size() == 1) return {v[0], v[0], v[0]};
      if (v.size() != 3) fail(n, "needs 3 numbers");
      return {v[0], v[1], v[2]};
    }
    D3 r{0, 0, 0};
    const char* axes[3] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i)
      if (n.attribute(axes[i])) r[size_t(i)] = number(n, n.attribute(axes[i]).value(), axes[i]);
    return r;
  }
  D3 pointProp(Props& p, const std::string& nm, D3 dflt) {
    pugi::xml_node n = p.get(nm);
    if (!n) return dflt;
    expectTag(n, {"point", "vector"});
    return pointOf(n);
  }

  // A constant colour: rgb, spectrum with one value, float.
  D3 colourOf(pugi::xml_node n, const std::string& what) {
    std::string tag = n.name();
    if (tag == "rgb") {
      auto v = numbers(n, attr(n, "value"), what);
      if (v.size() == 1) return {v[0], v[0], v[0]};
      if (v.size() != 3) fail(n, what + " needs 3 numbers (r g b)");
      return {v[0], v[1], v[2]};
    }
    if (tag == "spectrum") {
      if (n.attribute("filename")) fail(n, "spectra from files are not supported: invr renders RGB (linear sRGB primaries), not spectra");
      std::string v = attr(n, "value");
      if (v.find(':') != std::string::npos)
        fail(n, "sampled spectra (wavelength:value pairs) are not supported: invr renders RGB, give an <rgb> instead");
      double x = number(n, v, what);
      return {x, x, x};
    }
    if (tag == "float" || tag == "integer") {
      double x = number(n, attr(n, "value"), what);
      return {x, x, x};
    }
    fail(n, what + ": expected <rgb>, <spectrum> or <float>");
  }

  // Emission: a constant colour. Mitsuba's RGB variants turn a constant <spectrum> on an emitter
  // into the sRGB of that flat spectrum, about (1.20, 0.95, 0.91) times its value; invr reads it
  // as grey, and says so.
  D3 emission(pugi::xml_node n, const std::string& what) {
    if (std::string(n.name()) == "spectrum")
      warn(n, "a constant spectrum on an emitter is read as grey; Mitsuba's RGB variants tint it (about 1.20, 0.95, 0.91 times the value): use <rgb> to be exact");
    return colourOf(n, what);
  }

  // A reflectance-like property: a constant or a bitmap texture (inline or by reference).
  void textureProp(Props& p, const std::string& nm, v1::Texture* out, D3 dflt, bool colour) {
    pugi::xml_node n = p.get(nm);
    if (!n) {
      *out->mutable_constant() = toRgb(dflt);
      return;
    }
    std::string tag = n.name();
    if (tag == "ref") {
      n = resolveRef(n, "texture");
      usedTextures_.insert(n.attribute("id").value());
    }
    if (std::string(n.name()) == "texture") {
      bitmap(n, out, colour);
      return;
    }
    *out->mutable_constant() = toRgb(colourOf(n, "'" + nm + "'"));
  }

  void bitmap(pugi::xml_node n, v1::Texture* out, bool colour) {
    std::string type = n.attribute("type").value();
    if (type != "bitmap") fail(n, "texture type '" + type + "' is not supported (only bitmap)");
    Props p = props(n);
    std::string file = stringProp(p, "filename", "");
    if (file.empty()) fail(n, "a bitmap needs a filename");
    out->mutable_image()->set_path(assetPath(n, file));
    // Mitsuba decodes every 8-bit image from sRGB unless raw=true, scalar (roughness) ones too.
    (void)colour;
    out->set_srgb(!boolProp(p, "raw", false));
    std::string filter = stringProp(p, "filter_type", "bilinear");
    if (filter != "bilinear") fail(p.named["filter_type"], "filter_type '" + filter + "': invr looks textures up bilinearly");
    std::string wrap = stringProp(p, "wrap_mode", "repeat");
    if (wrap != "repeat") fail(p.named["wrap_mode"], "wrap_mode '" + wrap + "': invr repeats textures");
    finishProps(p, {"format", "accel"});  // storage and the lookup path, not the values
    for (auto c : p.unnamed) fail(c, "unexpected element inside a bitmap");
  }

  pugi::xml_node resolveRef(pugi::xml_node ref, const std::string& expectedTag) {
    std::string id = attr(ref, "id");
    auto it = ids_.find(id);
    if (it == ids_.end()) fail(ref, "no object with id \"" + id + "\"");
    if (!expectedTag.empty() && std::string(it->second.name()) != expectedTag)
      fail(ref, "\"" + id + "\" is a <" + it->second.name() + ">, not a <" + expectedTag + ">");
    return it->second;
  }

  // ------------------------------------------------------------------ transforms
  Affine3d transformOf(pugi::xml_node t) {
    Affine3d m;
    for (auto c : t.children()) {
      if (c.type() != pugi::node_element) continue;
      std::string tag = c.name();
      Affine3d op;
      if (tag == "translate") {
        D3 v = pointOf(c);
        if (c.attribute("value") && numbers(c, c.attribute("value").value(), "translate").size() != 3) fail(c, "translate needs 3 numbers");
        op.m[0][3] = v[0];
        op.m[1][3] = v[1];
        op.m[2][3] = v[2];
      } else if (tag == "scale") {
        D3 s{1, 1, 1};
        if (c.attribute("value")) {
          s = pointOf(c);
        } else {
          const char* axes[3] = {"x", "y", "z"};
          for (int i = 0; i < 3; ++i)
            if (c.attribute(axes[i])) s[size_t(i)] = number(c, c.attribute(axes[i]).value(), axes[i]);
        }
        if (s[0] == 0 || s[1] == 0 || s[2] == 0) fail(c, "a scale of zero is not invertible");
        op.m[0][0] = s[0];
        op.m[1][1] = s[1];
        op.m[2][2] = s[2];
      } else if (tag == "rotate") {
        D3 axis = pointOf(c);
        double angle = number(c, attr(c, "angle"), "angle");
        double l = lenD(axis);
        if (!(l > 0)) fail(c, "rotation axis is zero");
        axis = scaleD(axis, 1.0 / l);
        double r = angle * kPiD / 180.0, cs = std::cos(r), sn = std::sin(r), ic = 1 - cs;
        double x = axis[0], y = axis[1], z = axis[2];
        double R[3][3] = {{cs + x * x * ic, x * y * ic - z * sn, x * z * ic + y * sn},
                          {y * x * ic + z * sn, cs + y * y * ic, y * z * ic - x * sn},
                          {z * x * ic - y * sn, z * y * ic + x * sn, cs + z * z * ic}};
        // Quarter turns come out exact (cos 90 degrees is 6e-17 in doubles): snap what is within
        // rounding of 0 or 1, so axis-aligned scenes stay axis-aligned.
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) {
            double x = R[i][j];
            if (std::abs(x) < 1e-15) x = 0;
            if (std::abs(std::abs(x) - 1) < 1e-15) x = x > 0 ? 1 : -1;
            op.m[i][j] = x;
          }
      } else if (tag == "matrix") {
        auto v = numbers(c, attr(c, "value"), "matrix");
        if (v.size() == 16) {
          if (v[12] != 0 || v[13] != 0 || v[14] != 0 || v[15] != 1) fail(c, "projective matrices are not supported (the last row must be 0 0 0 1)");
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 4; ++j) op.m[i][j] = v[size_t(i * 4 + j)];
        } else if (v.size() == 9) {
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) op.m[i][j] = v[size_t(i * 3 + j)];
        } else {
          fail(c, "a matrix needs 16 numbers (or 9), got " + std::to_string(v.size()));
        }
      } else if (tag == "lookat") {
        auto vec3 = [&](const char* a, D3 dflt) {
          if (!c.attribute(a)) return dflt;
          auto v = numbers(c, c.attribute(a).value(), a);
          if (v.size() != 3) fail(c, std::string(a) + " needs 3 numbers");
          return D3{v[0], v[1], v[2]};
        };
        if (!c.attribute("origin") || !c.attribute("target")) fail(c, "lookat needs origin and target");
        D3 o = vec3("origin", {0, 0, 0}), tg = vec3("target", {0, 0, 1}), up = vec3("up", {0, 0, 0});
        D3 dir = sub(tg, o);
        if (!(lenD(dir) > 0)) fail(c, "lookat: target equals origin");
        dir = scaleD(dir, 1.0 / lenD(dir));
        if (!(lenD(up) > 0)) {
          // No up given: Mitsuba's choice, the first tangent of its orthonormal frame around the
          // view direction (Duff et al. 2017).
          const double sign = std::copysign(1.0, dir[2]), a = -1.0 / (sign + dir[2]), b = dir[0] * dir[1] * a;
          up = {1 + sign * dir[0] * dir[0] * a, sign * b, -sign * dir[0]};
        }
        D3 left = crossD(up, dir);
        if (!(lenD(left) > 1e-9)) fail(c, "lookat: up is parallel to the view direction");
        left = scaleD(left, 1.0 / lenD(left));
        D3 newUp = crossD(dir, left);
        // Columns: local x -> left, y -> up, z -> view direction; origin at the eye.
        for (int i = 0; i < 3; ++i) {
          op.m[i][0] = left[size_t(i)];
          op.m[i][1] = newUp[size_t(i)];
          op.m[i][2] = dir[size_t(i)];
          op.m[i][3] = o[size_t(i)];
        }
      } else {
        fail(c, "unknown transform operation (translate, rotate, scale, matrix or lookat)");
      }
      m = op * m;  // each operation applies after the ones before it
    }
    return m;
  }
  Affine3d toWorld(Props& p) {
    pugi::xml_node t = p.get("to_world");
    if (!t) return {};
    expectTag(t, {"transform"});
    return transformOf(t);
  }
  static void setMatrix(v1::Transform* t, const Affine3d& m) {
    t->clear_matrix();
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 4; ++j) t->add_matrix(m.m[i][j]);
  }

  // ------------------------------------------------------------------ names
  std::string uniqueName(std::set<std::string>& used, const std::string& want, const std::string& prefix) {
    // Generated names never take a name an object's id will claim.
    std::string base = want.empty() ? prefix + "_" + std::to_string(++anonymous_) : want;
    while (want.empty() && ids_.count(base)) base = prefix + "_" + std::to_string(++anonymous_);
    std::string n = base;
    for (int k = 2; used.count(n) || (n != want && ids_.count(n)); ++k) n = base + "_" + std::to_string(k);
    used.insert(n);
    return n;
  }

  // ------------------------------------------------------------------ top level
  void topLevelObject(pugi::xml_node n) {
    std::string tag = n.name();
    if (tag == "bsdf") {
      // Made a material where a shape uses it (finish() checks and reports the unused ones).
      if (!n.attribute("id")) fail(n, "a top-level <bsdf> needs an id (shapes refer to it with <ref id=...>)");
    } else if (tag == "texture") {
      if (!n.attribute("id")) fail(n, "a top-level <texture> needs an id");
      // Checked where it is used (as a reflectance or a roughness), and in finish() if unused.
      if (std::string(n.attribute("type").value()) != "bitmap") fail(n, "texture type '" + std::string(n.attribute("type").value()) + "' is not supported (only bitmap)");
    } else if (tag == "shape") {
      shape(n);
    } else if (tag == "emitter") {
      emitter(n);
    } else if (tag == "sensor") {
      sensor(n);
    } else if (tag == "integrator") {
      integrator(n);
    } else if (tag == "spectrum" || tag == "rgb" || tag == "float" || tag == "integer" || tag == "boolean" || tag == "string" ||
               tag == "point" || tag == "vector" || tag == "transform") {
      fail(n, "a property outside any plugin");
    } else {
      fail(n, "unsupported element <" + tag + "> (invr imports shapes, bsdfs, textures, emitters, sensors and integrators; " +
                  "media, volumes and phase functions are not supported)");
    }
  }

  // Returns the material name for a <bsdf> element (adding the material once per element).
  std::string material(pugi::xml_node n) {
    std::string id = n.attribute("id").value();
    if (!id.empty()) {
      auto it = bsdfMaterial_.find(id);
      if (it != bsdfMaterial_.end()) return it->second;
      if (resolving_.count(id)) fail(n, "refers to itself (a cycle of references through \"" + id + "\")");
    }
    resolving_.insert(id);
    v1::Material m;
    m.set_one_sided(true);
    bsdfInto(n, &m);
    resolving_.erase(id);
    m.set_name(uniqueName(materialNames_, id, "bsdf"));
    if (!id.empty()) bsdfMaterial_[id] = m.name();
    *out_.job.mutable_scene()->add_materials() = m;
    return m.name();
  }

  double iorProp(Props& p, const std::string& nm, double dflt) {
    pugi::xml_node n = p.get(nm);
    if (!n) return dflt;
    if (std::string(n.name()) == "string") {
      std::string v = attr(n, "value");
      auto it = iorTable().find(v);
      if (it == iorTable().end()) fail(n, "unknown material name '" + v + "' for an index of refraction");
      return it->second;
    }
    expectTag(n, {"float"});
    double v = number(n, attr(n, "value"), "'" + nm + "'");
    if (!(v > 0)) fail(n, "an index of refraction must be positive");
    return v;
  }

  void checkUnitSpecular(Props& p, const std::string& nm) {
    pugi::xml_node n = p.get(nm);
    if (!n) return;
    D3 c = colourOf(n, "'" + nm + "'");
    if (c[0] != 1 || c[1] != 1 || c[2] != 1) fail(n, "'" + nm + "' other than 1 is not supported");
  }

  double alphaProp(Props& p, v1::Texture* out, double dflt) {
    if (p.has("alpha_u") || p.has("alpha_v")) {
      double au = floatProp(p, "alpha_u", dflt), av = floatProp(p, "alpha_v", dflt);
      if (au != av) fail(p.named["alpha_u"] ? p.named["alpha_u"] : p.node, "anisotropic roughness (alpha_u != alpha_v) is not supported");
      out->set_value(au);
      return au;
    }
    pugi::xml_node a = p.named.count("alpha") ? p.named["alpha"] : pugi::xml_node();
    if (a && (std::string(a.name()) == "texture" || std::string(a.name()) == "ref")) {
      textureProp(p, "alpha", out, {dflt, dflt, dflt}, false);
      return dflt;
    }
    double v = floatProp(p, "alpha", dflt);
    if (!(v > 0 && v <= 1)) fail(a ? a : p.node, "alpha must be in (0, 1] (got " + std::to_string(v) + ")");
    out->set_value(v);
    return v;
  }

  void distribution(Props& p) {
    std::string d = stringProp(p, "distribution", "beckmann");
    if (d == "ggx") return;
    if (d == "beckmann")
      warn(p.named.count("distribution") ? p.named["distribution"] : p.node,
           "Beckmann microfacets are rendered as GGX with the same alpha (invr has GGX only; highlights get longer tails)");
    else
      fail(p.named["distribution"], "unknown microfacet distribution '" + d + "'");
  }

  void bsdfInto(pugi::xml_node n, v1::Material* m) {
    std::string type = n.attribute("type").value();
    Props p = props(n);
    if (type == "twosided") {
      std::vector<pugi::xml_node> inner;
      for (auto c : p.unnamed) {
        if (std::string(c.name()) == "bsdf") inner.push_back(c);
        else if (std::string(c.name()) == "ref") inner.push_back(resolveRef(c, "bsdf"));
        else fail(c, "unexpected element inside twosided");
      }
      if (inner.size() != 1) fail(n, "twosided with " + std::to_string(inner.size()) + " bsdfs: invr supports exactly one (the same on both sides)");
      finishProps(p, {"allow_transmission"});  // only a check in Mitsuba, never a change to what a loading scene renders
      std::string id = inner[0].attribute("id").value();
      if (!id.empty()) {
        if (resolving_.count(id)) fail(inner[0], "a cycle of references through \"" + id + "\"");
        resolving_.insert(id);
      }
      bsdfInto(inner[0], m);
      if (!id.empty()) {
        resolving_.erase(id);
        // Mitsuba names a referenced bsdf's parameters by its own id: they are this material's.
        m->add_aliases(id);
        wrapped_.insert(id);
      }
      m->set_one_sided(false);
      return;
    }
    if (type == "diffuse") {
      textureProp(p, "reflectance", m->mutable_diffuse()->mutable_albedo(), {0.5, 0.5, 0.5}, true);
    } else if (type == "conductor") {
      ConductorIor c = conductorIor(p);
      checkUnitSpecular(p, "specular_reflectance");
      auto* mirror = m->mutable_mirror();
      // A smooth conductor is a mirror; invr's mirror has no angle-dependent Fresnel term, so it
      // takes the conductor's reflectance at normal incidence.
      D3 r;
      for (size_t i = 0; i < 3; ++i) {
        double e = c.eta[i], k = c.k[i];
        r[i] = ((e - 1) * (e - 1) + k * k) / ((e + 1) * (e + 1) + k * k);
      }
      *mirror->mutable_reflectance() = toRgb(r);
      if (!(r[0] == 1 && r[1] == 1 && r[2] == 1))
        warn(n, "a smooth conductor becomes a mirror with its normal-incidence reflectance (invr's mirror has no angle-dependent Fresnel)");
    } else if (type == "roughconductor") {
      auto* rc = m->mutable_rough_conductor();
      distribution(p);
      alphaProp(p, rc->mutable_roughness(), 0.1);
      ConductorIor c = conductorIor(p);
      if (c.eta == D3{0, 0, 0} && c.k == D3{1, 1, 1})
        fail(n, "material 'none' (a perfect reflector) has no complex IOR for a rough conductor; give a metal (e.g. Al) or eta and k");
      *rc->mutable_eta() = toRgb(c.eta);
      *rc->mutable_k() = toRgb(c.k);
      checkUnitSpecular(p, "specular_reflectance");
      boolProp(p, "sample_visible", true);  // a sampling choice: the image does not change
    } else if (type == "plastic" || type == "roughplastic") {
      auto* rp = m->mutable_rough_plastic();
      textureProp(p, "diffuse_reflectance", rp->mutable_albedo(), {0.5, 0.5, 0.5}, true);
      double ior = iorProp(p, "int_ior", 1.49) / iorProp(p, "ext_ior", 1.000277);
      if (!(ior > 1 && ior < 10)) fail(n, "int_ior / ext_ior must be in (1, 10) for a plastic (got " + std::to_string(ior) + ")");
      rp->set_ior(ior);
      checkUnitSpecular(p, "specular_reflectance");
      if (boolProp(p, "nonlinear", false)) fail(p.named["nonlinear"], "nonlinear=true is not supported");
      if (type == "roughplastic") {
        distribution(p);
        alphaProp(p, rp->mutable_roughness(), 0.1);
        boolProp(p, "sample_visible", true);
      } else {
        rp->mutable_roughness()->set_value(kSmoothPlasticAlpha);
        warn(n, "a smooth plastic becomes a rough plastic of GGX alpha " + std::to_string(kSmoothPlasticAlpha) +
                    " (invr has no delta-specular coating)");
      }
    } else if (type == "dielectric") {
      double ior = iorProp(p, "int_ior", 1.5046) / iorProp(p, "ext_ior", 1.000277);
      if (!(ior > 0 && ior < 10) || ior == 1) fail(n, "int_ior / ext_ior must be in (0, 10) and not 1");
      m->mutable_dielectric()->set_ior(ior);
      checkUnitSpecular(p, "specular_reflectance");
      checkUnitSpecular(p, "specular_transmittance");
    } else {
      fail(n, "bsdf type '" + type + "' is not supported (diffuse, conductor, roughconductor, plastic, roughplastic, dielectric, twosided)");
    }
    finishProps(p);
    for (auto c : p.unnamed) fail(c, "unexpected element inside a " + type + " bsdf");
  }
  static constexpr double kSmoothPlasticAlpha = 0.01;

  ConductorIor conductorIor(Props& p) {
    if (p.has("material") && (p.has("eta") || p.has("k"))) fail(p.named["material"], "give either material or eta and k");
    if (p.has("eta") || p.has("k")) {
      if (!p.has("eta") || !p.has("k")) fail(p.node, "eta and k must be given together");
      return {colourOf(p.get("eta"), "'eta'"), colourOf(p.get("k"), "'k'")};
    }
    std::string name = stringProp(p, "material", "none");
    if (name == "none") return {{0, 0, 0}, {1, 1, 1}};
    auto it = conductorTable().find(name);
    if (it == conductorTable().end()) {
      std::string list;
      for (const auto& [k, v] : conductorTable()) list += " " + k;
      fail(p.named["material"], "conductor '" + name + "' is not in invr's table (none" + list + "); give eta and k as <rgb>");
    }
    return it->second;
  }

  // Material of a shape: a nested bsdf, a reference, or Mitsuba's default (diffuse 0.5).
  std::string shapeMaterial(Props& p, pugi::xml_node shapeNode, bool emits) {
    std::vector<pugi::xml_node> bsdfs;
    for (auto c : p.unnamed) {
      std::string tag = c.name();
      if (tag == "bsdf") bsdfs.push_back(c);
      else if (tag == "ref") bsdfs.push_back(resolveRef(c, "bsdf"));
    }
    if (bsdfs.size() > 1) fail(shapeNode, "a shape takes one bsdf");
    if (bsdfs.empty()) {
      // Mitsuba's default: diffuse 0.5, black on emitters.
      std::string& name = emits ? defaultEmitterMaterial_ : defaultMaterial_;
      if (!name.empty()) return name;
      v1::Material m;
      m.set_name(uniqueName(materialNames_, emits ? "default_emitter_black" : "default_diffuse", ""));
      m.set_one_sided(true);
      m.mutable_diffuse()->mutable_albedo()->set_value(emits ? 0.0 : 0.5);
      *out_.job.mutable_scene()->add_materials() = m;
      name = m.name();
      return name;
    }
    return material(bsdfs[0]);
  }
  std::string defaultMaterial_, defaultEmitterMaterial_;
  bool hasImageTexture(const std::string& material) const {
    for (const auto& m : out_.job.scene().materials()) {
      if (m.name() != material) continue;
      for (const v1::Texture* t : {&m.diffuse().albedo(), &m.rough_plastic().albedo(), &m.rough_plastic().roughness(),
                                   &m.rough_conductor().roughness()})
        if (t->has_image()) return true;
    }
    return false;
  }

  void shape(pugi::xml_node n) {
    std::string type = n.attribute("type").value();
    Props p = props(n);
    v1::Shape s;
    Affine3d xf = toWorld(p);
    if (type == "obj" || type == "ply") {
      std::string file = stringProp(p, "filename", "");
      if (file.empty()) fail(n, "a " + type + " shape needs a filename");
      std::string ext = fs::path(file).extension().string();
      std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
      if (ext != "." + type) fail(p.named["filename"], "shape type " + type + " but the file is '" + file + "'");
      s.mutable_mesh()->set_path(assetPath(n, file));
      s.set_face_normals(boolProp(p, "face_normals", false));
      s.set_smooth_normals(!s.face_normals());
      // Mitsuba puts uv (0, 0) at the image's top-left, invr at its bottom-left: invr flips
      // exactly when Mitsuba does not (OBJ flips by default, PLY does not).
      s.set_flip_tex_coords(!boolProp(p, "flip_tex_coords", type == "obj"));
    } else if (type == "rectangle") {
      s.mutable_quad();
      s.set_flip_tex_coords(true);  // the same uv layout, looked up from the other end
    } else if (type == "cube") {
      s.mutable_box();
    } else if (type == "disk") {
      s.mutable_disk()->set_segments(opt_.diskSegments);
    } else if (type == "sphere") {
      D3 c = pointProp(p, "center", {0, 0, 0});
      double r = floatProp(p, "radius", 1.0);
      if (!(r > 0)) fail(p.named["radius"], "radius must be positive");
      Affine3d local;
      for (int i = 0; i < 3; ++i) {
        local.m[i][i] = r;
        local.m[i][3] = c[size_t(i)];
      }
      xf = xf * local;
      s.mutable_sphere()->set_rings(opt_.sphereRings);
    } else {
      fail(n, "shape type '" + type + "' is not supported (obj, ply, rectangle, cube, sphere, disk)");
    }
    s.set_flip_normals(boolProp(p, "flip_normals", false));
    if (!xf.isIdentity()) setMatrix(s.mutable_transform(), xf);
    s.set_name(uniqueName(shapeNames_, n.attribute("id").value(), type));
    bool emits = false;
    for (auto c : p.unnamed) emits = emits || std::string(c.name()) == "emitter";
    s.set_material(shapeMaterial(p, n, emits));
    if ((type == "cube" || type == "sphere" || type == "disk") && hasImageTexture(s.material()))
      fail(n, "a bitmap texture on a Mitsuba " + type + ": invr's built-in " + type + " has another uv layout; use an obj or ply mesh");
    *out_.job.mutable_scene()->add_shapes() = s;
    for (auto c : p.unnamed) {
      std::string tag = c.name();
      if (tag == "bsdf" || tag == "ref") continue;
      if (tag != "emitter") fail(c, "unexpected element inside a shape");
      std::string et = c.attribute("type").value();
      if (et != "area") fail(c, "only area emitters can be attached to shapes (got '" + et + "')");
      Props ep = props(c);
      v1::Light l;
      l.set_name(uniqueName(lightNames_, c.attribute("id").value()[0] ? c.attribute("id").value() : s.name(), "light"));
      l.mutable_area()->set_shape(s.name());
      pugi::xml_node rad = ep.get("radiance");  // Mitsuba's default: 1
      if (rad && (std::string(rad.name()) == "texture" || std::string(rad.name()) == "ref")) fail(rad, "textured emission is not supported");
      *l.mutable_area()->mutable_radiance() = toRgb(rad ? emission(rad, "'radiance'") : D3{1, 1, 1});
      samplingWeight(ep, false);
      finishProps(ep);
      for (auto x : ep.unnamed) fail(x, "unexpected element inside an area emitter");
      *out_.job.mutable_scene()->add_lights() = l;
    }
    // How often projective integrators sample this shape's silhouette: gradients' noise only. A
    // planar or box face is flat whatever face_normals says.
    std::set<std::string> harmless{"silhouette_sampling_weight"};
    if (type == "rectangle" || type == "cube") harmless.insert("face_normals");
    finishProps(p, harmless);
  }

  void emitter(pugi::xml_node n) {
    std::string type = n.attribute("type").value();
    Props p = props(n);
    v1::Light l;
    l.set_name(uniqueName(lightNames_, n.attribute("id").value(), type));
    if (type == "point") {
      Affine3d xf = toWorld(p);
      D3 pos = pointProp(p, "position", {0, 0, 0});
      if (p.used.count("position") && p.used.count("to_world")) fail(n, "give either position or to_world");
      pos = applyPoint(xf, pos);
      *l.mutable_point()->mutable_position() = toVec(pos);
      pugi::xml_node in = p.get("intensity");
      *l.mutable_point()->mutable_intensity() = toRgb(in ? emission(in, "'intensity'") : D3{1, 1, 1});
    } else if (type == "spot") {
      Affine3d xf = toWorld(p);
      D3 pos = applyPoint(xf, {0, 0, 0}), dir = applyVector(xf, {0, 0, 1});
      if (!(lenD(dir) > 0)) fail(n, "to_world collapses the spot's direction");
      *l.mutable_spot()->mutable_position() = toVec(pos);
      *l.mutable_spot()->mutable_target() = toVec(add(pos, scaleD(dir, 1.0 / lenD(dir))));
      pugi::xml_node in = p.get("intensity");
      *l.mutable_spot()->mutable_intensity() = toRgb(in ? emission(in, "'intensity'") : D3{1, 1, 1});
      double cutoff = floatProp(p, "cutoff_angle", 20.0);
      double beam = floatProp(p, "beam_width", cutoff * 3.0 / 4.0);
      if (!(cutoff > 0 && cutoff < 180)) fail(p.named["cutoff_angle"], "cutoff_angle must be in (0, 180) degrees");
      if (!(beam > 0 && beam <= cutoff)) fail(p.named.count("beam_width") ? p.named["beam_width"] : n, "beam_width must be in (0, cutoff_angle]");
      l.mutable_spot()->set_cone_outer_degrees(cutoff);
      l.mutable_spot()->set_cone_inner_degrees(beam);
      if (beam < cutoff) warn(n, "the fall-off between beam_width and cutoff_angle follows invr's smooth step, not Mitsuba's linear ramp in angle");
      if (p.has("texture")) fail(p.named["texture"], "projected spot textures are not supported");
    } else if (type == "constant") {
      pugi::xml_node r = p.get("radiance");
      *l.mutable_constant_environment()->mutable_radiance() = toRgb(r ? emission(r, "'radiance'") : D3{1, 1, 1});
    } else if (type == "envmap") {
      std::string file = stringProp(p, "filename", "");
      if (file.empty()) fail(n, "an envmap needs a filename");
      l.mutable_environment()->mutable_radiance()->mutable_image()->set_path(assetPath(n, file));
      double scale = floatProp(p, "scale", 1.0);
      if (!(scale >= 0)) fail(p.named["scale"], "scale must be >= 0");
      if (scale != 1.0) l.set_scale(scale);
      // Mitsuba's map has u = 0.5 towards +z where invr's looks towards -z: half a turn about +y,
      // plus whatever turn about +y to_world adds (other rotations cannot be expressed).
      Affine3d xf = toWorld(p);
      const double eps = 1e-6;
      bool yRotation = std::abs(xf.m[1][1] - 1) < eps && std::abs(xf.m[0][1]) < eps && std::abs(xf.m[2][1]) < eps &&
                       std::abs(xf.m[1][0]) < eps && std::abs(xf.m[1][2]) < eps && std::abs(xf.m[0][0] - xf.m[2][2]) < eps &&
                       std::abs(xf.m[0][2] + xf.m[2][0]) < eps &&
                       std::abs(xf.m[0][0] * xf.m[0][0] + xf.m[0][2] * xf.m[0][2] - 1) < eps;
      if (!yRotation) fail(p.named["to_world"], "an environment map's to_world may only rotate about +y in invr");
      double beta = std::atan2(xf.m[0][2], xf.m[0][0]) * 180.0 / kPiD;
      double angle = std::fmod(beta + 180.0 + 360.0, 360.0);
      l.mutable_environment()->set_rotate_y_degrees(angle);
    } else if (type == "area") {
      fail(n, "an area emitter must be nested in the shape that emits");
    } else {
      fail(n, "emitter type '" + type + "' is not supported (area, point, spot, envmap, constant)");
    }
    samplingWeight(p, type == "point" || type == "spot");
    // mis_compensation reshapes the envmap's sampling distribution only; a constant emitter is the
    // same in every direction, so turning it changes nothing.
    finishProps(p, type == "envmap" ? std::set<std::string>{"mis_compensation"} : type == "constant" ? std::set<std::string>{"to_world"} : std::set<std::string>{});
    for (auto c : p.unnamed) fail(c, "unexpected element inside an emitter");
    *out_.job.mutable_scene()->add_lights() = l;
  }

  void sensor(pugi::xml_node n) {
    std::string type = n.attribute("type").value();
    if (type != "perspective") fail(n, "sensor type '" + type + "' is not supported (perspective)");
    Props p = props(n);
    Affine3d xf = toWorld(p);
    // Film and sampler first: fov_axis needs the film's aspect.
    int width = 768, height = 576, spp = 4;
    bool haveFilm = false, haveSampler = false;
    for (auto c : p.unnamed) {
      std::string tag = c.name();
      if (tag == "film") {
        std::string ft = c.attribute("type").value();
        if (ft != "hdrfilm") fail(c, "film type '" + ft + "' is not supported (hdrfilm)");
        Props fp = props(c);
        width = intProp(fp, "width", 768);
        height = intProp(fp, "height", 576);
        if (width < 1 || height < 1 || width > inputLimits().maxImageSide || height > inputLimits().maxImageSide)
          fail(c, "film size " + std::to_string(width) + "x" + std::to_string(height) + " (each side must be in 1.." +
                      std::to_string(inputLimits().maxImageSide) + ")");
        for (const char* crop : {"crop_offset_x", "crop_offset_y", "crop_width", "crop_height"})
          if (fp.has(crop)) fail(fp.named[crop], "film crops are not supported");
        for (auto f : fp.unnamed) {
          if (std::string(f.name()) != "rfilter") fail(f, "unexpected element inside a film");
          std::string rt = f.attribute("type").value();
          Props rp = props(f);
          if (rt == "box") {
            // invr's pixel filter: one uniform sample over the pixel.
          } else if (rt == "tent" || rt == "gaussian") {
            warn(f, "reconstruction filter '" + rt + "' is replaced by invr's box filter (one uniform sample over each pixel): edges come out slightly sharper");
            rp.used.insert("stddev");
            rp.used.insert("radius");
          } else {
            fail(f, "reconstruction filter '" + rt + "' is not supported (box; tent and gaussian become box)");
          }
          finishProps(rp);
        }
        bool haveFilter = false;
        for (auto f : fp.unnamed) haveFilter = haveFilter || std::string(f.name()) == "rfilter";
        if (!haveFilter) warn(c, "Mitsuba's default gaussian reconstruction filter is replaced by invr's box filter (one uniform sample over each pixel)");
        finishProps(fp, {"pixel_format", "component_format", "file_format", "sample_border", "compensate", "banner", "high_quality_edges"});
        haveFilm = true;
      } else if (tag == "sampler") {
        std::string st = c.attribute("type").value();
        Props sp = props(c);
        spp = intProp(sp, "sample_count", 4);
        if (spp < 1) fail(c, "sample_count must be positive");
        if (st != "independent" && st != "stratified" && st != "multijitter" && st != "orthogonal" && st != "ldsampler")
          fail(c, "sampler type '" + st + "' is not known");
        if (st != "independent") warn(c, "sampler '" + st + "': invr samples independently (the noise differs, the image converges to the same)");
        finishProps(sp, {"seed", "jitter", "strength"});
        haveSampler = true;
      } else if (tag == "ref" || tag == "bsdf" || tag == "emitter" || tag == "shape") {
        fail(c, "unexpected element inside a sensor");
      } else {
        fail(c, "unexpected element inside a sensor");
      }
    }
    if (!haveFilm) warn(n, "no <film>: Mitsuba's default 768x576 hdrfilm, whose gaussian reconstruction filter is replaced by invr's box filter");
    auto* sc = out_.job.mutable_scene();
    if (sensors_ > 0 && (sc->film().width() != width || sc->film().height() != height))
      fail(n, "every sensor of a scene must share one film size in invr (" + std::to_string(sc->film().width()) + "x" +
                  std::to_string(sc->film().height()) + " before)");
    sc->mutable_film()->set_width(width);
    sc->mutable_film()->set_height(height);
    if (haveSampler || sensors_ == 0) out_.job.mutable_render()->set_spp(spp);

    // Field of view, converted to invr's vertical one.
    const double aspect = double(width) / double(height);
    double fov = 0;
    std::string axis = "x";
    if (p.has("focal_length") && p.has("fov")) fail(n, "give either fov or focal_length");
    if (!p.has("fov")) {
      // 35 mm film equivalent (Mitsuba's default 50mm): the field over the film's 43.3 mm diagonal.
      pugi::xml_node f = p.get("focal_length");
      std::string v = f ? attr(f, "value") : "50mm";
      if (v.size() > 2 && v.substr(v.size() - 2) == "mm") v = v.substr(0, v.size() - 2);
      double mm = number(f ? f : n, v, "focal_length");
      if (!(mm > 0)) fail(f ? f : n, "focal_length must be positive");
      fov = 2.0 * std::atan(std::sqrt(36.0 * 36.0 + 24.0 * 24.0) / (2.0 * mm)) * 180.0 / kPiD;
      axis = "diagonal";
    } else {
      fov = floatProp(p, "fov", 0);
      axis = stringProp(p, "fov_axis", "x");
    }
    for (char& ch : axis) ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if (!(fov > 0 && fov < 180)) fail(n, "fov must be in (0, 180) degrees");
    double t = std::tan(0.5 * fov * kPiD / 180.0), tY = t;
    if (axis == "smaller") axis = width < height ? "x" : "y";
    if (axis == "larger") axis = width > height ? "x" : "y";
    if (axis == "x") tY = t / aspect;
    else if (axis == "y") tY = t;
    else if (axis == "diagonal") tY = t / std::sqrt(aspect * aspect + 1.0);
    else fail(p.named["fov_axis"], "fov_axis '" + axis + "' (x, y, diagonal, smaller or larger)");
    double fovY = 2.0 * std::atan(tY) * 180.0 / kPiD;

    // Mitsuba's camera looks along local +z with +y up and +x to the image's left.
    D3 eye = applyPoint(xf, {0, 0, 0}), fwd = applyVector(xf, {0, 0, 1}), up = applyVector(xf, {0, 1, 0}), left = applyVector(xf, {1, 0, 0});
    if (!(lenD(fwd) > 0 && lenD(up) > 0)) fail(n, "to_world collapses the camera frame");
    {
      const double eps = 1e-5;
      bool rigid = std::abs(lenD(fwd) - 1) < eps && std::abs(lenD(up) - 1) < eps && std::abs(lenD(left) - 1) < eps &&
                   std::abs(dotD(fwd, up)) < eps && std::abs(dotD(fwd, left)) < eps && std::abs(dotD(up, left)) < eps;
      if (!rigid && dotD(crossD(up, fwd), left) >= 0)
        fail(p.named["to_world"], "a camera's to_world must be a rotation and translation (Mitsuba refuses scales and shears there too)");
    }
    if (dotD(crossD(up, fwd), left) < 0)
      fail(p.named["to_world"], "the camera's to_world mirrors the image (a negative scale); invr's camera cannot");
    fwd = scaleD(fwd, 1.0 / lenD(fwd));
    v1::Camera cam;
    cam.set_name(n.attribute("id").value());
    *cam.mutable_eye() = toVec(eye);
    *cam.mutable_target() = toVec(add(eye, fwd));
    *cam.mutable_up() = toVec(scaleD(up, 1.0 / lenD(up)));
    cam.set_fov_y_degrees(fovY);
    double nearClip = floatProp(p, "near_clip", 1e-2), farClip = floatProp(p, "far_clip", 1e4);
    if (!(nearClip > 0 && farClip > nearClip)) fail(n, "near_clip and far_clip must satisfy 0 < near_clip < far_clip");
    if (p.used.count("near_clip") || p.used.count("far_clip"))
      warn(p.named.count("near_clip") ? p.named["near_clip"] : p.named["far_clip"],
           "clip planes are not applied: invr's camera rays start at the eye and are unbounded, so geometry nearer than near_clip "
           "or farther than far_clip stays visible");
    *sc->add_views() = cam;
    // A pinhole camera has no focus, and a static scene looks the same whatever the shutter times.
    finishProps(p, {"focus_distance", "shutter_open", "shutter_close"});
    ++sensors_;
  }
  void integrator(pugi::xml_node n) {
    if (integrators_++ > 0) fail(n, "a scene takes one integrator");
    std::string type = n.attribute("type").value();
    Props p = props(n);
    int depth = 0;
    // The projective-sampling integrators of Mitsuba's shape optimisation: their own boundary
    // sampling options have no counterpart (invr samples boundaries with its own terms).
    const bool projective = type == "direct_projective" || type == "prb_projective";
    if (projective) {
      std::vector<std::string> ignored;
      for (const char* name : {"sppc", "sppp", "sppi", "guiding", "guiding_proj", "guiding_rounds", "project_seed"})
        if (p.named.count(name)) {
          p.used.insert(name);
          ignored.push_back(name);
        }
      if (!ignored.empty()) {
        std::string list;
        for (const auto& i : ignored) list += (list.empty() ? "" : ", ") + i;
        warn(n, list + ": ignored (projective sampling options; invr samples visibility discontinuities with its own boundary terms, "
                       "set in the job's optimization.boundary)");
      }
    }
    if (type == "direct_projective") {
      // Direct illumination with boundary terms; Mitsuba's base class still reads these two.
      for (const char* name : {"max_depth", "rr_depth"})
        if (p.named.count(name)) {
          p.used.insert(name);
          warn(p.named[name], std::string(name) + ": ignored (direct_projective renders direct illumination)");
        }
      depth = 1;
    } else if (type == "path" || type == "prb" || type == "prb_basic" || type == "prb_projective") {
      int md = intProp(p, "max_depth", type == "path" || type == "prb_projective" ? -1 : 6);
      if (md == 0 || md < -1) fail(p.named["max_depth"], "max_depth must be -1 (unlimited) or >= 2");
      if (md == 1) fail(p.named["max_depth"], "max_depth 1 shows only emitters seen directly; invr renders at least direct illumination (max_depth 2)");
      // Mitsuba counts the camera segment; invr counts the vertices after the camera.
      depth = md == -1 ? kUnlimitedDepth : std::min(md - 1, kUnlimitedDepth);
      if (md - 1 > kUnlimitedDepth) warn(p.named["max_depth"], "max_depth " + std::to_string(md) + " is cut to invr's longest paths (" + std::to_string(kUnlimitedDepth) + " vertices)");
      if (md == -1) warn(p.named.count("max_depth") ? p.named["max_depth"] : n, "unlimited depth becomes invr's longest paths (" + std::to_string(kUnlimitedDepth) + " vertices, with Russian roulette)");
      int rr = intProp(p, "rr_depth", 5);
      if (rr < 1) fail(p.named["rr_depth"], "rr_depth must be >= 1");
      out_.job.mutable_render()->set_russian_roulette_depth(std::max(1, rr - 1));
    } else if (type == "direct") {
      depth = 1;
      const int shading = intProp(p, "shading_samples", 1);
      if (intProp(p, "emitter_samples", shading) == 0 || intProp(p, "bsdf_samples", shading) == 0)
        fail(n, "emitter_samples or bsdf_samples = 0 leaves light out of Mitsuba's image (delta lights, or what only BSDF sampling reaches); invr's cannot");
      if (p.used.count("emitter_samples") || p.used.count("bsdf_samples") || p.used.count("shading_samples"))
        warn(n, "shading_samples / emitter_samples / bsdf_samples: invr takes one light and one BSDF sample per vertex (the noise differs, not the image)");
    } else {
      fail(n, "integrator type '" + type + "' is not supported (path, prb, prb_basic, prb_projective, direct, direct_projective)");
    }
    if (boolProp(p, "hide_emitters", false)) fail(p.named["hide_emitters"], "hide_emitters=true is not supported");
    out_.job.mutable_render()->set_max_depth(depth);
    finishProps(p, {"timeout", "block_size", "samples_per_pass"});  // scheduling, not the image
    for (auto c : p.unnamed) fail(c, "unexpected element inside an integrator");
  }
  static constexpr int kUnlimitedDepth = 64;

  void finish(pugi::xml_node scene) {
    if (sensors_ == 0) fail(scene, "the scene has no <sensor type=\"perspective\">: invr needs a camera");
    if (integrators_ == 0) {
      // Mitsuba's default integrator is a path tracer of unlimited depth.
      out_.job.mutable_render()->set_max_depth(kUnlimitedDepth);
      out_.warnings.push_back(rootSource().name + ": no <integrator>: Mitsuba's default path tracer (unlimited depth) becomes invr's longest paths (" +
                              std::to_string(kUnlimitedDepth) + " vertices)");
    }
    if (out_.job.scene().lights_size() == 0) fail(scene, "the scene has no emitter: it would render black");
    // Objects no shape uses cannot change the image, but are still checked: a mistake in them is
    // reported as Mitsuba would report it.
    for (auto n : topLevel_) {
      std::string tag = n.name(), id = n.attribute("id").value();
      if (tag == "bsdf" && !bsdfMaterial_.count(id) && !wrapped_.count(id)) {
        v1::Material scratch;
        resolving_.insert(id);
        bsdfInto(n, &scratch);
        resolving_.erase(id);
        warn(n, "bsdf \"" + id + "\" is not used by any shape");
      } else if (tag == "texture" && !usedTextures_.count(id)) {
        v1::Texture scratch;
        bitmap(n, &scratch, true);
        warn(n, "texture \"" + id + "\" is not used");
      }
    }
  }
};

}  // namespace

MitsubaImport importMitsubaSceneText(const std::string& xml, const fs::path& baseDir, const std::string& sourceName,
                                     const MitsubaImportOptions& options) {
  Importer im(options);
  MitsubaImport out = im.run(xml, baseDir, sourceName);
  // The limits every job meets (name lengths, counts), whichever way it was written.
  try {
    validateJobSpec(out.job);
  } catch (const InputError& e) {
    rethrowWithMessage(e, sourceName + ": " + e.what());
  }
  return out;
}

MitsubaImport importMitsubaScene(const fs::path& xml, const MitsubaImportOptions& options) {
  std::string text = readSceneFile(xml, "Mitsuba scene");
  return importMitsubaSceneText(text, xml.has_parent_path() ? xml.parent_path() : fs::path("."), xml.string(), options);
}

}  // namespace invr
