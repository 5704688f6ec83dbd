#include "core/job/job_source.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <regex>

#include "core/error.h"
#include "core/limits.h"
#include "core/io/job_io.h"
#include "core/io/mitsuba_import.h"
#include "core/job/zoo_jobs.h"

namespace invr {

namespace v1 = invr::v1;
namespace fs = std::filesystem;

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

std::map<std::string, std::string> parseDefines(const std::vector<std::string>& defines) {
  std::map<std::string, std::string> out;
  for (const auto& d : defines) {
    auto eq = d.find('=');
    if (eq == std::string::npos || eq == 0) throw InputError("-D '" + d + "': expected NAME=VALUE");
    out[d.substr(0, eq)] = d.substr(eq + 1);
  }
  return out;
}

namespace {

// `p` (absolute, or relative to the working directory) relative to `base` where it lies in base's
// folder tree or its parent's (a job next to its scene stays movable with it); absolute otherwise.
std::string pathRelativeTo(const fs::path& p, const fs::path& base) {
  const fs::path abs = fs::absolute(p).lexically_normal();
  fs::path rel = abs.lexically_relative(fs::absolute(base).lexically_normal());
  const std::string r = rel.generic_string();
  if (rel.empty() || r.rfind("../../", 0) == 0 || r == "../..") return abs.string();
  return rel.string();
}

// A missing file as the caller names it: relative to baseDir where it lies below it.
std::string missingName(const fs::path& file, const fs::path& baseDir) {
  fs::path rel = fs::absolute(file).lexically_normal().lexically_relative(fs::absolute(baseDir).lexically_normal());
  return rel.empty() ? file.generic_string() : rel.generic_string();
}

// --param NAME[=V[,V,V]]... replaces the parameter list.
void applyParams(v1::JobSpec& job, const std::vector<std::string>& params) {
  auto* o = job.mutable_optimization();
  o->clear_parameters();
  for (const auto& p : params) {
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
}

}  // namespace

void rebaseAssetPaths(v1::JobSpec& job, const fs::path& fromDir, const fs::path& toDir) {
  forEachAssetRef(job, [&](v1::AssetRef& ref, const std::string&) {
    if (ref.has_path() && fs::path(ref.path()).is_relative()) ref.set_path(pathRelativeTo(fromDir / ref.path(), toDir));
  });
}

void importMitsubaIntoJob(v1::JobSpec& job, const fs::path& baseDir, std::vector<std::string>& warnings, std::vector<std::string>* missing) {
  const auto& m = job.mitsuba();
  if (m.path().empty()) throw InputError("mitsuba.path: empty (the .xml scene file, relative to the job file)");
  fs::path xml(m.path());
  if (xml.is_relative()) xml = baseDir / xml;
  if (!fs::exists(xml)) {
    if (missing) {
      missing->push_back(missingName(xml, baseDir));
      return;
    }
    throw InputError("mitsuba.path: '" + xml.string() + "' not found");
  }
  MitsubaImportOptions opt;
  for (const auto& [k, v] : m.defaults()) opt.defaults[k] = v;
  std::vector<std::string> missingBelowXml;
  if (missing) opt.missingFiles = &missingBelowXml;
  MitsubaImport imp = importMitsubaScene(xml, opt);
  warnings.insert(warnings.end(), imp.warnings.begin(), imp.warnings.end());
  const fs::path xmlDir = xml.has_parent_path() ? xml.parent_path() : fs::path(".");
  for (const auto& f : missingBelowXml) missing->push_back(missingName(xmlDir / f, baseDir));
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

ResolvedJob resolveJob(const JobSource& src, const JobOverrides& ov, bool forOptimization, bool collectMissing) {
  ResolvedJob r;
  const auto defines = parseDefines(ov.defines);
  std::vector<std::string>* missing = collectMissing ? &r.missing : nullptr;
  switch (src.kind) {
    case JobSource::Kind::JobJson: {
      r.baseDir = src.baseDir.empty() ? fs::path(".") : src.baseDir;
      r.job = parseJobJson(src.json, src.name);
      if (r.job.has_mitsuba()) {
        r.imported = true;
        for (const auto& [k, v] : defines) (*r.job.mutable_mitsuba()->mutable_defaults())[k] = v;
        try {
          importMitsubaIntoJob(r.job, r.baseDir, r.warnings, missing);
        } catch (const InputError& e) {
          rethrowWithMessage(e, "job file '" + src.name + "': " + e.what());
        }
        if (!r.missing.empty()) return r;
      } else if (!defines.empty()) {
        throw InputError("-D: applies to Mitsuba scenes only ('" + src.name + "' does not name one)");
      }
      break;
    }
    case JobSource::Kind::MitsubaXml: {
      r.baseDir = src.xml.has_parent_path() ? src.xml.parent_path() : fs::path(".");
      if (!fs::exists(src.xml)) {
        if (!missing) throw InputError("Mitsuba scene '" + src.name + "': not found");
        missing->push_back(missingName(src.xml, r.baseDir));
        return r;
      }
      MitsubaImportOptions opt;
      opt.defaults = defines;
      opt.missingFiles = missing;
      MitsubaImport imp = importMitsubaScene(src.xml, opt);
      if (!r.missing.empty()) return r;
      r.imported = true;
      r.warnings = imp.warnings;
      r.job = std::move(imp.job);
      break;
    }
    case JobSource::Kind::Zoo:
      if (!defines.empty()) throw InputError("-D: applies to Mitsuba scenes only ('" + src.zoo + "' is a zoo scene name)");
      r.job = zooJob(src.zoo);  // InputError naming the closest zoo names
      break;
  }
  applySets(r.job, ov.sets);
  if (!ov.params.empty()) {
    applyParams(r.job, ov.params);
  } else if (forOptimization && !(r.job.has_optimization() && r.job.optimization().parameters_size() > 0)) {
    if (src.kind == JobSource::Kind::MitsubaXml)
      throw InputError("'" + src.name + "' is a Mitsuba scene: name what to recover with --param NAME[=INITIAL] (e.g. --param "
                       "red.reflectance.value=0.01,0.2,0.9), or write a job with `invr import " + src.name +
                       " -o job.json` and add an 'optimization' block");
    throw InputError("job file '" + src.name + "': has no 'optimization' parameters (see `invr example cornell`), or name them with --param");
  }
  if (!ov.params.empty()) {
    // A scene file's own depth: the optimisation renders and differentiates what the file renders.
    auto* o = r.job.mutable_optimization();
    const int depth = r.job.render().max_depth();
    if (r.imported && o->max_depth() == 0 && depth > 1) {
      o->set_max_depth(depth);
      if (o->method() == v1::METHOD_UNSPECIFIED) o->set_method(v1::METHOD_PT);
    }
  }
  return r;
}

}  // namespace invr
