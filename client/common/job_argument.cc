#include "client/common/job_argument.h"

#include <nlohmann/json.hpp>

#include <iostream>
#include <regex>
#include <sstream>

#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "core/io/mitsuba_import.h"
#include "core/limits.h"

namespace invr::cli {

namespace v1 = invr::v1;
namespace fs = std::filesystem;

bool isJobFile(const std::string& arg) { return arg.size() > 5 && arg.substr(arg.size() - 5) == ".json"; }

void addSceneArgs(CLI::App* cmd, SceneArgs& a, bool withParams) {
  // One value per occurrence, so a positional after them is not taken for one.
  cmd->add_option("-D,--define", a.defines, "NAME=VALUE: set a Mitsuba scene's <default name=NAME> (repeatable)")->allow_extra_args(false);
  if (withParams)
    cmd->add_option("--param", a.params,
                    "NAME[=V[,V,V]]: recover this parameter (invr or Mitsuba name, e.g. red.reflectance.value=0.01,0.2,0.9), starting "
                    "at the values given; replaces the job's parameter list (repeatable)")
        ->allow_extra_args(false);
  cmd->add_option("--set", a.sets,
                  "FIELD.PATH=VALUE: set any job field, e.g. optimization.steps=50, optimization.parameters[0].learning_rate=0.05, "
                  "render.spp=64, optimization.method=pt (repeatable; applied after the job is loaded)")
      ->allow_extra_args(false);
}

void applySets(v1::JobSpec& job, const std::vector<std::string>& sets) {
  if (sets.empty()) return;
  using nlohmann::json;
  json doc = json::parse(jobToJson(job));
  for (const auto& set : sets) {
    const size_t eq = set.find('=');
    if (eq == std::string::npos || eq == 0) throw InputError("--set '" + set + "': expected FIELD.PATH=VALUE (e.g. optimization.steps=50)");
    const std::string path = set.substr(0, eq), text = set.substr(eq + 1);
    json value = json::parse(text, nullptr, false);
    if (value.is_discarded()) value = text;  // a bare word: a string (an enum name, a file path)
    // Segments: "a.b[2].c" and "a.b.2.c" both index the list b.
    std::vector<std::string> segs;
    std::string cur;
    for (char c : path) {
      if (c == '.' || c == '[' || c == ']') {
        if (!cur.empty()) segs.push_back(cur);
        cur.clear();
      } else {
        cur += c;
      }
    }
    if (!cur.empty()) segs.push_back(cur);
    if (segs.empty()) throw InputError("--set '" + set + "': no field named");
    json* at = &doc;
    for (size_t i = 0; i < segs.size(); ++i) {
      const std::string& k = segs[i];
      const bool last = i + 1 == segs.size();
      const bool index = !k.empty() && k.find_first_not_of("0123456789") == std::string::npos;
      if (index && at->is_array()) {
        const size_t n = std::stoul(k);
        if (n >= at->size())
          throw InputError("--set '" + set + "': index " + k + " is past the end of the list (it has " + std::to_string(at->size()) + " elements)");
        at = &(*at)[n];
      } else {
        if (at->is_null()) *at = json::object();
        if (!at->is_object()) throw InputError("--set '" + set + "': '" + k + "' is inside a value that is not an object");
        at = &(*at)[k];
      }
      if (last) *at = value;
    }
  }
  try {
    job = parseJobJson(doc.dump(), "--set");
  } catch (const InputError& e) {
    // The parser places errors at a line:column of the rewritten text, which the user never saw.
    std::string msg = e.what();
    static const std::regex place(R"(^--set:\d+:\d+: )");
    rethrowWithMessage(e, std::regex_replace(msg, place, "--set: "));
  }
}

namespace {

std::map<std::string, std::string> parseDefines(const std::vector<std::string>& defines) {
  std::map<std::string, std::string> out;
  for (const auto& d : defines) {
    auto eq = d.find('=');
    if (eq == std::string::npos || eq == 0) throw InputError("-D '" + d + "': expected NAME=VALUE");
    out[d.substr(0, eq)] = d.substr(eq + 1);
  }
  return out;
}

void printWarnings(const std::vector<std::string>& warnings) {
  for (const auto& w : warnings) std::cerr << "warning: " << w << "\n";
}

// `p` (absolute, or relative to the working directory) relative to `base` where it lies in base's
// folder tree or its parent's (a job next to its scene stays movable with it); absolute otherwise.
std::string pathRelativeTo(const fs::path& p, const fs::path& base) {
  const fs::path abs = fs::absolute(p).lexically_normal();
  fs::path rel = abs.lexically_relative(fs::absolute(base).lexically_normal());
  const std::string r = rel.generic_string();
  if (rel.empty() || r.rfind("../../", 0) == 0 || r == "../..") return abs.string();
  return rel.string();
}

}  // namespace

void rebaseAssetPaths(v1::JobSpec& job, const fs::path& fromDir, const fs::path& toDir) {
  forEachAssetRef(job, [&](v1::AssetRef& ref, const std::string&) {
    if (ref.has_path() && fs::path(ref.path()).is_relative()) ref.set_path(pathRelativeTo(fromDir / ref.path(), toDir));
  });
}

void importMitsubaIntoJob(v1::JobSpec& job, const fs::path& baseDir, std::vector<std::string>& warnings) {
  const auto& m = job.mitsuba();
  if (m.path().empty()) throw InputError("mitsuba.path: empty (the .xml scene file, relative to the job file)");
  fs::path xml(m.path());
  if (xml.is_relative()) xml = baseDir / xml;
  if (!fs::exists(xml)) throw InputError("mitsuba.path: '" + xml.string() + "' not found");
  MitsubaImportOptions opt;
  for (const auto& [k, v] : m.defaults()) opt.defaults[k] = v;
  MitsubaImport imp = importMitsubaScene(xml, opt);
  warnings.insert(warnings.end(), imp.warnings.begin(), imp.warnings.end());
  const fs::path xmlDir = xml.has_parent_path() ? xml.parent_path() : fs::path(".");
  forEachAssetRef(imp.job, [&](v1::AssetRef& ref, const std::string&) {
    if (ref.has_path() && fs::path(ref.path()).is_relative()) ref.set_path(pathRelativeTo(xmlDir / ref.path(), baseDir));
  });
  const v1::RenderSettings& r = imp.job.render();
  auto* jr = job.mutable_render();
  if (jr->spp() == 0) jr->set_spp(r.spp());
  if (jr->russian_roulette_depth() == 0) jr->set_russian_roulette_depth(r.russian_roulette_depth());
  if (jr->max_depth() == 0) {
    if (!job.has_optimization()) {
      jr->set_max_depth(r.max_depth());
    } else if (job.optimization().max_depth() == 0 && r.max_depth() > 1) {
      if (job.optimization().method() == v1::METHOD_PT)
        job.mutable_optimization()->set_max_depth(r.max_depth());
      else
        warnings.push_back(xml.string() + ": the integrator's depth (" + std::to_string(r.max_depth()) +
                           " vertices) is not used: the job's method differentiates direct illumination; set optimization.max_depth "
                           "with method METHOD_PT for longer paths");
    }
  }
  if (job.name().empty()) job.set_name(imp.job.name());
  *job.mutable_scene() = imp.job.scene();  // replaces `mitsuba` in the oneof
}

v1::JobSpec jobFromArgument(const std::string& arg, AssetResolver& assets, const SceneArgs& sceneArgs, bool* imported) {
  if (imported) *imported = false;
  auto defines = parseDefines(sceneArgs.defines);
  std::vector<std::string> warnings;
  v1::JobSpec job;
  if (isJobFile(arg) || arg == "-") {
    if (arg == "-") {  // the job's JSON on standard input; its relative paths from the working directory
      std::stringstream text;
      text << std::cin.rdbuf();
      assets.baseDir = fs::path(".");
      job = parseJobJson(text.str(), "<stdin>");
    } else {
      fs::path p(arg);
      if (!fs::exists(p)) throw InputError("job file '" + arg + "': not found");
      assets.baseDir = p.has_parent_path() ? p.parent_path() : fs::path(".");
      job = loadJobFile(p);
    }
    if (job.has_mitsuba()) {
      if (imported) *imported = true;
      for (const auto& [k, v] : defines) (*job.mutable_mitsuba()->mutable_defaults())[k] = v;
      try {
        importMitsubaIntoJob(job, assets.baseDir, warnings);
      } catch (const InputError& e) {
        rethrowWithMessage(e, "job file '" + arg + "': " + e.what());
      }
    } else if (!defines.empty()) {
      throw InputError("-D: applies to Mitsuba scenes only ('" + arg + "' does not name one)");
    }
  } else if (isMitsubaSceneFile(arg)) {
    fs::path p(arg);
    if (!fs::exists(p)) throw InputError("Mitsuba scene '" + arg + "': not found");
    MitsubaImportOptions opt;
    opt.defaults = defines;
    MitsubaImport imp = importMitsubaScene(p, opt);
    if (imported) *imported = true;
    warnings = imp.warnings;
    job = std::move(imp.job);
    assets.baseDir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  } else {
    if (!defines.empty()) throw InputError("-D: applies to Mitsuba scenes only ('" + arg + "' is a zoo scene name)");
    job = zooJob(arg);  // InputError listing the known names
  }
  printWarnings(warnings);
  applySets(job, sceneArgs.sets);
  return job;
}

v1::JobSpec optimizationJobFromArgument(const std::string& arg, AssetResolver& assets, const SceneArgs& sceneArgs) {
  bool imported = false;
  v1::JobSpec job = jobFromArgument(arg, assets, sceneArgs, &imported);
  const bool xml = isMitsubaSceneFile(arg);
  if (sceneArgs.params.empty()) {
    if (job.has_optimization() && job.optimization().parameters_size() > 0) return job;
    if (xml)
      throw InputError("'" + arg + "' is a Mitsuba scene: name what to recover with --param NAME[=INITIAL] (e.g. --param "
                       "red.reflectance.value=0.01,0.2,0.9), or write a job with `invr import " + arg +
                       " -o job.json` and add an 'optimization' block");
    throw InputError("job file '" + arg + "': has no 'optimization' parameters (see `invr example cornell`), or name them with --param");
  }
  auto* o = job.mutable_optimization();
  o->clear_parameters();
  for (const auto& p : sceneArgs.params) {
    auto* ps = o->add_parameters();
    auto eq = p.find('=');
    ps->set_name(p.substr(0, eq));
    if (ps->name().empty()) throw InputError("--param '" + p + "': expected NAME or NAME=V[,V,V]");
    if (eq == std::string::npos) continue;
    std::string list = p.substr(eq + 1);
    size_t start = 0;
    while (start <= list.size()) {
      size_t comma = list.find(',', start);
      std::string tok = list.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      char* end = nullptr;
      double v = std::strtod(tok.c_str(), &end);
      if (tok.empty() || end != tok.c_str() + tok.size() || !std::isfinite(v))
        throw InputError("--param '" + p + "': '" + tok + "' is not a number");
      ps->add_initial_values(v);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
  }
  // A scene file's own depth: the optimisation renders and differentiates what the file renders.
  const int depth = job.render().max_depth();
  if (imported && o->max_depth() == 0 && depth > 1) {
    o->set_max_depth(depth);
    if (o->method() == v1::METHOD_UNSPECIFIED) o->set_method(v1::METHOD_PT);
  }
  return job;
}

}  // namespace invr::cli
