#include "core/io/job_json_normalize.h"

#include <nlohmann/json.hpp>

#include <cctype>
#include <vector>

#include "core/io/suggest.h"

namespace invr {

namespace {

namespace pb = google::protobuf;
using nlohmann::json;

struct FieldFailure {
  JsonFieldError error;
};

std::string upper(std::string s) {
  for (char& c : s) c = c == '-' ? '_' : char(std::toupper(static_cast<unsigned char>(c)));
  return s;
}
std::string lower(std::string s) {
  for (char& c : s) c = char(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// The prefix every value of an enum shares up to an underscore ("METHOD_"), which the short
// form leaves out.
std::string commonPrefix(const pb::EnumDescriptor* e) {
  std::string p = e->value(0)->name();
  for (int i = 1; i < e->value_count(); ++i) {
    const std::string& n = e->value(i)->name();
    size_t k = 0;
    while (k < p.size() && k < n.size() && p[k] == n[k]) ++k;
    p.resize(k);
  }
  const size_t us = p.rfind('_');
  return us == std::string::npos ? "" : p.substr(0, us + 1);
}

// The forms a user may write: the proto's names without the shared prefix, lower case; the
// unspecified default is left out.
std::vector<std::string> shortForms(const pb::EnumDescriptor* e) {
  const std::string prefix = commonPrefix(e);
  std::vector<std::string> out;
  for (int i = 0; i < e->value_count(); ++i)
    if (e->value(i)->number() != 0) out.push_back(lower(e->value(i)->name().substr(prefix.size())));
  return out;
}

std::string joined(const std::vector<std::string>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + v[i];
  return s;
}

std::string kindOf(const pb::FieldDescriptor* f) {
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_MESSAGE: return "object ({...})";
    case pb::FieldDescriptor::CPPTYPE_STRING: return "string";
    case pb::FieldDescriptor::CPPTYPE_BOOL: return "true or false";
    case pb::FieldDescriptor::CPPTYPE_ENUM: return "name";
    default: return "number";
  }
}

class Normalizer {
 public:
  void message(json& obj, const pb::Descriptor* d, const std::string& path) {
    if (d->full_name().rfind("google.protobuf.", 0) == 0) return;  // well-known types: protobuf's own rules
    if (!obj.is_object()) return;
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      const std::string& key = it.key();
      const pb::FieldDescriptor* f = d->FindFieldByName(key);
      if (!f) f = d->FindFieldByCamelcaseName(key);
      const std::string at = path.empty() ? key : path + "." + key;
      if (!f) {
        std::vector<std::string> names;
        for (int i = 0; i < d->field_count(); ++i) names.push_back(d->field(i)->name());
        fail(at, key, "unknown field" + didYouMean(key, names));
      }
      json& v = it.value();
      if (v.is_null()) continue;
      if (f->is_map()) {
        if (!v.is_object()) fail(at, key, "expects an object of names to values ({...})");
        const pb::FieldDescriptor* valueField = f->message_type()->map_value();
        for (auto mv = v.begin(); mv != v.end(); ++mv) value(mv.value(), valueField, at + "[\"" + mv.key() + "\"]", key);
      } else if (f->is_repeated()) {
        if (!v.is_array()) fail(at, key, "expects a list ([...]) of " + kindOf(f) + (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE ? "s" : "s") + ", got a single value");
        for (size_t i = 0; i < v.size(); ++i) value(v[i], f, at + "[" + std::to_string(i) + "]", key);
      } else {
        if (v.is_array()) {
          std::string hint;
          for (const std::string& plural : {key + "_values", key + "s"})
            if (const auto* g = d->FindFieldByName(plural); g && g->is_repeated()) hint = "; a list goes in '" + plural + "'";
          fail(at, key, "expects a single " + kindOf(f) + ", not a list" + hint);
        }
        value(v, f, at, key);
      }
    }
  }

 private:
  [[noreturn]] void fail(const std::string& path, const std::string& key, const std::string& message) {
    throw FieldFailure{JsonFieldError{path, key, message}};
  }

  void value(json& v, const pb::FieldDescriptor* f, const std::string& path, const std::string& key) {
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      if (!v.is_object() && !v.is_null() && f->message_type()->full_name().rfind("google.protobuf.", 0) != 0)
        fail(path, key, "expects an object ({...})");
      message(v, f->message_type(), path);
    } else if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_ENUM && v.is_string()) {
      const pb::EnumDescriptor* e = f->enum_type();
      const std::string given = v.get<std::string>();
      if (e->FindValueByName(given)) return;
      const std::string u = upper(given);
      const pb::EnumValueDescriptor* match = nullptr;
      int matches = 0;
      for (int i = 0; i < e->value_count() && !u.empty(); ++i) {
        const std::string& n = e->value(i)->name();
        if (n == u || (n.size() > u.size() && n.compare(n.size() - u.size(), u.size(), u) == 0 && n[n.size() - u.size() - 1] == '_')) {
          match = e->value(i);
          ++matches;
        }
      }
      if (matches == 1) {
        v = match->name();
        return;
      }
      const auto forms = shortForms(e);
      fail(path, key, "'" + given + "' is not a valid value; use one of: " + joined(forms) + didYouMean(given, forms));
    }
  }
};

}  // namespace

bool normalizeJobJson(const std::string& text, const pb::Descriptor* type, std::string& out, JsonFieldError& error, std::string& syntaxLineCol) {
  json doc;
  try {
    doc = json::parse(text);
  } catch (const json::parse_error& e) {
    // nlohmann's message: "[json.exception.parse_error.101] parse error at line 3, column 1: syntax
    // error while parsing object - unexpected end of input; expected '}'". Keep the last part.
    std::string what = e.what();
    const size_t colon = what.find(": ");
    error.message = "JSON syntax error: " + (colon == std::string::npos ? what : what.substr(colon + 2));
    size_t line = 1, col = 1;
    for (size_t i = 0; i + 1 < e.byte && i < text.size(); ++i) {
      if (text[i] == '\n') {
        ++line;
        col = 1;
      } else {
        ++col;
      }
    }
    syntaxLineCol = std::to_string(line) + ":" + std::to_string(col);
    return false;
  } catch (const json::exception& e) {  // out_of_range: a number beyond a double ("2e308")
    std::string what = e.what();
    const size_t bracket = what.find("] ");
    error.message = "JSON number out of range: " + (bracket == std::string::npos ? what : what.substr(bracket + 2));
    return false;
  }
  if (!doc.is_object()) {
    error.message = "a job is a JSON object ({...})";
    return false;
  }
  try {
    Normalizer().message(doc, type, "");
  } catch (const FieldFailure& f) {
    error = f.error;
    return false;
  }
  try {
    out = doc.dump();
  } catch (const json::type_error&) {
    error.message = "a string is not valid UTF-8";
    return false;
  }
  return true;
}

}  // namespace invr
