#include "core/diff/gradient_stats.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/reflection.h>

#include <stdexcept>

namespace invr {

namespace pb = google::protobuf;

void setRayCounts(v1::GradientStats& stats, const RayStats& rays) {
  v1::RayCounts* r = stats.mutable_rays();
  r->set_camera(rays.camera);
  r->set_shadow(rays.shadow);
  r->set_bounce(rays.bounce);
}

void setDropCounts(v1::GradientStats& stats, const SampleDrops& d) {
  v1::DropCounts* o = stats.mutable_drops();
  o->set_primal(d.primal);
  o->set_derivative(d.derivative);
  o->set_stage1(d.stage1);
  o->set_variance(d.variance);
  o->set_pixel_map(d.pixelMap);
  o->set_boundary(d.boundary);
}

namespace {

void addMessage(pb::Message& total, const pb::Message& part);

// Adds one scalar field of `part` into `total` (both the same message type).
void addScalar(pb::Message& total, const pb::Message& part, const pb::FieldDescriptor* f) {
  const pb::Reflection* rt = total.GetReflection();
  const pb::Reflection* rp = part.GetReflection();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_DOUBLE: rt->SetDouble(&total, f, rt->GetDouble(total, f) + rp->GetDouble(part, f)); break;
    case pb::FieldDescriptor::CPPTYPE_FLOAT: rt->SetFloat(&total, f, rt->GetFloat(total, f) + rp->GetFloat(part, f)); break;
    case pb::FieldDescriptor::CPPTYPE_UINT64: rt->SetUInt64(&total, f, rt->GetUInt64(total, f) + rp->GetUInt64(part, f)); break;
    case pb::FieldDescriptor::CPPTYPE_UINT32: rt->SetUInt32(&total, f, rt->GetUInt32(total, f) + rp->GetUInt32(part, f)); break;
    case pb::FieldDescriptor::CPPTYPE_INT64: rt->SetInt64(&total, f, rt->GetInt64(total, f) + rp->GetInt64(part, f)); break;
    case pb::FieldDescriptor::CPPTYPE_INT32: rt->SetInt32(&total, f, rt->GetInt32(total, f) + rp->GetInt32(part, f)); break;
    case pb::FieldDescriptor::CPPTYPE_MESSAGE: addMessage(*rt->MutableMessage(&total, f), rp->GetMessage(part, f)); break;
    default: throw std::logic_error("GradientStats." + f->full_name() + ": a statistic must be a number or a message of numbers");
  }
}

// Map fields are repeated entries (key = field 1, value = field 2): entries of `part` are added to
// the entry of `total` with the same key, or appended.
void addMap(pb::Message& total, const pb::Message& part, const pb::FieldDescriptor* f) {
  const pb::Reflection* rt = total.GetReflection();
  const pb::Reflection* rp = part.GetReflection();
  const pb::FieldDescriptor* key = f->message_type()->map_key();
  for (int i = 0; i < rp->FieldSize(part, f); ++i) {
    const pb::Message& entry = rp->GetRepeatedMessage(part, f, i);
    const std::string k = entry.GetReflection()->GetString(entry, key);
    pb::Message* target = nullptr;
    for (int j = 0; j < rt->FieldSize(total, f) && !target; ++j) {
      pb::Message* e = rt->MutableRepeatedMessage(&total, f, j);
      if (e->GetReflection()->GetString(*e, key) == k) target = e;
    }
    if (!target) {
      rt->AddMessage(&total, f)->CopyFrom(entry);
      continue;
    }
    addScalar(*target, entry, f->message_type()->map_value());
  }
}

void addMessage(pb::Message& total, const pb::Message& part) {
  const pb::Descriptor* d = total.GetDescriptor();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->is_map()) addMap(total, part, f);
    else if (f->is_repeated()) throw std::logic_error("GradientStats." + f->full_name() + ": a statistic is not a list");
    else addScalar(total, part, f);
  }
}

}  // namespace

void addGradientStats(v1::GradientStats& total, const v1::GradientStats& part) { addMessage(total, part); }

uint64_t droppedSamples(const v1::GradientStats& s) {
  const v1::DropCounts& d = s.drops();
  return d.primal() + d.derivative() + d.stage1() + d.variance() + d.pixel_map() + d.boundary();
}

double meanM(const v1::GradientStats& s) { return s.shading_points() ? s.sum_m() / double(s.shading_points()) : 0.0; }

double meanNeighbours(const v1::GradientStats& s) {
  return s.shading_points() ? double(s.neighbours_used()) / double(s.shading_points()) : 0.0;
}

}  // namespace invr
