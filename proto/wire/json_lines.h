// Messages as the JSON that scripts read (`--json` output, progress.jsonl): every number a JSON
// number (int64 too, where protobuf's own printer writes strings), non-finite values null, enums
// by name, field names as in the .proto files, scalar fields always present (zero counters too).
// protobuf's JSON parser reads it back (null as the field's default).
#pragma once

#include <google/protobuf/message.h>

#include <string>

namespace invr::wire {

// One line, no trailing newline.
std::string jsonLine(const google::protobuf::Message& m);

}  // namespace invr::wire
