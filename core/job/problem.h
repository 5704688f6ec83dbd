// An inverse-rendering problem built from a job: the scene (as ground truth), the parameters to
// recover with their starting point, the gradient settings and the optimiser. Validation errors
// name the job field at fault.
#pragma once

#include <memory>

#include "core/diff/gradient_engine.h"
#include "core/geometry/mesh_distance.h"
#include "core/job/optimizer_settings.h"
#include "core/render/renderer.h"
#include "core/scene/scene_builder.h"

namespace invr {

inline constexpr StreamId kTargetStream{5};       // ground-truth targets
inline constexpr StreamId kViewBatchStream{7};    // which views a step renders
inline constexpr StreamId kFinalRenderStream{8};  // renders of the result

struct Problem {
  std::unique_ptr<Scene> scene;
  ParameterRegistry params;
  std::vector<float> truth, initial;
  GradientOptions gradient;
  OptimizerKind optimizer = OptimizerKind::Adam;
  LearningRateSchedule schedule;
  int steps = 100;
  int viewsPerStep = 0;  // 0: all
  int burnIn = 0;
  int targetSpp = 256;
  uint64_t seed = 0;
  // Fixed partition of the views: each shard keeps its own reservoirs and is evaluated by one
  // worker (or, in process, in shard order), so results do not depend on the worker count.
  std::vector<std::vector<int>> shards;
  // Uploaded targets (one per view); empty: rendered from the truth and the parameter error is known.
  std::vector<Image> givenTargets;
  bool groundTruthKnown() const { return givenTargets.empty(); }
  // Per vertex parameter: the shape's own mesh, the truth that shape_error measures against and,
  // when the job starts from another mesh (initial_mesh), what its targets are rendered with.
  struct TruthMesh {
    size_t slot = 0;  // index into params.slots()
    uint32_t mesh = 0;
    TriangleMesh geometry;  // world space
    double diagonal = 0;    // of its bounding box
    bool replaced = false;  // the scene holds a start mesh instead
    std::shared_ptr<const SurfaceDistance> distance;  // to the geometry, built once
  };
  std::vector<TruthMesh> truthMeshes;
};

// One evaluation of a job: burn-in evaluations come first, then one per gradient step. The
// counter indexes the random streams, so burn-in and gradient steps never share one.
struct Evaluation {
  uint64_t counter = 0;
  bool renderOnly = false;
  std::vector<int> views;  // the mini-batch
};
Evaluation evaluationAt(const Problem& problem, uint64_t counter);

// The request shard `shard` evaluates for an evaluation (views empty: the shard sits this one out).
GradientRequest shardRequest(const Problem& problem, const Evaluation& e, size_t shard);

// Built once per process that needs it: SceneUse::Validate where nothing is traced (client
// checks, plan, server), Render (with the BVH) in workers and in-process runs.
Problem buildProblem(const invr::v1::JobSpec& job, const AssetResolver& assets = {}, SceneUse use = SceneUse::Render);

// The job's light transport for forward renders: targets, final renders and the image-error
// meter all render through it, so they show what the gradients differentiate (optimization.
// max_depth vertices; direct illumination with visibility-aware RIS over 16 candidates, longer
// paths with NEE + MIS), on random stream `stream` of the job.
RenderOptions transportRenderOptions(const Problem& problem, int spp, StreamId stream);

// Ground-truth targets: the truth rendered through the job's transport at target_spp.
// Uploaded targets are returned as given.
std::vector<Image> renderTargets(Problem& problem);
RenderOptions targetRenderOptions(const Problem& problem);  // how targets are rendered
// `cancel` (optional) is checked every 256 samples of a pixel: raised, the render throws
// EvaluationCancelled.
Image renderTarget(Problem& problem, int view, const std::atomic<bool>* cancel = nullptr);

// Jobs with vertex parameters and a known truth: the symmetric mean chamfer distance of each
// parameter's mesh to its truth over the truth's bounding-box diagonal, averaged over them; -1
// otherwise (core/geometry/mesh_distance.h).
double shapeError(const Problem& problem, const std::vector<float>& theta);

// RMS distance of theta to the truth over the parameters that have one (not sampling/..., nor the
// vertices of a shape started from another mesh); -1 when none does.
double parameterError(const Problem& problem, const std::vector<float>& theta);

// The views of step `step`: a deterministic mini-batch (a seeded shuffle per step) or all views.
std::vector<int> viewsForStep(const Problem& problem, uint64_t step);

}  // namespace invr
