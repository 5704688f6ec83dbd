// Named optimisation parameters mapped into one flat vector theta. Each kind of parameter is one
// file that registers itself (core/diff/parameter_kind.h lists them); the registry dispatches to
// the kinds when a parameter is added, read or written, and keeps the dense tables the estimators
// read at render time (ParameterTables). The names:
//   materials/<name>/albedo     diffuse or rough_plastic albedo: 3 values, or width*height*3 texels
//   materials/<name>/roughness  GGX alpha of rough_conductor/rough_plastic: 1 value, or width*height
//   lights/<name>/intensity     area/constant-environment radiance or point/spot intensity: 3 values
//   lights/<name>/texels        an image environment map's texels: width*height*3 values (radiance,
//                               the light's scale applied). Mitsuba: <id>.data. Its sampling
//                               distribution is rebuilt from them after every update and treated
//                               as detached (as Mitsuba does): the derivative is the integrand's.
// Shape parameters (Wang et al. 2023's shape half; core/scene/shape_motion.h): the pose relative to
// the scene as described, about the shape's or group's pivot
//   shapes/<name>/translation   x, y, z: 3 values, starting at 0
//   shapes/<name>/rotation      Euler degrees about x, then y, then z: 3 values, starting at 0
//   shapes/<name>/scale         uniform: 1 value, starting at 1
//   shapes/<name>/translation/x (y, z), shapes/<name>/rotation/x (y, z)   one component alone
//   groups/<name>/translation|rotation|scale   the same for a group of shapes (applied after the
//                                               members' own)
//   shapes/<name>/vertices      x, y, z of every vertex (vertices at one position, the copies at
//                               uv or normal seams, are one vertex: 3 values each), in world space,
//                               starting at the mesh as described. Not with the shape's (or its
//                               group's) pose parameters. Flat-shaded meshes only.
//                               Mitsuba: <id>.vertex_positions, <id>.positions.
// Camera parameters (param_camera.cc): a view's pose relative to the camera as described, about
// its eye; <view> is the camera's name or index, or * for every view together (the same offset)
//   cameras/<view>/translation  x, y, z in world space: 3 values, starting at 0
//   cameras/<view>/rotation     Euler degrees about x, then y, then z (world axes): 3 values
//   cameras/<view>/translation/x (y, z), cameras/<view>/rotation/x (y, z)   one component alone
// Sampling parameters (Yan et al. 2024; they change a render's noise, never its mean):
//   sampling/light_logits                 one logit per light: NEE picks lights by their softmax
//   sampling/pixel_light_logits/<view>    per cell of a map over view <view>'s film: one logit per light
//   sampling/rr_survival                  Russian-roulette survival of bounce 1, 2, ... (fixed survival)
// Registering logits starts them at log(the current selection pmf): today's selection by power.
// Mitsuba 3 names of the same values are accepted too (invrParameterName).
// Values are the effective ones (texture scale applied). Only registered parameters get derivative
// storage.
#pragma once

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/diff/gradient_sink.h"
#include "core/scene/scene.h"

namespace invr {

class ParameterKind;

// Default lower bound of albedos and light intensities. Above zero so that optimisation never
// changes where a light sample's target is positive: ReSTIR's normalisation (Z) counts the reused
// reservoirs that could have produced a sample by evaluating their target now, which is exact
// only while positivity is what it was when they were created.
inline constexpr float kPositiveFloor = 1e-4f;

struct ParameterSlot {
  std::string name;
  const ParameterKind* kind = nullptr;  // what it is (parameter_kind.h)
  uint32_t offset = 0, size = 0;
  int channels = 3;  // values per texel (3 colour, 1 scalar)
  int material = -1, light = -1;
  int view = -1;  // PixelLightLogits
  int shape = -1, group = -1;  // shape parameters: the mesh or the group they move
  int component = -1;          // one component of a translation or rotation (0 x, 1 y, 2 z), or -1: all three
  int width = 0, height = 0;  // texture resolution; 0 for constants
  float lower = 0.f, upper = 1.f;
  float learningRate = 0.01f;
  // Vertex parameters: Large Steps' lambda (core/optim/large_steps.h); 0 optimises x itself.
  float largeStepsLambda = 0.f;
};

struct ParameterOptions {
  std::optional<float> lower, upper, learningRate;
  std::optional<float> largeStepsLambda;  // vertex parameters only, >= 0
  int mapWidth = 0, mapHeight = 0;  // PixelLightLogits: the map's resolution (0: the film's)
};

// What the estimators read at render time, dense and indexed by the scene's objects. The kinds
// fill it when a parameter is added (ParameterKind::attach).
struct ParameterTables {
  std::vector<int> albedo, roughness, intensity, texels;  // per material or light: offset in theta, or -1
  std::vector<int> pixelLogits;                            // per view: index into the slots, or -1
  int lightLogits = -1, survival = -1;                     // offsets, or -1
  // Shape parameters: per rigidly moving mesh the theta index of each motion component that moves
  // it with its velocity field (ShapeMotion: 0-6 own, 7-13 group's).
  struct ShapeField {
    uint32_t index;
    int field;
  };
  std::vector<std::vector<ShapeField>> meshFields;  // per mesh
  std::vector<uint32_t> movingMeshes, rigidMeshes;  // ascending
  std::vector<uint8_t> moving;                      // per mesh
  // Vertex parameters (param_vertices.cc): per mesh, index into vertexFields or -1.
  struct VertexField {
    uint32_t offset = 0;
    std::vector<uint32_t> weld;            // mesh vertex -> parameter vertex
    std::vector<uint32_t> representative;  // parameter vertex -> its first mesh vertex
    std::vector<std::pair<uint32_t, uint32_t>> edges;  // between parameter vertices
    // Smooth meshes: where dL/d(vertex normal) of mesh vertex v starts, size + normalOffset + 3v;
    // -1 for flat meshes.
    int64_t normalOffset = -1;
    uint32_t mesh = 0;
  };
  std::vector<int> vertexField;
  std::vector<VertexField> vertexFields;
  // Camera parameters (param_camera.cc): per view the theta index of each motion component that
  // moves its camera (Scene::cameraPointVelocity's k, 0-5); empty for a view that does not move.
  std::vector<std::vector<ShapeField>> cameraFields;
  bool cameraMoves(int view) const { return view >= 0 && size_t(view) < cameraFields.size() && !cameraFields[size_t(view)].empty(); }
  size_t normalAdjoints = 0;
  int nextSlot = 0;  // the index the slot being attached will have

  static int lookup(const std::vector<int>& v, int i) { return i >= 0 && size_t(i) < v.size() ? v[size_t(i)] : -1; }
  // Sets v[i] = value, growing v with -1.
  static void put(std::vector<int>& v, size_t i, int value) {
    if (v.size() <= i) v.resize(i + 1, -1);
    v[i] = value;
  }
  bool moves(uint32_t mesh) const { return mesh < moving.size() && moving[mesh]; }
  bool deforms(uint32_t mesh) const { return mesh < vertexField.size() && vertexField[mesh] >= 0; }
  const VertexField& vertices(uint32_t mesh) const { return vertexFields[size_t(vertexField[mesh])]; }
  void markMoving(const Scene& scene, uint32_t mesh);
};

class ParameterRegistry {
 public:
  using ShapeField = ParameterTables::ShapeField;
  // Throws InputError naming the parameter when it does not exist in the scene or is repeated.
  const ParameterSlot& add(const Scene& scene, const std::string& name, const ParameterOptions& options = {});

  size_t size() const { return size_; }
  // The length of the gradient vector the estimators accumulate into: size(), then dL/d each
  // vertex normal of the smooth meshes whose vertices are parameters (3 per mesh vertex), which
  // foldNormalAdjoints takes to the vertices once the passes are summed (a per-sample scatter
  // over each hit vertex's ring of triangles would cost more than the rest of the sample).
  size_t adjointSize() const { return size_ + t_.normalAdjoints; }
  const std::vector<ParameterSlot>& slots() const { return slots_; }
  // Sets one slot's learning rate (benchmarks sweep them; jobs set them through ParameterSpec).
  void setLearningRate(size_t slot, float rate) { slots_.at(slot).learningRate = rate; }
  const ParameterSlot* find(const std::string& name) const;
  const ParameterTables& tables() const { return t_; }

  std::vector<float> read(const Scene& scene) const;
  // Writes theta into the scene's materials and lights; refreshes light selection when emission
  // changed (unless refreshSampling is false: finite-difference references keep sampling fixed so
  // that common random numbers stay common). Throws InputError on a size mismatch.
  void write(const std::vector<float>& theta, Scene& scene, bool refreshSampling = true) const;
  void clampToBounds(std::vector<float>& theta) const;

  // Offsets of a material's or light's parameters in theta, or -1 if not optimised.
  int albedoOffset(int material) const { return ParameterTables::lookup(t_.albedo, material); }
  int roughnessOffset(int material) const { return ParameterTables::lookup(t_.roughness, material); }
  int intensityOffset(int light) const { return ParameterTables::lookup(t_.intensity, light); }
  // An image environment's texels (lights/<l>/texels): texel t's channel c is at offset + 3t + c
  // (t as environmentTexel numbers it), or -1 if not optimised.
  int texelsOffset(int light) const { return ParameterTables::lookup(t_.texels, light); }
  // Sampling parameters: offsets, or -1 if not optimised.
  int lightLogitsOffset() const { return t_.lightLogits; }
  int survivalOffset() const { return t_.survival; }
  const ParameterSlot* pixelLogits(int view) const {
    int i = ParameterTables::lookup(t_.pixelLogits, view);
    return i >= 0 ? &slots_[size_t(i)] : nullptr;
  }
  bool hasSamplingParameters() const { return t_.lightLogits >= 0 || t_.survival >= 0 || !t_.pixelLogits.empty(); }

  // Shape parameters: the meshes they move (sorted), and per rigidly moving mesh the theta index of
  // each motion component that moves it.
  bool hasShapeParameters() const { return !t_.movingMeshes.empty(); }
  // Every mesh a shape parameter moves (rigidly or vertex by vertex), ascending.
  const std::vector<uint32_t>& movingMeshes() const { return t_.movingMeshes; }
  bool moves(uint32_t mesh) const { return t_.moves(mesh); }
  const std::vector<ShapeField>& shapeFields(uint32_t mesh) const { return t_.meshFields[mesh]; }
  // The edges between a vertex parameter's vertices (parameter vertex indices, each edge once).
  const std::vector<std::pair<uint32_t, uint32_t>>& vertexEdges(const ParameterSlot& slot) const {
    return t_.vertices(uint32_t(slot.shape)).edges;
  }
  // A vertex parameter's mesh at `values` (the slot's part of theta): one vertex per parameter
  // vertex, the shape's triangles on them (triangles welding collapsed are dropped); normals
  // (computeSmoothNormals over the welded vertices) when the shape is smooth-shaded.
  // (param_vertices.cc)
  TriangleMesh vertexMesh(const Scene& scene, const ParameterSlot& slot, const float* values) const;
  // Whether the mesh's vertices are a parameter (shapes/<s>/vertices).
  bool deforms(uint32_t mesh) const { return t_.deforms(mesh); }
  // Camera parameters: whether any is registered, and whether view v's camera moves.
  bool hasCameraParameters() const { return !t_.cameraFields.empty(); }
  bool movesCamera(int view) const { return t_.cameraMoves(view); }
  // Whether mesh m moves relative to view v's camera (it moves, or the camera does): its edges are
  // then discontinuities that move on that view's film.
  bool movesOnFilm(uint32_t mesh, int view) const { return moves(mesh) || movesCamera(view); }
  // Parameters that move visibility discontinuities on the film (shapes or cameras): the boundary
  // terms and the interior terms of moving points apply.
  bool hasVisibilityParameters() const { return hasShapeParameters() || hasCameraParameters(); }
  // The shape-parameter adjoints of the estimators: the derivative of the loss with respect to a
  // point that moves with a moving mesh, taken to the parameters (no-op for a mesh that does not
  // move). A surface point (a hit: its triangle and barycentrics) with its unit shading normal:
  void addHitGradient(const Scene& scene, const SurfaceHit& hit, Vec3 dLdp, Vec3 dLdn, PathGradient& grad) const;
  // A point p carried with view v's camera, dLdp the derivative of the loss with respect to moving
  // it: dLdp . dp/dtheta_k for each component k of the view's camera parameters (no-op when the
  // camera does not move). The interior term passes the camera-ray point p = o + t d at fixed t
  // (the ray moves with the camera); a boundary term passes minus its film-space gradient at a
  // fixed world point, because moving the camera moves such a point the other way on the film.
  void addCameraPointGradient(const Scene& scene, int view, Vec3 p, Vec3 dLdp, PathGradient& grad) const;
  // A point p = lerp(v0, v1, t) of the edge between mesh vertices v0 and v1:
  void addEdgeGradient(const Scene& scene, uint32_t mesh, uint32_t v0, uint32_t v1, float t, Vec3 p, Vec3 dLdp, PathGradient& grad) const;
  // Takes the vertex-normal entries of `gradient` (adjointSize() long; scene at the parameters the
  // gradient was taken at) to the vertex positions through computeSmoothNormalsAdjoint, and cuts
  // it to size(). With `normals` false they are dropped instead (tests measure the term's share).
  void foldNormalAdjoints(const Scene& scene, std::vector<double>& gradient, bool normals = true) const;

 private:
  void applyOptions(ParameterSlot& slot, const ParameterOptions& o) const;
  // Rigid motion: dot(dLdp, dp/dtheta) for a point p of the mesh, and the same for a unit normal.
  void addPointGradient(const Scene& scene, uint32_t mesh, Vec3 p, Vec3 dLdp, PathGradient& grad) const;
  void addNormalGradient(const Scene& scene, uint32_t mesh, Vec3 n, Vec3 dLdn, PathGradient& grad) const;
  std::vector<ParameterSlot> slots_;
  ParameterTables t_;
  size_t size_ = 0;
};

// The invr name of a parameter: invr names (materials/..., lights/...) as given; a Mitsuba 3 name
// (mi.traverse's key) translated: <bsdf id>.reflectance.value or .diffuse_reflectance.value (a
// bitmap: .data) -> materials/<id>/albedo, <bsdf id>.alpha.value -> materials/<id>/roughness,
// twosided wrappers' <id>.brdf_0.<...> as <id>.<...>, <emitter id>.radiance.value or
// .intensity.value -> lights/<id>/intensity, <shape id>.emitter.radiance.value -> the light on
// that shape. Throws InputError saying what has no equivalent.
std::string invrParameterName(const Scene& scene, const std::string& name);

// All parameters of a zoo-style name prefix, e.g. every registered slot: "name[i]" for logs.
std::string describeParameters(const ParameterRegistry& registry);

}  // namespace invr
