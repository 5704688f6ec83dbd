// Boundary terms of shape derivatives (Wang et al. 2023, §5-6): the parts of a gradient that come
// from visibility discontinuities moving with the shape parameters. Each term samples one kind of
// discontinuity (silhouettes and creases seen by the camera, the shadow borders of one kind of
// light) and lives in its own file, where it registers itself:
//
//   primary_boundary.cc             primary: silhouette and crease edges (Eq. 9-11)
//   delta_shadow_boundary.cc        shadow borders of point and spot lights
//   edge_reservoir_boundary.cc      shadow borders of area lights, edge point first (Alg. 6, Eq. 27)
//   area_shadow_boundary.cc         shadow borders of area lights, light points first
//   environment_shadow_boundary.cc  shadow borders of environment lights
//
// The engine builds the list of terms that apply to its scene and options once, then runs each
// per view of a step, in the order of their `order` (the gradient is summed in that order, so a
// step's numbers do not depend on registration order). docs/architecture.md shows how to add one.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/diff/boundary_options.h"
#include "core/diff/boundary_state.h"
#include "core/diff/gradient_sink.h"
#include "core/diff/parameters.h"
#include "core/geometry/edge_topology.h"
#include "core/image/image.h"
#include "core/math/rng.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"
#include "invr/v1/job.pb.h"

namespace invr {

// What a job sets of the boundary terms (optimization.boundary): used when shape or camera
// parameters are optimised. Defaults here are the job's defaults. The fields here are the ones
// every term shares; each term's own are in `terms` (boundary_options.h), parsed by the term.
struct BoundaryOptions {
  bool primary = true;    // silhouette, crease and terminator edges of moving meshes seen by the camera
  bool secondary = true;  // shadow borders of point, spot, area and environment lights
  int samples = 0;        // edge samples per term, view and step; 0: a quarter of the film's pixels, at least 256
  // Light points (area lights, light points first) and directions (environments) per pass whose
  // shadow borders are sampled; a term's own option may override it.
  int lightPoints = 16;
  // ReSTIR: test the support of reused samples in the current geometry (the paper's multi-view
  // shortcut, §3.2), which is biased once geometry moves. Default: in the geometry each sample was
  // created in (unbiased; the reservoir store keeps the moving meshes' poses for that).
  bool multiViewShortcut = false;
  // Area lights' shadow borders: sampled edge point first with the light point by RIS (Alg. 6;
  // restir reuses edge reservoirs across steps) or light points first. Selects between two terms.
  enum class AreaSampling { EdgeFirst, LightPoints };
  AreaSampling areaSampling = AreaSampling::EdgeFirst;
  // Accept moving shapes whose discontinuities no term samples (contact curves with other surfaces,
  // hard spot-light cones on them): the gradient is then biased, and the plan says so.
  bool allowUnsampled = false;
  // Each term's own options (optimization.boundary.terms.<name>), by its registered name.
  BoundaryTermOptionSlots terms;

  int samplesFor(int width, int height) const { return samples > 0 ? samples : std::max(256, width * height / 4); }
  // A term's samples: its own option, else the shared ones above.
  int samplesFor(const std::string& term, int width, int height) const {
    const BoundaryTermOptions* o = terms.find(term);
    return o && o->samples > 0 ? o->samples : samplesFor(width, height);
  }
  bool enabled(const std::string& term) const {
    const BoundaryTermOptions* o = terms.find(term);
    return !o || o->enabled;
  }
  // T's options (made with T's defaults on first use), for tests and ablations to change.
  template <class T>
  T& term() { return terms.get<T>(); }
  // T's options as the job set them, or T's defaults.
  template <class T>
  const T& termOr() const { return terms.getOr<T>(); }
};

// The fields every term's message has (enabled, samples), into o; `term` names the message
// (optimization.boundary.terms.<term>) in errors.
template <class Spec>
void parseSharedTermFields(const Spec& spec, const std::string& term, BoundaryTermOptions& o) {
  if (spec.samples() < 0 || spec.samples() > (1 << 24))
    throw InputError("optimization.boundary.terms." + term + ".samples: must be in 1..16777216 (0: optimization.boundary.samples)");
  o.samples = spec.samples();
  o.enabled = spec.has_enabled() ? spec.enabled() : true;
}

// Throws InputError naming the field (optimization.boundary.*) for a value out of range.
BoundaryOptions parseBoundaryOptions(const invr::v1::BoundarySpec& spec);

struct BoundaryPassStats {
  size_t candidateEdges = 0;  // edges a sample may pick
  double filmLength = 0;      // primary: their total clipped length in pixels
  uint64_t samples = 0, dropped = 0;  // dropped: non-finite
  RayStats rays;
};

struct GradientOptions;
class InteriorEstimator;
class GradientScratchPool;

// What a term is built from, once per step.
struct BoundaryStep {
  const Scene& scene;
  const ParameterRegistry& params;
  const std::vector<EdgeTopology>& topology;  // per mesh (occluders need not move to cast a moving shadow)
  const GradientOptions& options;
  std::unique_ptr<BoundaryTermState>& state;  // this term's slot in the session: what it keeps between steps
  const std::vector<int>& views;  // the step's views (of this shard)
  bool allSessionViews = false;   // the step holds every view the session serves
};

// One view's pass of a term.
struct BoundaryView {
  int view = 0;
  const Image& adjoint;                // dLoss/dI per pixel and channel (the primal render's)
  const InteriorEstimator& estimator;  // the derivative pass's, for terms that trace the scene's radiance
  int samples = 0;                     // BoundaryOptions::samplesFor the film
  uint64_t stream = 0;                 // streamSeed(job seed, the term's stream)
  uint64_t step = 0;
  GradientScratchPool& scratch;
  std::vector<double>& gradient;
  const std::atomic<bool>* cancel = nullptr;
  SamplerKind sampler = SamplerKind::Independent;  // GradientOptions::sampler
  // Set for a derivative image (GradientRequest::derivativeImage): each sample's entries of its
  // parameter value also go to the pixel whose dL/dI weighed the sample (PathGradient::setPixel).
  PixelDerivativeSink* pixels = nullptr;
};

class BoundaryTerm {
 public:
  virtual ~BoundaryTerm() = default;
  // Adds the view's samples into view.gradient (sample i keyed by (stream, step, view, i); chunks
  // reduced in order: the same sums for any thread count).
  virtual BoundaryPassStats run(const BoundaryView& view) = 0;
  // After every view of the step: what the term keeps for the next step, and counters of its own
  // (added to the stats' counters map). Default: nothing.
  virtual void endStep(RayStats& rays, std::vector<std::pair<std::string, uint64_t>>& counters) { (void)rays, (void)counters; }
};

// The facts of a job a term's plan line and memory estimate are made from.
struct BoundaryPlanInput {
  const Scene& scene;
  const GradientOptions& options;
  size_t shardViews = 1;  // views of the largest shard
  const ParameterRegistry* params = nullptr;  // the job's parameters, for counts in the scene as given
};

// The edge topology the boundary terms use, per mesh of the scene (occluders need not move to cast
// a moving shadow): deforming flat-shaded meshes have every edge a crease, deforming smooth ones
// none (their terminators are found per step).
std::vector<EdgeTopology> buildBoundaryTopology(const Scene& scene, const ParameterRegistry& params);

// The kinds of film discontinuity that move with shape or camera parameters. Each boundary term
// declares the ones it samples (BoundaryTermKind::samples); a job whose scene has one that no
// registered term declares is refused, naming it (unsampledDiscontinuities, gradient_job_check.h).
enum class Discontinuity : uint8_t {
  MeshEdges,                // silhouettes, creases and smooth meshes' shadow terminators, seen by the camera
  DeltaLightShadows,        // shadow borders of point and spot lights
  AreaLightShadows,         // shadow borders of area lights
  EnvironmentShadows,       // shadow borders of environment lights
  ContactCurves,            // where a surface touches or cuts another (or itself) in view: not a mesh edge
  HardSpotCones,            // a spot light's hard cone border on what it lights
  EnvironmentTexelBorders,  // an image environment map's texel borders, seen by a moving camera
};

// One kind of boundary term, as it registers itself.
struct BoundaryTermKind {
  std::string name;  // the key of its statistics (GradientStats.boundary)
  int order = 0;     // where it runs in a step
  // Its random numbers: StreamId::named(name) unless it pins the number its documented figures
  // were measured with (the terms older than named streams do: docs/architecture.md).
  std::optional<StreamId> pinnedStream;
  StreamId stream() const { return pinnedStream ? *pinnedStream : StreamId::named(name); }
  // Whether it has work for this scene under these options (the options may select another term
  // for the same discontinuities).
  std::function<bool(const Scene&, const GradientOptions&)> applies;
  std::function<std::unique_ptr<BoundaryTerm>(const BoundaryStep&)> make;
  // One line of the job's plan: what it computes per step.
  std::function<std::string(const BoundaryPlanInput&)> describe;
  // Bytes one worker holds for it beyond the shared edge topology (0 by default).
  std::function<double(const BoundaryPlanInput&)> memoryBytes;
  // The discontinuities it samples (alternatives for one kind may both declare it).
  std::vector<Discontinuity> samples;
  // Its options from the job's optimization.boundary: its own message under `terms` (read with
  // parseSharedTermFields for enabled and samples) and any shared field it reads; nullptr when the
  // job set none. Throws InputError naming the field. Every term sets it.
  std::function<std::unique_ptr<BoundaryTermOptions>(const invr::v1::BoundarySpec&)> parse;
};

// Registers a term kind; a file defines one of these at namespace scope. Throws std::logic_error
// for a name or order already registered, for a stream another term has (unless both sample the
// same discontinuities: alternatives never run in one job), or a pinned stream among the engine's
// own small numbers.
struct RegisterBoundaryTerm {
  explicit RegisterBoundaryTerm(BoundaryTermKind kind);
};

// Every registered kind, in run order.
const std::vector<const BoundaryTermKind*>& boundaryTermKinds();
// Whether one of `kinds` declares that it samples d.
bool sampledBy(Discontinuity d, const std::vector<const BoundaryTermKind*>& kinds);
// The kinds that apply to a scene under a job's options (none unless shapes are optimised and the
// options enable them).
std::vector<const BoundaryTermKind*> boundaryTermsFor(const Scene& scene, const ParameterRegistry& params, const GradientOptions& options);

}  // namespace invr
