#include "proto/wire/json_lines.h"

#include <google/protobuf/descriptor.h>

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <nlohmann/json.hpp>

namespace invr::wire {

namespace {

namespace pb = google::protobuf;
using json = nlohmann::ordered_json;

json number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// A float printed at float precision ("0.1", not "0.10000000149011612").
json number(float v) {
  if (!std::isfinite(v)) return nullptr;
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  *r.ptr = '\0';
  return json(std::strtod(buf, nullptr));
}

std::string base64(const std::string& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned n = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8 | (unsigned char)in[i + 2];
    out += {k[n >> 18], k[(n >> 12) & 63], k[(n >> 6) & 63], k[n & 63]};
  }
  if (i + 1 == in.size()) {
    const unsigned n = (unsigned char)in[i] << 16;
    out += {k[n >> 18], k[(n >> 12) & 63], '=', '='};
  } else if (i + 2 == in.size()) {
    const unsigned n = (unsigned char)in[i] << 16 | (unsigned char)in[i + 1] << 8;
    out += {k[n >> 18], k[(n >> 12) & 63], k[(n >> 6) & 63], '='};
  }
  return out;
}

json message(const pb::Message& m);

json single(const pb::Message& m, const pb::FieldDescriptor* f) {
  const pb::Reflection* r = m.GetReflection();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_INT32: return r->GetInt32(m, f);
    case pb::FieldDescriptor::CPPTYPE_INT64: return r->GetInt64(m, f);
    case pb::FieldDescriptor::CPPTYPE_UINT32: return r->GetUInt32(m, f);
    case pb::FieldDescriptor::CPPTYPE_UINT64: return r->GetUInt64(m, f);
    case pb::FieldDescriptor::CPPTYPE_DOUBLE: return number(r->GetDouble(m, f));
    case pb::FieldDescriptor::CPPTYPE_FLOAT: return number(r->GetFloat(m, f));
    case pb::FieldDescriptor::CPPTYPE_BOOL: return r->GetBool(m, f);
    case pb::FieldDescriptor::CPPTYPE_ENUM: {
      const pb::EnumValueDescriptor* v = r->GetEnum(m, f);
      return v->name();
    }
    case pb::FieldDescriptor::CPPTYPE_STRING: {
      const std::string s = r->GetString(m, f);
      return f->type() == pb::FieldDescriptor::TYPE_BYTES ? base64(s) : s;
    }
    case pb::FieldDescriptor::CPPTYPE_MESSAGE: return message(r->GetMessage(m, f));
  }
  return nullptr;
}

json element(const pb::Message& m, const pb::FieldDescriptor* f, int i) {
  const pb::Reflection* r = m.GetReflection();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_INT32: return r->GetRepeatedInt32(m, f, i);
    case pb::FieldDescriptor::CPPTYPE_INT64: return r->GetRepeatedInt64(m, f, i);
    case pb::FieldDescriptor::CPPTYPE_UINT32: return r->GetRepeatedUInt32(m, f, i);
    case pb::FieldDescriptor::CPPTYPE_UINT64: return r->GetRepeatedUInt64(m, f, i);
    case pb::FieldDescriptor::CPPTYPE_DOUBLE: return number(r->GetRepeatedDouble(m, f, i));
    case pb::FieldDescriptor::CPPTYPE_FLOAT: return number(r->GetRepeatedFloat(m, f, i));
    case pb::FieldDescriptor::CPPTYPE_BOOL: return r->GetRepeatedBool(m, f, i);
    case pb::FieldDescriptor::CPPTYPE_ENUM: return r->GetRepeatedEnum(m, f, i)->name();
    case pb::FieldDescriptor::CPPTYPE_STRING: {
      const std::string s = r->GetRepeatedString(m, f, i);
      return f->type() == pb::FieldDescriptor::TYPE_BYTES ? base64(s) : s;
    }
    case pb::FieldDescriptor::CPPTYPE_MESSAGE: return message(r->GetRepeatedMessage(m, f, i));
  }
  return nullptr;
}

json message(const pb::Message& m) {
  json o = json::object();
  const pb::Descriptor* d = m.GetDescriptor();
  const pb::Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->is_map()) {
      json obj = json::object();
      const pb::FieldDescriptor* kf = f->message_type()->map_key();
      const pb::FieldDescriptor* vf = f->message_type()->map_value();
      for (int k = 0; k < r->FieldSize(m, f); ++k) {
        const pb::Message& entry = r->GetRepeatedMessage(m, f, k);
        const json key = single(entry, kf);
        obj[key.is_string() ? key.get<std::string>() : key.dump()] = single(entry, vf);
      }
      o[f->name()] = std::move(obj);
    } else if (f->is_repeated()) {
      json arr = json::array();
      for (int k = 0; k < r->FieldSize(m, f); ++k) arr.push_back(element(m, f, k));
      o[f->name()] = std::move(arr);
    } else if (!f->has_presence() || r->HasField(m, f)) {  // unset messages, oneof members and optionals are left out
      o[f->name()] = single(m, f);
    }
  }
  return o;
}

}  // namespace

std::string jsonLine(const pb::Message& m) { return message(m).dump(-1, ' ', false, json::error_handler_t::replace); }

}  // namespace invr::wire
