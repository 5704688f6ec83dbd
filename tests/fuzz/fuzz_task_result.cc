// fuzz_task_result: a worker's TaskResult as the server receives it (binary protobuf), checked by
// checkTaskResult against fixed tasks; a result the check passes is then used the way the server
// uses it (server/server.cc): its gradient added element-wise into the step's sum, its images'
// pixels copied into film-sized images. If the check is right, nothing here can go out of bounds.
#include <google/protobuf/stubs/logging.h>

#include <algorithm>
#include <climits>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <string>
#include <vector>

#include "core/diff/gradient_stats.h"
#include "core/image/image.h"
#include "invr/v1/service.pb.h"
#include "server/task_check.h"
#include "tests/fuzz/fuzz_common.h"

namespace {

using invr::v1::Task;
using invr::v1::TaskResult;

// The job of tests/fuzz/make_seeds.py's TaskResult seeds: 12 parameters, an 8 x 6 film.
const invr::server::ResultShape kShape{12, 8, 6};

Task makeTask(uint64_t id, Task::Kind kind, uint32_t shard, std::initializer_list<int> views, bool renderOnly = false) {
  Task t;
  t.set_task_id(id);
  t.set_job_id("job-000001");
  t.set_kind(kind);
  t.set_shard(shard);
  for (int v : views) t.add_views(v);
  t.set_batch_views(2);
  t.set_render_only(renderOnly);
  return t;
}

const std::vector<Task>& tasks() {
  static const std::vector<Task> all = {
      makeTask(1, Task::GRADIENT, 0, {0, 1}),
      makeTask(2, Task::GRADIENT, 1, {1}, /*renderOnly=*/true),
      makeTask(3, Task::FINAL_RENDER, 0, {0}),
  };
  return all;
}

// What the server does with a result that passed the check.
void use(const Task& task, const TaskResult& r) {
  // A failed task (its error text is reported) or a worker without the job's spec (the server
  // sends the spec again): nothing else of the result is read.
  if (!r.error().empty() || r.spec_unknown()) {
    invr::fuzz::accepted(r.spec_unknown() ? "spec unknown" : "error result: " + r.error().substr(0, 60));
    return;
  }
  if (task.kind() == Task::GRADIENT) {
    if (task.render_only()) return;  // burn-in: the server reads nothing of it
    std::vector<double> sum(kShape.parameters, 0.0);
    for (int i = 0; i < r.gradient_size(); ++i) sum[size_t(i)] += r.gradient(i);
    invr::v1::GradientStats stats;
    invr::addGradientStats(stats, r.stats());  // the server sums shards' statistics
    invr::fuzz::accepted("gradient of " + std::to_string(r.gradient_size()));
    return;
  }
  const int nv = task.views_size();
  for (int k = 0; k < r.renders_size(); ++k) {
    FUZZ_CHECK(k < 2 * nv, std::to_string(r.renders_size()) + " images for " + std::to_string(nv) + " views");
    const invr::v1::FloatImage& fi = r.renders(k);
    FUZZ_CHECK(fi.width() == kShape.width && fi.height() == kShape.height, "image size differs from the film");
    invr::Image im(fi.width(), fi.height(), fi.channels());
    std::copy(fi.pixels().begin(), fi.pixels().end(), im.data().begin());
    FUZZ_CHECK(size_t(fi.pixels_size()) == im.data().size(), "pixels short of the image");
    std::string stem = (k < nv ? "final_view" : "target_view") + std::to_string(task.views(k % nv));
    (void)stem;
  }
  invr::fuzz::accepted(std::to_string(r.renders_size()) + " images");
}

}  // namespace

// protobuf logs every string field with invalid UTF-8 it parses (an expected outcome here) to
// stderr: quiet, so that the log shows the findings.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  google::protobuf::SetLogHandler(nullptr);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size > size_t(INT_MAX)) return 0;
  TaskResult r;
  if (!r.ParseFromArray(data, int(size))) return 0;
  for (const Task& t : tasks()) {
    const std::string why = invr::server::checkTaskResult(t, r, kShape);
    if (why.empty())
      use(t, r);
    else if (invr::fuzz::verbose())
      std::fprintf(stderr, "task %llu: %s\n", static_cast<unsigned long long>(t.task_id()), why.c_str());
  }
  return 0;
}
