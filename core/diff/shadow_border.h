// What the shadow-boundary estimators (delta_shadow_boundary.h for point and spot lights,
// area_shadow_boundary.h for points sampled on area lights, environment_shadow_boundary.h for
// directions sampled on environments) share: the silhouette edges an occluder shows a source, and
// the border point a (source, edge, t) sample lands on.
//
// For a source at l and an occluder edge a-b, e(t) = a + t (b - a), the shadow point y(t) is the
// first surface the ray l -> e(t) meets beyond e, and x(t) its film position. Across the film
// curve x(t) what the pixel sees from that source jumps; Reynolds transport gives
//     d/dtheta sum_p w_p I_p = ∫ w(x) ΔL(x) (v . perp(dx/dt)) dt,
// with v the film velocity of the curve, from dy/dtheta by the ray-plane intersection at y given
// the occluder's velocity at e and the receiver's at y (either or both may move). A source at
// infinity in direction w is the same with the ray e(t) - t' w: y = e + s' d for the fixed
// travel direction d = -w, whose derivative is the point source's with (e - l) -> d and s -> 1.
#pragma once

#include <atomic>
#include <functional>
#include <vector>

#include "core/diff/boundary_sampling.h"
#include "core/diff/gradient_sink.h"
#include "core/diff/parameters.h"
#include "core/geometry/edge_topology.h"
#include "core/render/render_options.h"
#include "core/scene/scene.h"

namespace invr {

// Where a shadow-casting source is: a point (point and spot lights, points on area lights), or a
// direction towards a source at infinity (environments).
struct ShadowSource {
  Vec3 v;
  bool directional = false;
  Vec3 n;  // a point on an emitter: the emitter's normal (shadow rays end just off it); else 0
  static ShadowSource at(Vec3 p, Vec3 emitterNormal = Vec3(0.f)) { return {p, false, emitterNormal}; }
  static ShadowSource towards(Vec3 w) { return {w, true, Vec3(0.f)}; }
  // From x towards the source (not normalised).
  Vec3 from(Vec3 x) const { return directional ? v : v - x; }
};

struct ShadowEdge {
  uint32_t source;  // index into the pass's sources (BorderSource list)
  uint32_t mesh;
  Vec3 a, b;
  uint32_t v0 = 0, v1 = 0;  // the mesh vertices at a and b (vertex parameters take the gradient)
};

// Edges a sample may pick carry a weight proportional to their length, times this when a ray
// through the midpoint finds no receiver, and again when neither the edge's mesh nor that
// receiver moves (guesses: any positive weight is unbiased).
constexpr float kUnlikelyShadowEdgeWeight = 0.05f;

// Appends the silhouette edges every mesh with a topology (but `skipMesh`: the emitter a source
// lies on) shows `source`. `view`: the view whose film the borders are sampled on (a moving camera
// moves every border on it).
void collectShadowEdges(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology, ShadowSource source,
                        uint32_t sourceIndex, std::vector<ShadowEdge>& edges, std::vector<float>& weights, uint32_t skipMesh = UINT32_MAX,
                        int view = -1);

struct ShadowBorderPoint {
  Vec3 e, toE;       // the edge point and e - l (directional sources: the unit travel direction d)
  float t = 0.f;     // e = lerp(a, b, t)
  SurfaceHit hit;    // the shadow point y on its receiver
  float s = 0.f;     // |y - l| / |e - l| (directional: 1)
  float denom = 0.f; // nr . toE
  Vec3 drawn;        // where the renderer draws the border, on the receiver's plane
  Vec2 x, n;         // film position and the unit film normal of the border there
  float speed = 0.f; // |dx/dt| in pixels
  Vec3 jx, jy;       // d(film x, y)/dy
  // The two sides the jump is measured between (L(side[0]) - L(side[1]) is the film's
  // L(x - eps n) - L(x + eps n)): points of the receiver's plane just off the border along its
  // normal in that plane, far enough to straddle the border the renderer draws.
  SurfaceHit side[2];
};

// The border point of edge `se` at t for `source` on view `view`'s film; false when there is none
// on the film or nothing there moves (the occluder, the receiver, or the view's camera). Counts
// the rays it traces (up to two: edge to receiver, receiver to eye) in rays.shadow.
bool shadowBorderPoint(const Scene& scene, const ParameterRegistry& params, int view, ShadowSource source, const ShadowEdge& se, float t,
                       ShadowBorderPoint& out, RayStats& rays);

// The receiver `hit`'s surface (its triangle's normal, interpolated shading normal and uv) at q, a
// point of that triangle's plane, inside the triangle or just beyond it.
SurfaceHit receiverAt(const Scene& scene, const SurfaceHit& hit, Vec3 q);

// Adds w * (n . dx/dtheta) for the occluder's and the receiver's shape parameters (x moving with
// dy/dtheta) and view `view`'s camera parameters (x moving as the camera does), where w is the
// sample's weight: adjoint . ΔL * speed / pdf.
void addShadowBorderGradient(const Scene& scene, const ParameterRegistry& params, int view, const ShadowEdge& se, const ShadowBorderPoint& bp,
                             double w, PathGradient& grad);

// What the point or spot light l adds to surface point `at` seen from `eye`: f |cos| I falloff / r^2,
// visibility included. The delta-light border term differences this one source across the
// border: its jump is exact, and no other light's noise or other discontinuity enters it.
Rgb deltaSourceRadiance(const Scene& scene, const SurfaceHit& at, Vec3 eye, const Light& l, RayStats& rays);

// Area lights as integrals of point sources (area_shadow_boundary.h, edge_reservoir_boundary.h).
float emittedPower(const Light& l);  // luminance of the power an area light emits; 0 for other lights

struct LightPoint {
  uint32_t light;
  Vec3 y, n;
  double pdf;  // area density of y (light choice included)
};

// What the point source at y (a point of area light l, intensity Le(y) |cos_y| dA) adds to the
// surface point `at` seen from `eye`: f |cos_x| Le(y) |cos_y| / r^2, visibility included.
Rgb pointSourceRadiance(const Scene& scene, const SurfaceHit& at, Vec3 eye, const Light& l, const LightPoint& lp, RayStats& rays);

// A source whose shadow borders a pass samples: a delta light, or one of the points (directions)
// a pass drew on an area light (an environment).
struct BorderSource {
  ShadowSource at;
  double weight = 1.0;  // 1 / (its density times the number drawn); 1 for a delta light
  uint32_t skipMesh = UINT32_MAX;  // the emitter the source lies on
};

// What `source` adds to surface point `at` seen from `eye`, visibility included.
using BorderSourceRadiance = std::function<Rgb(uint32_t source, const SurfaceHit& at, Vec3 eye, RayStats& rays)>;

// The pass the shadow-border estimators share: collects every source's silhouette edges, samples
// (source, edge, t) by their weights and t uniformly, measures the jump of that source's radiance
// across the border (ShadowBorderPoint::side), and adds adjoint . jump * speed * weight / pdf
// through addShadowBorderGradient. Sample i uses the key (stream, step, view, i).
BoundaryPassStats sampleShadowBorders(const Scene& scene, const ParameterRegistry& params, const std::vector<EdgeTopology>& topology,
                                      int view, const Image& adjoint, int samples, const std::vector<BorderSource>& sources,
                                      const BorderSourceRadiance& radiance, uint64_t stream, uint64_t step, GradientScratchPool& scratch,
                                      std::vector<double>& gradient, const std::atomic<bool>* cancel,
                                      SamplerKind samplerKind = SamplerKind::Independent, PixelDerivativeSink* pixels = nullptr);

// What the environment's direction `ls.wi` (radiance ls.radiance, dist infinite) adds to surface
// point `at` seen from `eye`: f |cos| Le, visibility included (per unit solid angle).
Rgb directionalSourceRadiance(const Scene& scene, const SurfaceHit& at, Vec3 eye, const LightSample& ls, RayStats& rays);

}  // namespace invr
