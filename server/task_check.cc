#include "server/task_check.h"

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <cmath>

namespace invr::server {

namespace {

constexpr size_t kMaxErrorBytes = 64 * 1024;
constexpr int kMaxChannels = 4;

bool finiteNonNegative(double v) { return std::isfinite(v) && v >= 0.0; }

namespace pb = google::protobuf;

// Every number of a statistics message: timings, costs and sums of M are finite and >= 0 (the
// loss and its terms may be anything: a non-finite loss is how divergence shows), maps hold few
// entries with short names.
std::string checkStats(const pb::Message& m, int depth = 0) {
  const pb::Descriptor* d = m.GetDescriptor();
  const pb::Reflection* r = m.GetReflection();
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->is_map()) {
      if (r->FieldSize(m, f) > 64) return "statistics '" + f->name() + "' has " + std::to_string(r->FieldSize(m, f)) + " entries (limit 64)";
      for (int k = 0; k < r->FieldSize(m, f); ++k) {
        const pb::Message& e = r->GetRepeatedMessage(m, f, k);
        if (e.GetReflection()->GetString(e, f->message_type()->map_key()).size() > 64) return "a statistics name is longer than 64 bytes";
        if (depth < 4) {
          std::string bad = checkStats(e, depth + 1);
          if (!bad.empty()) return bad;
        }
      }
    } else if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE && !f->is_repeated()) {
      if (depth < 4) {
        std::string bad = checkStats(r->GetMessage(m, f), depth + 1);
        if (!bad.empty()) return bad;
      }
    } else if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_DOUBLE && !f->is_repeated()) {
      const std::string& n = f->name();
      if (n == "loss" || n == "bias_term" || n == "variance_term") continue;
      if (!finiteNonNegative(r->GetDouble(m, f))) return "statistic '" + n + "' is negative or not finite";
    }
  }
  return "";
}

}  // namespace

std::string checkTaskResult(const v1::Task& task, const v1::TaskResult& r, const ResultShape& shape) {
  if (r.task_id() != task.task_id()) return "answers task " + std::to_string(r.task_id()) + ", not " + std::to_string(task.task_id());
  if (r.job_id() != task.job_id()) return "names job '" + r.job_id().substr(0, 64) + "', the task is for " + task.job_id();
  if (r.shard() != task.shard()) return "names shard " + std::to_string(r.shard()) + ", the task is for shard " + std::to_string(task.shard());
  if (r.error().size() > kMaxErrorBytes) return "error text of " + std::to_string(r.error().size()) + " bytes (limit 65536)";
  if (!r.error().empty()) return "";  // a failed task: its error is reported, nothing else is read
  if (r.spec_unknown()) return "";    // the spec is sent again; nothing else is read
  if (r.input_error()) return "input_error set without an error text";
  if (!finiteNonNegative(r.seconds_session())) return "a timing is negative or not finite";
  if (std::string bad = checkStats(r.stats()); !bad.empty()) return bad;
  if (task.kind() == v1::Task::FINAL_RENDER || task.kind() == v1::Task::SNAPSHOT) {
    const bool snapshot = task.kind() == v1::Task::SNAPSHOT;
    if (r.gradient_size() != 0) return "a final render carries a gradient";
    // A final render: each view's render, then its target; a snapshot: the renders alone, or
    // with the targets when asked for them (a worker without the shard's session has none).
    const int expected = (snapshot ? 1 : 2) * task.views_size();
    const bool withTargets = snapshot && task.with_targets() && r.renders_size() == 2 * task.views_size();
    if (r.renders_size() != expected && !withTargets)
      return std::to_string(r.renders_size()) + " images for " + std::to_string(task.views_size()) + " view(s) (expected " +
             std::to_string(expected) + ")";
    // Variance-aware jobs add one variance map per view.
    if (r.variances_size() != 0 && (snapshot || r.variances_size() != task.views_size()))
      return std::to_string(r.variances_size()) + " variance maps for " + std::to_string(task.views_size()) + " view(s)";
    for (int k = 0; k < r.renders_size() + r.variances_size(); ++k) {
      const v1::FloatImage& im = k < r.renders_size() ? r.renders(k) : r.variances(k - r.renders_size());
      if (im.width() != shape.width || im.height() != shape.height)
        return "image " + std::to_string(k) + " is " + std::to_string(im.width()) + "x" + std::to_string(im.height()) + ", the film is " +
               std::to_string(shape.width) + "x" + std::to_string(shape.height);
      if (im.channels() < 1 || im.channels() > kMaxChannels)
        return "image " + std::to_string(k) + " has " + std::to_string(im.channels()) + " channels (1 to 4)";
      const uint64_t values = uint64_t(shape.width) * uint64_t(shape.height) * uint64_t(im.channels());
      if (uint64_t(im.pixels_size()) != values)
        return "image " + std::to_string(k) + " has " + std::to_string(im.pixels_size()) + " values, expected " + std::to_string(values);
    }
    return "";
  }
  if (task.kind() != v1::Task::GRADIENT) return "answers a task of unknown kind";
  // Render-only (burn-in) steps may return no gradient; every other step one value per parameter.
  if (size_t(r.gradient_size()) != shape.parameters && !(task.render_only() && r.gradient_size() == 0))
    return "gradient has " + std::to_string(r.gradient_size()) + " values, the job has " + std::to_string(shape.parameters) + " parameters";
  if (r.renders_size() != 0 || r.variances_size() != 0) return "a gradient result carries images";
  // A non-finite gradient or loss is not malformed: it is how divergence shows, and the step
  // loop's divergence check fails the job naming the parameter.
  return "";
}

}  // namespace invr::server
