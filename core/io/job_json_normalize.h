// A job's JSON read as a person writes it, before protobuf's parser sees it: enum values in their
// short form ("restir", "pt", "edge_first") become the proto's names, and mistakes protobuf would
// describe in its own words (an unknown field, a list where one value goes, an enum value that
// does not exist) are reported with the field's path, the valid choices and the closest names.
#pragma once

#include <google/protobuf/descriptor.h>

#include <string>

namespace invr {

struct JsonFieldError {
  std::string path;     // "optimization.parameters[0].initial"
  std::string key;      // the JSON key at fault, to locate it in the text ("initial")
  std::string message;  // "a single number, not a list; per-value starts go in 'initial_values'"
};

// Parses `json` and rewrites it for `type`. Syntax errors come back with their line and column
// in `syntaxLineCol` ("3:17") and `error.message`; field errors in `error`. Returns true and
// sets `out` (compact JSON) when the text is well formed and every field is known.
bool normalizeJobJson(const std::string& json, const google::protobuf::Descriptor* type, std::string& out, JsonFieldError& error,
                      std::string& syntaxLineCol);

}  // namespace invr
