#include "core/io/job_io.h"

#include <google/protobuf/util/json_util.h>

#include <fstream>
#include <regex>
#include <sstream>

#include "core/error.h"
#include "core/io/job_json_normalize.h"
#include "core/limits.h"
#include "core/math/rng.h"

namespace invr {

namespace {

std::string lineCol(const std::string& text, size_t offset) {
  size_t line = 1, col = 1;
  for (size_t i = 0; i < offset && i < text.size(); ++i) {
    if (text[i] == '\n') { ++line; col = 1; } else { ++col; }
  }
  return std::to_string(line) + ":" + std::to_string(col);
}

// Best-effort location of a protobuf JSON error in the source text.
std::string locate(const std::string& json, const std::string& message) {
  // Syntax errors come with an excerpt of the source (which may span lines) and, on the last
  // line, a caret whose column indexes into that excerpt.
  auto nl = message.find('\n');
  if (nl != std::string::npos) {
    auto lastNl = message.rfind('\n');
    std::string excerpt = message.substr(nl + 1, lastNl > nl ? lastNl - nl - 1 : 0);
    std::string caret = message.substr(lastNl + 1);
    size_t at = excerpt.empty() ? std::string::npos : json.find(excerpt);
    size_t col = caret.find('^');
    if (at != std::string::npos && col != std::string::npos) return lineCol(json, at + col);
    return "";
  }
  // Unknown field "(path) key: Cannot find field." or bad value "(path.key): invalid value ...".
  std::smatch m;
  std::string key;
  if (std::regex_search(message, m, std::regex(R"(\) (\w+): Cannot find field)"))) key = m[1];
  else if (std::regex_search(message, m, std::regex(R"(\(([\w\.\[\]]+)\):)"))) {
    key = m[1];
    key = key.substr(key.find_last_of('.') + 1);
    key = key.substr(0, key.find('['));
  }
  if (key.empty()) return "";
  size_t at = json.find("\"" + key + "\"");
  return at == std::string::npos ? "" : lineCol(json, at);
}

std::string firstLine(const std::string& s) { return s.substr(0, s.find('\n')); }

}  // namespace

invr::v1::JobSpec parseJobJson(const std::string& json, const std::string& sourceName) {
  invr::v1::JobSpec job;
  std::string normalized, syntaxAt;
  JsonFieldError fieldError;
  if (!normalizeJobJson(json, invr::v1::JobSpec::descriptor(), normalized, fieldError, syntaxAt)) {
    if (!syntaxAt.empty()) throw InputError(sourceName + ":" + syntaxAt + ": " + fieldError.message);
    if (fieldError.path.empty()) throw InputError(sourceName + ": " + fieldError.message);
    const size_t at = json.find("\"" + fieldError.key + "\"");
    throw InputError(sourceName + (at == std::string::npos ? "" : ":" + lineCol(json, at)) + ": " + fieldError.path + ": " + fieldError.message);
  }
  google::protobuf::util::JsonParseOptions opts;
  opts.ignore_unknown_fields = false;
  auto status = google::protobuf::util::JsonStringToMessage(normalized, &job, opts);
  if (!status.ok()) {
    std::string msg(status.message());
    std::string where = locate(json, msg);
    std::string text = firstLine(msg);
    // "(render) spq: Cannot find field." -> "render.spq: unknown field"
    std::smatch m;
    if (std::regex_search(text, m, std::regex(R"(^\(([^)]*)\) (\w+): Cannot find field\.?)")))
      text = (m[1].str().empty() ? "" : m[1].str() + ".") + m[2].str() + ": unknown field";
    else if (std::regex_search(text, m, std::regex(R"(^\(([^)]*)\): (.*)$)")))
      text = m[1].str().empty() ? m[2].str() : m[1].str() + ": " + m[2].str();
    if (text.rfind(": ", 0) == 0) text = text.substr(2);  // a message about the top level has an empty path
    throw InputError(sourceName + (where.empty() ? "" : ":" + where) + ": " + text);
  }
  validateJobSpec(job);
  return job;
}

invr::v1::JobSpec loadJobFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw InputError("job file '" + path.string() + "': cannot open");
  std::stringstream ss;
  ss << in.rdbuf();
  return parseJobJson(ss.str(), path.string());
}

std::string jobToJson(const invr::v1::JobSpec& job) {
  std::string out;
  google::protobuf::util::JsonPrintOptions opts;
  opts.add_whitespace = true;
  opts.preserve_proto_field_names = true;
  auto st = google::protobuf::util::MessageToJsonString(job, &out, opts);
  if (!st.ok()) throw std::runtime_error("cannot serialise job: " + std::string(st.message()));
  return out;
}

void validateRenderSettings(const invr::v1::RenderSettings& r, const std::string& path) {
  auto bad = [&](const std::string& field, const std::string& why) { throw InputError(path + "." + field + ": " + why); };
  if (r.spp() < 0) bad("spp", "must be positive (got " + std::to_string(r.spp()) + ")");
  if (r.spp() > 1 << 20) bad("spp", "too large (got " + std::to_string(r.spp()) + ", max 1048576)");
  if (r.max_depth() < 0 || r.max_depth() > 1024) bad("max_depth", "must be in 1..1024 (got " + std::to_string(r.max_depth()) + ")");
  if (r.ris_candidates() < 0 || r.ris_candidates() > 4096) bad("ris_candidates", "must be in 1..4096 (got " + std::to_string(r.ris_candidates()) + ")");
  if (r.russian_roulette_depth() < 0) bad("russian_roulette_depth", "must not be negative");
  samplerKindFromName(r.sampler(), path + ".sampler");
}

namespace {

std::string fieldPath(const std::string& parent, const std::string& name) { return parent.empty() ? name : parent + "." + name; }

// Everything protobuf's parsers accept but a job must not hold: enum numbers that name no value
// (proto3 keeps them as open enums), oversized strings and repeated fields.
void checkBounds(const google::protobuf::Message& m, const std::string& path) {
  namespace pb = google::protobuf;
  const InputLimits& lim = inputLimits();
  const auto* desc = m.GetDescriptor();
  const auto* refl = m.GetReflection();
  auto checkEnum = [&](const pb::FieldDescriptor* f, int value, const std::string& at) {
    if (f->enum_type()->FindValueByNumber(value)) return;
    std::string known;
    for (int k = 0; k < f->enum_type()->value_count(); ++k) {
      if (f->enum_type()->value(k)->number() == 0) continue;  // the unspecified default
      known += (known.empty() ? "" : ", ") + f->enum_type()->value(k)->name();
    }
    throw InputError(at + ": unknown value " + std::to_string(value) + " (use one of " + known + ")");
  };
  auto checkString = [&](const pb::FieldDescriptor* f, const std::string& v, const std::string& at) {
    size_t limit = f->name() == "name" ? lim.maxNameBytes : lim.maxStringBytes;
    if (v.size() > limit)
      throw InputError(at + ": " + std::to_string(v.size()) + " bytes long (limit " + std::to_string(limit) + ")");
  };
  for (int i = 0; i < desc->field_count(); ++i) {
    const auto* f = desc->field(i);
    const std::string sub = fieldPath(path, f->name());
    if (f->is_repeated()) {
      int n = refl->FieldSize(m, f);
      if (n > lim.maxRepeated)
        throw InputError(sub + ": " + std::to_string(n) + " entries (limit " + std::to_string(lim.maxRepeated) + ")");
      for (int k = 0; k < n; ++k) {
        const std::string at = sub + "[" + std::to_string(k) + "]";
        switch (f->cpp_type()) {
          case pb::FieldDescriptor::CPPTYPE_MESSAGE: checkBounds(refl->GetRepeatedMessage(m, f, k), at); break;
          case pb::FieldDescriptor::CPPTYPE_ENUM: checkEnum(f, refl->GetRepeatedEnumValue(m, f, k), at); break;
          case pb::FieldDescriptor::CPPTYPE_STRING: checkString(f, refl->GetRepeatedString(m, f, k), at); break;
          default: break;
        }
      }
      continue;
    }
    if (f->has_presence() && !refl->HasField(m, f)) continue;
    switch (f->cpp_type()) {
      case pb::FieldDescriptor::CPPTYPE_MESSAGE: checkBounds(refl->GetMessage(m, f), sub); break;
      case pb::FieldDescriptor::CPPTYPE_ENUM: checkEnum(f, refl->GetEnumValue(m, f), sub); break;
      case pb::FieldDescriptor::CPPTYPE_STRING: checkString(f, refl->GetString(m, f), sub); break;
      default: break;
    }
  }
}

void walkAssets(google::protobuf::Message& m, const std::string& path,
                const std::function<void(v1::AssetRef&, const std::string&)>& fn) {
  if (auto* ref = dynamic_cast<v1::AssetRef*>(&m)) {
    fn(*ref, path);
    return;
  }
  const auto* desc = m.GetDescriptor();
  const auto* refl = m.GetReflection();
  for (int i = 0; i < desc->field_count(); ++i) {
    const auto* f = desc->field(i);
    if (f->cpp_type() != google::protobuf::FieldDescriptor::CPPTYPE_MESSAGE) continue;
    std::string sub = path.empty() ? f->name() : path + "." + f->name();
    if (f->is_repeated()) {
      for (int k = 0; k < refl->FieldSize(m, f); ++k)
        walkAssets(*refl->MutableRepeatedMessage(&m, f, k), sub + "[" + std::to_string(k) + "]", fn);
    } else if (refl->HasField(m, f)) {
      walkAssets(*refl->MutableMessage(&m, f), sub, fn);
    }
  }
}

}  // namespace

void validateJobSpec(const v1::JobSpec& job) {
  checkBounds(job, "");
  if (job.has_render()) validateRenderSettings(job.render());
  if (job.scheduling().priority() > 100)
    throw InputError("scheduling.priority: " + std::to_string(job.scheduling().priority()) + " (expected 1..100, or 0 for the default 1)");
  if (job.scheduling().max_workers() > 4096)
    throw InputError("scheduling.max_workers: " + std::to_string(job.scheduling().max_workers()) + " (expected 0..4096; 0: no cap)");
}

void forEachAssetRef(v1::JobSpec& job, const std::function<void(v1::AssetRef&, const std::string&)>& fn) {
  walkAssets(job, "", fn);
}

}  // namespace invr
