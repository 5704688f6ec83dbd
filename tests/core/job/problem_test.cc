// Inverse problems from job JSON: every mistake names the field; mini-batches are deterministic.
#include "core/job/problem.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "core/job/plan.h"
#include "core/job/zoo_jobs.h"
#include "core/error.h"
#include "core/io/job_io.h"
#include "core/image/image.h"
#include "core/scene/zoo.h"

namespace invr {
namespace {

std::string errorOf(const std::string& optimizationJson) {
  try {
    auto job = parseJobJson(R"({"zoo": "cornell", "optimization": )" + optimizationJson + "}", "job.json");
    buildProblem(job);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_MENTIONS(err, part) EXPECT_NE((err).find(part), std::string::npos) << "error was: " << (err)

TEST(Problem, JobMistakesNameTheField) {
  EXPECT_MENTIONS(errorOf(R"({})"), "optimization.parameters: list at least one");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/wood/albedo"}]})"),
                  "optimization.parameters[0].name: parameter 'materials/wood/albedo': no material named 'wood'");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial": "NaN"}]})"),
                  "optimization.parameters[0].initial: must be a finite number");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial": 1.5}]})"),
                  "optimization.parameters[0].initial: outside the bounds");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "lower": 0.9, "upper": 0.1}]})"),
                  "bounds are inverted");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "learning_rate": -1}]})"), "learning rate");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "steps": -5})"), "optimization.steps");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "loss": "l7"})"), "optimization.loss");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "optimizer": "lbfgs"})"), "optimization.optimizer");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "learning_rate_half_life": -3})"),
                  "optimization.learning_rate_half_life: must be a finite number of steps >= 0");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "learning_rate_half_life": "Infinity"})"),
                  "optimization.learning_rate_half_life");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "views_per_step": 3})"),
                  "optimization.views_per_step: must be in 1..1");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "restir": {"radius_pixels": -2}})"),
                  "optimization.restir.radius_pixels");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial": 0.3}]})"), "");
}

TEST(Problem, ShapeJobsSayWhatTheyCannotDo) {
  // The Cornell box's blocks stand on its floor: accepted only with the bias acknowledged (below).
  // Accepted then with pt, ris and restir (with or without the shortcut); the rest refused, saying why.
  const std::string allow = R"("boundary": {"allow_unsampled_discontinuities": true})";
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "method": "METHOD_PT", )" + allow + "}"), "");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], )" + allow + "}"), "");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"multi_view_shortcut": true, "allow_unsampled_discontinuities": true}})"), "");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "method": "METHOD_PT", "max_depth": 3})"),
                  "optimization.parameters: shape parameters: the interior shape derivative covers direct illumination only");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "method": "METHOD_PT", "pixel_sampler": "uniform"})"),
                  "pixel_sampler all");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "method": "METHOD_PT", "boundary": {"samples": -1}})"),
                  "optimization.boundary.samples");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"edge_neighbours": 9}})"),
                  "optimization.boundary.edge_neighbours");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"area_sampling": "AREA_SAMPLING_LIGHT_POINTS",
                    "edge_importance": false, "edge_neighbours": 3, "allow_unsampled_discontinuities": true}})"), "");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/nope/translation"}]})"), "no shape named 'nope'");
  // Each term's own message, under its registered name.
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"terms": {"area_shadows_edge_first": {"edge_neighbours": 9}}}})"),
                  "optimization.boundary.terms.area_shadows_edge_first.edge_neighbours: must be in 0..8");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"terms": {"primary": {"samples": -4}}}})"),
                  "optimization.boundary.terms.primary.samples");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"terms": {"environment_shadows": {"directions": 5000}}}})"),
                  "optimization.boundary.terms.environment_shadows.directions");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"terms": {"area_shadows_light_points": {"light_points": -1}}}})"),
                  "optimization.boundary.terms.area_shadows_light_points.light_points");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"terms": {"silhouettes": {}}}})"), "silhouettes");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}], "boundary": {"allow_unsampled_discontinuities": true, "terms": {
                    "primary": {"samples": 512, "terminators": false}, "delta_shadows": {"enabled": false},
                    "area_shadows_edge_first": {"edge_importance": false, "edge_neighbours": 2}}}})"), "");
}

// Each pixel sampler's own options: named when wrong, refused for a sampler the job does not use.
TEST(Problem, PixelSamplerOptionsNameTheirField) {
  const std::string albedo = R"({"parameters": [{"name": "materials/red/albedo"}], )";
  EXPECT_EQ(errorOf(albedo + R"("pixel_sampler": "adaptive", "pixel_samplers": {"adaptive": {"levels": 2, "stage1_stride": 4, "defensive": 0.5, "refresh": 5, "samples": 100}}})"), "");
  EXPECT_MENTIONS(errorOf(albedo + R"("pixel_sampler": "adaptive", "pixel_samplers": {"adaptive": {"levels": 9}}})"),
                  "optimization.pixel_samplers.adaptive.levels: must be in 1..8");
  EXPECT_MENTIONS(errorOf(albedo + R"("pixel_sampler": "loss_grad", "pixel_samplers": {"loss_grad": {"defensive": 1.5}}})"),
                  "optimization.pixel_samplers.loss_grad.defensive");
  EXPECT_MENTIONS(errorOf(albedo + R"("pixel_sampler": "loss_grad", "pixel_samplers": {"loss_grad": {"stage1_stride": 17}}})"),
                  "optimization.pixel_samplers.loss_grad.stage1_stride");
  EXPECT_MENTIONS(errorOf(albedo + R"("pixel_sampler": "uniform", "pixel_samplers": {"uniform": {"samples": -3}}})"),
                  "optimization.pixel_samplers.uniform.samples");
  EXPECT_MENTIONS(errorOf(albedo + R"("pixel_sampler": "uniform", "pixel_samplers": {"adaptive": {"levels": 2}}})"),
                  "optimization.pixel_samplers.adaptive: options of a sampler the job does not use (pixel_sampler is 'uniform')");
  EXPECT_MENTIONS(errorOf(albedo + R"("pixel_samplers": {"uniform": {"samples": 10}}})"), "pixel_sampler is 'all'");
}

// Vertex parameters and Large Steps: each mistake names its field.
TEST(Problem, VertexParameterMistakesNameTheField) {
  const std::string allow = R"(, "boundary": {"allow_unsampled_discontinuities": true})";
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "shapes/tall_box/vertices", "large_steps_lambda": 10}], "optimizer": "adam_uniform")" + allow + "}"), "");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/vertices", "large_steps_lambda": -1}])" + allow + "}"),
                  "optimization.parameters[0].large_steps_lambda: must be >= 0");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/vertices", "large_steps_lambda": "NaN"}])" + allow + "}"),
                  "optimization.parameters[0].large_steps_lambda: must be a finite number");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "large_steps_lambda": 5}]})"),
                  "large_steps_lambda applies to vertex parameters");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/vertices"}, {"name": "shapes/short_box/scale"}], "optimizer": "adam_uniform")" +
                          allow + "}"),
                  "optimization.optimizer: adam_uniform scales each parameter's steps by the largest second moment over its values; parameters[1]");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/vertices"}, {"name": "shapes/tall_box/translation"}])" + allow + "}"),
                  "optimization.parameters[1].name: parameter 'shapes/tall_box/translation': shape 'tall_box' has its vertices as a parameter");
}

// A vertex parameter started from another mesh (initial_mesh): the parameter has the start
// mesh's vertices, the targets are still the shape's own (bit for bit the targets of the same job
// without a start mesh), shape_error is 0 at the truth and positive at the start, and mistakes
// name the field.
TEST(Problem, StartMeshesReplaceTheGeometryButNotTheTruth) {
  const std::string scene = R"("scene": {"materials": [{"name": "m", "diffuse": {}}],
    "shapes": [{"name": "floor", "quad": {}, "material": "m", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}},
               {"name": "block", "box": {}, "material": "m", "transform": {"scale": {"x": 0.3, "y": 0.3, "z": 0.3}, "translate": {"z": 0.8}}}],
    "lights": [{"name": "bulb", "point": {"position": {"x": 1, "z": 4}, "intensity": {"r": 10, "g": 10, "b": 10}}}],
    "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}}], "film": {"width": 24, "height": 24}}, "render": {"spp": 4})";
  auto job = [&](const std::string& param) {
    return parseJobJson("{" + scene + R"(, "optimization": {"method": "METHOD_PT", "target_spp": 4, "parameters": [)" + param + "]}}", "job.json");
  };
  Problem plain = buildProblem(job(R"({"name": "shapes/block/vertices"})"));
  Problem sphere = buildProblem(job(R"({"name": "shapes/block/vertices", "initial_mesh": {"sphere": {"subdivisions": 2}}})"));
  EXPECT_EQ(plain.params.size(), 24u);
  EXPECT_EQ(sphere.params.size(), 3u * 162u);
  EXPECT_EQ(renderTarget(plain, 0).data(), renderTarget(sphere, 0).data());
  EXPECT_EQ(sphere.scene->meshes[1].positions.size(), 162u) << "the start mesh is back after the target render";
  EXPECT_LT(shapeError(plain, plain.initial), 1e-6);
  const double start = shapeError(sphere, sphere.initial);
  EXPECT_GT(start, 0.02);
  EXPECT_LT(start, 0.5);
  EXPECT_EQ(parameterError(sphere, sphere.initial), -1.0) << "a start mesh's vertices have no counterpart in the truth";
  Problem plane = buildProblem(job(R"({"name": "block.vertex_positions", "initial_mesh": {"plane": {"subdivisions": 3}}})"));
  EXPECT_EQ(plane.params.size(), 3u * 16u);
  auto error = [&](const std::string& param) {
    try {
      buildProblem(job(param), {}, SceneUse::Validate);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_MENTIONS(error(R"({"name": "materials/m/albedo", "initial_mesh": {"sphere": {}}})"),
                  "optimization.parameters[0].initial_mesh: a start mesh is for vertex parameters");
  EXPECT_MENTIONS(error(R"({"name": "shapes/block/vertices", "initial_mesh": {"file": {"path": "/nonexistent/start.obj"}}})"),
                  "optimization.parameters[0].initial_mesh.file");
  EXPECT_MENTIONS(error(R"({"name": "shapes/block/vertices", "initial_mesh": {"sphere": {"subdivisions": 9}}})"),
                  "optimization.parameters[0].initial_mesh.sphere.subdivisions");
  EXPECT_MENTIONS(error(R"({"name": "shapes/block/vertices", "initial_mesh": {}})"), "optimization.parameters[0].initial_mesh: set file, sphere or plane");
  EXPECT_MENTIONS(error(R"({"name": "shapes/block/vertices", "initial": 0.5})"), "optimization.parameters[0].initial: would put every vertex");
}

// Moving discontinuities that are not mesh edges (issue 39): a shape resting on another surface
// cuts it along a contact curve at every tilt, and a hard spot cone's border slides over the
// moving surfaces it lights; no boundary term samples either. Such jobs are refused, naming the
// shape or light, unless the bias is accepted, and then the plan says BIASED and where.
TEST(Problem, UnsampledMovingDiscontinuitiesAreRefusedOrNamedInThePlan) {
  // The tall block stands on the Cornell box's floor, in view.
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}]})"),
                  "shape 'tall_box' touches or cuts 'floor' in view: their contact curve moves with it");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "shapes/tall_box/rotation"}]})"), "optimization.boundary.allow_unsampled_discontinuities");
  auto job = parseJobJson(R"({"zoo": "cornell", "optimization": {"parameters": [{"name": "shapes/tall_box/rotation"}],
    "boundary": {"allow_unsampled_discontinuities": true}}})", "job.json");
  Problem p = buildProblem(job, {}, SceneUse::Validate);
  const std::string plan = planJob(job, p, 2).text();
  EXPECT_MENTIONS(plan, "BIASED (boundary.allow_unsampled_discontinuities): shape 'tall_box' touches or cuts 'floor'");
  EXPECT_EQ(plan.find("none found"), std::string::npos);
  // A hard-edged spot (inner cone == outer cone) over a moving card; the same card under a soft one
  // (and held above the floor: no contact) is accepted, and its plan says nothing is left unsampled.
  auto spotJob = [](double inner, bool allow) {
    return R"({"scene": {"materials": [{"name": "m", "diffuse": {}}],
      "shapes": [{"name": "floor", "quad": {}, "material": "m", "transform": {"scale": {"x": 4, "y": 4, "z": 1}}},
                 {"name": "card", "quad": {}, "material": "m", "transform": {"scale": {"x": 0.3, "y": 0.3, "z": 1}, "translate": {"z": 1}}}],
      "lights": [{"name": "key", "spot": {"position": {"z": 3}, "target": {}, "intensity": {"r": 5, "g": 5, "b": 5},
                  "cone_outer_degrees": 20, "cone_inner_degrees": )" + std::to_string(inner) + R"(}}],
      "views": [{"eye": {"z": 4}, "target": {}, "up": {"y": 1}}], "film": {"width": 16, "height": 16}},
     "optimization": {"parameters": [{"name": "shapes/card/translation"}], "boundary": {"allow_unsampled_discontinuities": )" +
           std::string(allow ? "true" : "false") + "}}}";
  };
  try {
    buildProblem(parseJobJson(spotJob(20, false), "job.json"), {}, SceneUse::Validate);
    ADD_FAILURE() << "a hard spot cone over a moving card was accepted";
  } catch (const InputError& e) {
    EXPECT_MENTIONS(std::string(e.what()), "spot light 'key' has a hard cone edge");
  }
  auto soft = parseJobJson(spotJob(15, false), "job.json");
  Problem ps = buildProblem(soft, {}, SceneUse::Validate);
  EXPECT_MENTIONS(planJob(soft, ps, 2).text(), "discontinuities not sampled: none found");
  auto hard = parseJobJson(spotJob(20, true), "job.json");
  Problem ph = buildProblem(hard, {}, SceneUse::Validate);
  EXPECT_MENTIONS(planJob(hard, ph, 2).text(), "BIASED (boundary.allow_unsampled_discontinuities): spot light 'key' has a hard cone edge");
}

// The time-aware loss (cost_model depth) weighs V by the render cost t, and t depends on albedos,
// roughness and lights through roulette and sampling; V dt/dtheta is estimated for survival only,
// so any other parameter is refused (it used to be accepted, its gradient short of V dt/dtheta).
TEST(Problem, TimeAwareLossesOptimiseSurvivalOnly) {
  const std::string depth = R"("method": "METHOD_PT", "max_depth": 4, "variance": {"cost_model": "depth"})";
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], )" + depth + "}"),
                  "optimization.variance.cost_model: \"depth\" optimises sampling/rr_survival only");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "sampling/rr_survival"}, {"name": "materials/red/albedo"}], )" + depth + "}"),
                  "'materials/red/albedo'");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "sampling/rr_survival"}], )" + depth + "}"), "");
  EXPECT_EQ(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}], "method": "METHOD_PT", "variance": {}})"), "");
}

TEST(Problem, VarianceJobsNameTheirMistakes) {
  const std::string albedo = R"("parameters": [{"name": "materials/red/albedo"}])";
  EXPECT_MENTIONS(errorOf("{" + albedo + R"(, "variance": {}})"), "optimization.variance: needs method METHOD_PT");
  EXPECT_MENTIONS(errorOf("{" + albedo + R"(, "method": "METHOD_PT", "variance": {"estimator": "biased"}})"), "optimization.variance.estimator");
  EXPECT_MENTIONS(errorOf("{" + albedo + R"(, "method": "METHOD_PT", "variance": {"samples": -4}})"), "optimization.variance.samples");
  EXPECT_MENTIONS(errorOf("{" + albedo + R"(, "method": "METHOD_PT", "variance": {"weight": -1}})"), "optimization.variance.weight");
  EXPECT_MENTIONS(errorOf("{" + albedo + R"(, "method": "METHOD_PT", "pixel_sampler": "adaptive", "variance": {}})"), "pixel_sampler all or uniform");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "sampling/rr_survival"}], "method": "METHOD_RIS"})"), "need method METHOD_PT");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "sampling/guess"}], "method": "METHOD_PT"})"), "sampling/light_logits");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "sampling/pixel_light_logits/0"}], "method": "METHOD_PT"})"), "at least two lights");
  EXPECT_EQ(errorOf("{" + albedo + R"(, "method": "METHOD_PT", "variance": {"samples": 16, "spp": 2}})"), "");

  // Naming the survival parameter selects fixed survival: one value per bounce, 1 by default.
  auto job = parseJobJson(R"({"zoo": "cornell", "render": {"survival": [1, 0.8]}, "optimization": {"method": "METHOD_PT", "max_depth": 4,
    "parameters": [{"name": "sampling/rr_survival"}]}})", "job.json");
  Problem p = buildProblem(job);
  EXPECT_EQ(p.scene->sampling.survival, (std::vector<float>{1.f, 0.8f, 0.8f, 0.8f}));
  EXPECT_EQ(p.params.size(), 4u);
  auto bad = parseJobJson(R"({"zoo": "cornell", "render": {"russian_roulette": "throughput"}, "optimization": {"method": "METHOD_PT",
    "max_depth": 4, "parameters": [{"name": "sampling/rr_survival"}]}})", "job.json");
  try {
    buildProblem(bad);
    ADD_FAILURE() << "throughput roulette with the survival parameter was accepted";
  } catch (const InputError& e) {
    EXPECT_MENTIONS(std::string(e.what()), "render.russian_roulette");
  }
}

// A parameter at 0 changes which light samples ReSTIR's reused reservoirs could have produced:
// the default bounds keep albedos and intensities above 0, and an explicit 0 with ReSTIR is refused
// (other methods accept it). The scene's own values start inside the bounds.
TEST(Problem, RestirKeepsParametersOffZero) {
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "lower": 0}]})"),
                  "optimization.parameters[0].lower: must be above 0 with method METHOD_RESTIR");
  EXPECT_MENTIONS(errorOf(R"({"method": "METHOD_RESTIR", "parameters": [{"name": "materials/red/albedo"}, {"name": "lights/ceiling_light/intensity", "lower": 0}]})"),
                  "optimization.parameters[1].lower");
  EXPECT_EQ(errorOf(R"({"method": "METHOD_RIS", "parameters": [{"name": "materials/red/albedo", "lower": 0}]})"), "");
  auto job = parseJobJson(R"({"zoo": "cornell", "optimization": {"parameters": [{"name": "materials/red/albedo"}]}})", "job.json");
  Problem p = buildProblem(job);
  EXPECT_EQ(p.params.slots()[0].lower, kPositiveFloor);
  for (float v : p.initial) EXPECT_GE(v, kPositiveFloor);
}

// Targets, gradients and final renders share one light transport: a job whose render block asks
// for another depth is refused, naming both fields; the transport follows optimization.max_depth.
TEST(Problem, OneLightTransportForTargetsGradientsAndRenders) {
  auto with = [](const std::string& render, const std::string& optimization) {
    try {
      auto job = parseJobJson(R"({"zoo": "cornell", "render": )" + render + R"(, "optimization": )" + optimization + "}", "job.json");
      buildProblem(job);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string albedo = R"("parameters": [{"name": "materials/red/albedo"}])";
  std::string err = with(R"({"max_depth": 3})", "{" + albedo + "}");
  EXPECT_MENTIONS(err, "render.max_depth (3)");
  EXPECT_MENTIONS(err, "optimization.max_depth (1");
  EXPECT_MENTIONS(with(R"({"max_depth": 1})", R"({"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}"), "render.max_depth (1)");
  EXPECT_EQ(with(R"({"max_depth": 4, "spp": 8})", R"({"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}"), "");
  EXPECT_EQ(with(R"({"spp": 8})", R"({"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}"), "");
  auto job = parseJobJson(R"({"zoo": "cornell", "optimization": {"method": "METHOD_PT", "max_depth": 4, )" + albedo + "}}", "job.json");
  Problem p = buildProblem(job);
  for (StreamId s : {kTargetStream, kFinalRenderStream, StreamId{9}}) {
    RenderOptions ro = transportRenderOptions(p, 16, s);
    EXPECT_EQ(ro.maxDepth, 4);
    EXPECT_EQ(ro.estimator, LightEstimator::NeeMis);
  }
  EXPECT_EQ(targetRenderOptions(p).maxDepth, 4);
  EXPECT_NE(transportRenderOptions(p, 16, kTargetStream).seed, transportRenderOptions(p, 16, kFinalRenderStream).seed);
}

TEST(Problem, InitialValuesAndBatchesAreDeterministic) {
  auto job = zooJob("backlit");
  job.mutable_optimization()->set_target_spp(4);
  Problem p = buildProblem(job);
  for (float v : p.initial) EXPECT_FLOAT_EQ(v, 0.5f);
  EXPECT_GT(parameterError(p, p.initial), 0.05);
  EXPECT_EQ(parameterError(p, p.truth), 0.0);
  auto a = viewsForStep(p, 7), b = viewsForStep(p, 7), c = viewsForStep(p, 8);
  EXPECT_EQ(a, b);
  EXPECT_EQ(a.size(), 4u);
  EXPECT_NE(a, c);
  for (int v : a) EXPECT_LT(v, 16);
}

TEST(Problem, EveryZooSceneHasAValidJob) {
  for (const auto& e : zooEntries()) {
    auto job = zooJob(e.name);
    Problem p = buildProblem(job);
    EXPECT_GT(p.params.size(), 0u) << e.name;
    // Sampling parameters (spot, roulette) change the noise, not the mean: they have no truth.
    if (parameterError(p, p.initial) >= 0) {
      EXPECT_NE(p.initial, p.truth) << e.name;
    }
  }
}

TEST(Problem, InitialValuesPerChannel) {
  auto job = zooJob("cornell");
  auto* ps = job.mutable_optimization()->mutable_parameters(0);
  ASSERT_EQ(ps->name(), "materials/red/albedo");
  ps->clear_initial();
  for (double v : {0.01, 0.2, 0.9}) ps->add_initial_values(v);
  Problem p = buildProblem(job, {}, SceneUse::Validate);
  const ParameterSlot& s = p.params.slots()[0];
  EXPECT_FLOAT_EQ(p.initial[s.offset + 0], 0.01f);
  EXPECT_FLOAT_EQ(p.initial[s.offset + 1], 0.2f);
  EXPECT_FLOAT_EQ(p.initial[s.offset + 2], 0.9f);
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial_values": [0.1, 0.2]}]})"),
                  "optimization.parameters[0].initial_values: has 2 values; 'materials/red/albedo' takes 1, 3 (one per channel)");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial_values": [0.1, 1.2, 0.3]}]})"),
                  "optimization.parameters[0].initial_values[1]: outside the bounds");
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo", "initial": 0.5, "initial_values": [0.1]}]})"),
                  "set either initial or initial_values");
}

TEST(Problem, MitsubaNamesNameTheSameParameters) {
  auto scene = buildScene(zooScene("cornell"), {}, SceneUse::Validate);
  EXPECT_EQ(invrParameterName(*scene, "red.reflectance.value"), "materials/red/albedo");
  EXPECT_EQ(invrParameterName(*scene, "red.brdf_0.reflectance.value"), "materials/red/albedo");
  EXPECT_EQ(invrParameterName(*scene, "left.bsdf.reflectance.value"), "materials/red/albedo");  // nested in shape 'left'
  EXPECT_EQ(invrParameterName(*scene, "ceiling_light.radiance.value"), "lights/ceiling_light/intensity");
  EXPECT_EQ(invrParameterName(*scene, "light.emitter.radiance.value"), "lights/ceiling_light/intensity");
  EXPECT_EQ(invrParameterName(*scene, "materials/red/albedo"), "materials/red/albedo");
  auto err = [&](const std::string& n) {
    try {
      invrParameterName(*scene, n);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_MENTIONS(err("blue.reflectance.value"), "no material (bsdf) with id 'blue'");
  EXPECT_MENTIONS(err("red.eta.value"), "property 'eta' has no invr parameter");
  EXPECT_MENTIONS(err("floor.emitter.radiance.value"), "shape 'floor' does not emit");
  // Both spellings of one value: listed twice.
  EXPECT_MENTIONS(errorOf(R"({"parameters": [{"name": "materials/red/albedo"}, {"name": "red.reflectance.value"}]})"),
                  "the same value as parameter 'materials/red/albedo'");
}

// The zoo's Cornell box on a small square film, recovering the red wall with PT.
v1::JobSpec smallCornellJob(int side) {
  v1::JobSpec job;
  *job.mutable_scene() = zooScene("cornell");
  job.mutable_scene()->mutable_film()->set_width(side);
  job.mutable_scene()->mutable_film()->set_height(side);
  job.mutable_optimization()->set_method(v1::METHOD_PT);
  job.mutable_optimization()->add_parameters()->set_name("materials/red/albedo");
  return job;
}

// Masked-out pixels take no part in the loss or its gradient: junk there changes nothing, while
// without the mask it changes both.
TEST(Problem, TargetMasksExcludePixelsFromLossAndGradient) {
  namespace fs = std::filesystem;
  fs::path dir = fs::temp_directory_path() / ("invr_mask_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  v1::JobSpec job = smallCornellJob(32);
  job.mutable_optimization()->set_target_spp(8);
  job.mutable_optimization()->mutable_parameters(0)->set_initial(0.3);
  {
    Problem truth = buildProblem(job);
    Image t = renderTarget(truth, 0), junk = t, mask(32, 32, 3), ones(32, 32, 3);
    for (int y = 0; y < 32; ++y)
      for (int x = 0; x < 32; ++x) {
        if (x < 12) junk.setRgb(x, y, Rgb(5.f, 0.f, 5.f));  // the left (red) wall's side
        mask.setRgb(x, y, Rgb(x < 12 ? 0.f : 1.f));
        ones.setRgb(x, y, Rgb(1.f));
      }
    writeImage(dir / "clean.exr", t);
    writeImage(dir / "junk.exr", junk);
    writeImage(dir / "mask.png", mask);
    writeImage(dir / "ones.png", ones);
  }
  AssetResolver assets;
  assets.baseDir = dir;
  auto evaluate = [&](const std::string& target, const std::string& mask) {
    v1::JobSpec j = job;
    j.mutable_optimization()->add_targets()->set_path(target);
    if (!mask.empty()) j.mutable_optimization()->add_target_masks()->set_path(mask);
    Problem p = buildProblem(j, assets);
    p.params.write(p.initial, *p.scene);
    GradientEngine engine(*p.scene, p.params, p.givenTargets, p.gradient);
    EngineSession session;
    return engine.evaluate(shardRequest(p, evaluationAt(p, 0), 0), session);
  };
  GradientResult cleanMasked = evaluate("clean.exr", "mask.png"), junkMasked = evaluate("junk.exr", "mask.png");
  EXPECT_EQ(cleanMasked.gradient, junkMasked.gradient);
  EXPECT_EQ(cleanMasked.stats.loss(), junkMasked.stats.loss());
  GradientResult clean = evaluate("clean.exr", ""), junk = evaluate("junk.exr", "");
  EXPECT_NE(clean.gradient, junk.gradient);
  EXPECT_GT(junk.stats.loss(), 10 * std::abs(clean.stats.loss()));
  // A mask that keeps everything is no mask.
  GradientResult cleanOnes = evaluate("clean.exr", "ones.png");
  for (size_t i = 0; i < clean.gradient.size(); ++i) EXPECT_NEAR(cleanOnes.gradient[i], clean.gradient[i], 1e-6 * std::abs(clean.gradient[i]) + 1e-12);
  // Mistakes name the field.
  auto maskError = [&](const std::string& optimizationJson) {
    try {
      v1::JobSpec j = job;
      auto extra = parseJobJson(R"({"optimization": )" + optimizationJson + "}", "job.json");
      j.mutable_optimization()->MergeFrom(extra.optimization());
      buildProblem(j, assets, SceneUse::Validate);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_MENTIONS(maskError(R"({"target_masks": [{"path": "mask.png"}]})"), "optimization.target_masks: masks need targets");
  Image black(32, 32, 3), small(8, 8, 3);
  writeImage(dir / "black.png", black);
  writeImage(dir / "small.png", small);
  EXPECT_MENTIONS(maskError(R"({"targets": [{"path": "clean.exr"}], "target_masks": [{"path": "black.png"}]})"),
                  "optimization.target_masks[0]: excludes every pixel");
  EXPECT_MENTIONS(maskError(R"({"targets": [{"path": "clean.exr"}], "target_masks": [{"path": "small.png"}]})"),
                  "optimization.target_masks[0]: is 8x8, the film is 32x32");
  EXPECT_MENTIONS(maskError(R"({"targets": [{"path": "clean.exr"}], "target_masks": [{"path": "mask.png"}, {"path": "mask.png"}]})"),
                  "needs one entry per target");
  // An empty entry leaves its view unmasked.
  EXPECT_EQ(maskError(R"({"targets": [{"path": "clean.exr"}], "target_masks": [{}]})"), "");
  fs::remove_all(dir);
}

// Photographs as targets: 8-bit PNGs hold sRGB-encoded values and are decoded to linear; EXRs
// are linear as they are; a wrong size names the size expected.
TEST(Problem, EightBitTargetsAreDecodedFromSrgb) {
  namespace fs = std::filesystem;
  fs::path dir = fs::temp_directory_path() / ("invr_photo_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  v1::JobSpec job = smallCornellJob(8);
  Image linear(8, 8, 3);
  for (int y = 0; y < 8; ++y)
    for (int x = 0; x < 8; ++x) linear.setRgb(x, y, Rgb(0.05f, 0.2f, 0.6f));
  writeImage(dir / "photo.png", linear);  // sRGB-encoded, 8 bits
  writeImage(dir / "linear.exr", linear);
  AssetResolver assets;
  assets.baseDir = dir;
  for (const char* file : {"photo.png", "linear.exr"}) {
    v1::JobSpec j = job;
    j.mutable_optimization()->add_targets()->set_path(file);
    Problem p = buildProblem(j, assets, SceneUse::Validate);
    Rgb c = p.givenTargets.at(0).rgb(3, 3);
    // Half an 8-bit step of sRGB around each value, in linear terms: at most 0.003 here.
    EXPECT_NEAR(c.x, 0.05f, 0.003f) << file;
    EXPECT_NEAR(c.y, 0.2f, 0.003f) << file;
    EXPECT_NEAR(c.z, 0.6f, 0.003f) << file;
  }
  Image wrong(16, 8, 3);
  writeImage(dir / "wrong.png", wrong);
  v1::JobSpec j = job;
  j.mutable_optimization()->add_targets()->set_path("wrong.png");
  try {
    buildProblem(j, assets, SceneUse::Validate);
    ADD_FAILURE() << "a target of the wrong size was accepted";
  } catch (const InputError& e) {
    EXPECT_MENTIONS(std::string(e.what()), "optimization.targets[0]: is 16x8, the film is 8x8");
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace invr
