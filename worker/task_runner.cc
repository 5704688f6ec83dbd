#include "worker/task_runner.h"

#include <spdlog/spdlog.h>

#include <algorithm>

#include "core/error.h"
#include "core/render/renderer.h"
#include "core/stopwatch.h"

namespace invr::worker {

namespace v1 = invr::v1;

namespace {

void toProto(const Image& im, v1::FloatImage* out) {
  out->set_width(im.width());
  out->set_height(im.height());
  out->set_channels(im.channels());
  out->mutable_pixels()->Assign(im.data().begin(), im.data().end());
}

std::vector<float> thetaOf(const v1::Task& t, const Problem& p) {
  std::vector<float> theta(t.theta().begin(), t.theta().end());
  if (theta.size() != p.params.size())
    throw InputError("task: theta has " + std::to_string(theta.size()) + " values, the job " + std::to_string(p.params.size()));
  return theta;
}

}  // namespace

Session& TaskRunner::session(const v1::Task& t, const v1::JobSpec& spec, v1::TaskResult& res) {
  if (Session* s = sessions_.find(t.job_id(), t.shard())) return *s;
  Stopwatch clock;
  Session s;
  s.problem = std::make_unique<Problem>(buildProblem(spec, assets_.resolver()));
  Problem& p = *s.problem;
  if (t.shard() >= p.shards.size()) throw InputError("task: shard " + std::to_string(t.shard()) + " out of range");
  s.targets.resize(p.scene->cameras.size());
  for (int v : p.shards[t.shard()]) {
    if (cancel_) throw EvaluationCancelled{};
    s.targets[size_t(v)] = renderTarget(p, v, &cancel_);
  }
  s.engine = std::make_unique<GradientEngine>(*p.scene, p.params, s.targets, p.gradient);
  // Taking over a shard mid-job: rebuild the reservoirs with render-only steps at the current
  // parameters, on random streams of their own (top bit set) so no step's stream is reused.
  if (t.counter() > 0 && t.rebuild_burn_in() > 0) {
    p.params.write(thetaOf(t, p), *p.scene);  // the session's one writer, between passes
    for (uint32_t k = 0; k < t.rebuild_burn_in(); ++k) {
      GradientRequest r;
      r.views = p.shards[t.shard()];
      r.step = (uint64_t(1) << 63) | (t.counter() << 16) | k;
      r.seed = p.seed;
      r.renderOnly = true;
      r.allSessionViews = true;
      r.cancel = &cancel_;
      s.engine->evaluate(r, s.state);
    }
  }
  res.set_rebuilt(true);
  res.set_seconds_session(clock.seconds());
  return sessions_.insert(t.job_id(), t.shard(), std::move(s));
}

std::optional<v1::WorkerMessage> TaskRunner::execute(const v1::Task& t) {
  v1::WorkerMessage out;
  v1::TaskResult& res = *out.mutable_result();
  res.set_task_id(t.task_id());
  res.set_job_id(t.job_id());
  res.set_shard(t.shard());
  try {
    const v1::JobSpec* spec = specs_.specFor(t);
    if (!spec) {
      res.set_spec_unknown(true);
      return out;
    }
    if (t.kind() != v1::Task::GRADIENT && t.kind() != v1::Task::FINAL_RENDER && t.kind() != v1::Task::SNAPSHOT)
      throw InputError("task kind " + std::to_string(int(t.kind())) + " is not known to this worker: run workers of the server's version");
    if (t.kind() == v1::Task::SNAPSHOT) {
      // A snapshot leaves the sessions as they are: without the shard's session, it renders from
      // a scene of its own, so that no session starts without its rebuild burn-in. With it, the
      // scene gets the theta the next gradient task writes anyway (an unchanged write is a no-op).
      std::unique_ptr<Problem> own;
      Session* existing = sessions_.find(t.job_id(), t.shard());
      if (!existing) own = std::make_unique<Problem>(buildProblem(*spec, assets_.resolver()));
      Problem& p = existing ? *existing->problem : *own;
      p.params.write(thetaOf(t, p), *p.scene);
      RenderOptions ro = transportRenderOptions(p, std::max(1, t.final_spp()), kFinalRenderStream);
      ro.cancel = &cancel_;
      for (int v : t.views()) {
        if (v < 0 || size_t(v) >= p.scene->cameras.size()) throw InputError("task: view " + std::to_string(v) + " out of range");
        toProto(renderView(*p.scene, v, ro).image, res.add_renders());
      }
      // The targets beside them when asked (the dashboard shows both) and the session holds them.
      if (existing && t.with_targets())
        for (int v : t.views())
          if (size_t(v) < existing->targets.size()) toProto(existing->targets[size_t(v)], res.add_renders());
      return out;
    }
    Session& s = session(t, *spec, res);
    Problem& p = *s.problem;
    const std::vector<float> theta = thetaOf(t, p);
    if (t.kind() == v1::Task::FINAL_RENDER) {
      p.params.write(theta, *p.scene);
      RenderOptions ro = transportRenderOptions(p, std::max(1, t.final_spp()), kFinalRenderStream);
      ro.cancel = &cancel_;
      for (int v : t.views()) toProto(renderView(*p.scene, v, ro).image, res.add_renders());
      for (int v : t.views()) toProto(s.targets.at(size_t(v)), res.add_renders());
      if (p.gradient.variance.enabled)
        for (int v : t.views()) toProto(s.engine->sampleVarianceMap(v, std::max(2, t.final_spp()), p.seed, &cancel_), res.add_variances());
      return out;
    }
    GradientRequest r;
    r.views.assign(t.views().begin(), t.views().end());
    r.step = t.counter();
    r.seed = p.seed;
    r.renderOnly = t.render_only();
    r.batchViews = int(t.batch_views());
    r.allSessionViews = t.all_shard_views();
    r.cancel = &cancel_;
    p.params.write(theta, *p.scene);  // between tasks: nothing renders now
    GradientResult g = s.engine->evaluate(r, s.state);
    res.mutable_gradient()->Assign(g.gradient.begin(), g.gradient.end());
    *res.mutable_stats() = std::move(g.stats);
  } catch (const EvaluationCancelled&) {
    sessions_.erase(t.job_id(), t.shard());
    spdlog::info("worker {}: task {} of {} cancelled", name_, t.task_id(), t.job_id());
    return std::nullopt;
  } catch (const InputError& e) {
    res.set_error(e.what());
    res.set_input_error(true);
  } catch (const std::exception& e) {
    res.set_error(e.what());
    sessions_.erase(t.job_id(), t.shard());
  }
  return out;
}

}  // namespace invr::worker
