#include "core/diff/parameters.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>

#include "core/error.h"
#include "core/geometry/edge_topology.h"
#include "core/io/suggest.h"

namespace invr {

namespace {

std::vector<std::string> split(const std::string& s, char sep = '/') {
  std::vector<std::string> parts;
  std::stringstream ss(s);
  std::string part;
  while (std::getline(ss, part, sep)) parts.push_back(part);
  return parts;
}

int materialIndex(const Scene& scene, const std::string& name) {
  for (size_t i = 0; i < scene.materials.size(); ++i)
    if (scene.materials[i].name == name) return int(i);
  for (size_t i = 0; i < scene.materials.size(); ++i)
    for (const auto& a : scene.materials[i].aliases)
      if (a == name) return int(i);
  return -1;
}

// "; did you mean 'red'?" from the names of a scene's materials, lights, shapes or groups.
template <class Items, class NameOf>
std::string closestOf(const std::string& given, const Items& items, NameOf nameOf) {
  std::vector<std::string> names;
  for (const auto& it : items) names.push_back(nameOf(it));
  return didYouMean(given, names);
}

int lightIndex(const Scene& scene, const std::string& name) {
  for (size_t i = 0; i < scene.lights.size(); ++i)
    if (scene.lights[i].name == name) return int(i);
  return -1;
}

}  // namespace

std::string invrParameterName(const Scene& scene, const std::string& name) {
  if (name.find('/') != std::string::npos || name.find('.') == std::string::npos) return name;
  // A Mitsuba 3 key (mi.traverse): <object path>.<property>[.value|.data].
  auto fail = [&](const std::string& why) -> std::string { throw InputError("parameter '" + name + "' (a Mitsuba name): " + why); };
  auto parts = split(name, '.');
  for (const auto& p : parts)
    if (p.empty()) return fail("empty component");
  // An envmap's bitmap: <emitter id>.data.
  if (parts.size() == 2 && parts[1] == "data" && lightIndex(scene, parts[0]) >= 0) return "lights/" + parts[0] + "/texels";
  if (parts.back() == "value" || parts.back() == "data") parts.pop_back();
  if (parts.size() < 2) return fail("expected <id>.<property>.value (or .data for a bitmap), e.g. red.reflectance.value");
  const std::string prop = parts.back();
  std::vector<std::string> owner(parts.begin(), parts.end() - 1);
  auto shapeIndex = [&](const std::string& id) {
    for (size_t m = 0; m < scene.meshNames.size(); ++m)
      if (scene.meshNames[m] == id) return int(m);
    return -1;
  };
  if (prop == "reflectance" || prop == "diffuse_reflectance" || prop == "alpha") {
    // <bsdf id>, <shape id>.bsdf (a bsdf nested in a shape), each optionally through a twosided
    // wrapper's child (.brdf_0).
    std::string material;
    size_t k = 1;
    if (owner.size() >= 2 && owner[1] == "bsdf" && shapeIndex(owner[0]) >= 0) {
      material = scene.materials[size_t(scene.meshMaterial[size_t(shapeIndex(owner[0]))])].name;
      k = 2;
    } else {
      int mi = materialIndex(scene, owner[0]);
      if (mi < 0) return fail("no material (bsdf) with id '" + owner[0] + "'");
      material = scene.materials[size_t(mi)].name;
    }
    if (k < owner.size() && owner[k] == "brdf_0") ++k;
    if (k != owner.size()) return fail("no bsdf property at '" + name + "'");
    return "materials/" + material + (prop == "alpha" ? "/roughness" : "/albedo");
  }
  if (prop == "vertex_positions" || prop == "positions") {  // mi.traverse: a mesh's vertex buffer
    if (owner.size() != 1 || shapeIndex(owner[0]) < 0) return fail("no shape (mesh) with id '" + owner[0] + "'");
    return "shapes/" + owner[0] + "/vertices";
  }
  if (prop == "radiance" || prop == "intensity") {
    if (owner.size() == 1 && lightIndex(scene, owner[0]) >= 0) return "lights/" + owner[0] + "/intensity";
    // <shape id>.emitter: the area light on that shape.
    if (owner.size() == 2 && owner[1] == "emitter") {
      int m = shapeIndex(owner[0]);
      if (m < 0) return fail("no shape with id '" + owner[0] + "'");
      if (scene.meshLight[size_t(m)] < 0) return fail("shape '" + owner[0] + "' does not emit");
      return "lights/" + scene.lights[size_t(scene.meshLight[size_t(m)])].name + "/intensity";
    }
    return fail("no emitter with id '" + owner[0] + "'");
  }
  return fail("property '" + prop + "' has no invr parameter (reflectance, diffuse_reflectance and alpha of a bsdf; radiance or intensity of an emitter; vertex_positions or positions of a mesh; data of an envmap)");
}

const ParameterSlot& ParameterRegistry::add(const Scene& scene, const std::string& givenName, const ParameterOptions& o) {
  auto fail = [&](const std::string& why) -> const ParameterSlot& {
    throw InputError("parameter '" + givenName + "': " + why);
  };
  if (find(givenName)) return fail("listed twice");
  const std::string name = invrParameterName(scene, givenName);
  auto parts = split(name);
  if (!parts.empty() && parts[0] == "sampling") return addSampling(scene, givenName, parts, o);
  if (!parts.empty() && (parts[0] == "shapes" || parts[0] == "groups")) return addShape(scene, givenName, parts, o);
  if (parts.size() != 3)
    return fail("expected materials/<name>/albedo|roughness, lights/<name>/intensity, shapes/<name>/translation|rotation|scale|vertices, "
                "groups/<name>/translation|rotation|scale or sampling/...");
  ParameterSlot slot;
  slot.name = givenName;
  if (parts[0] == "materials") {
    int m = materialIndex(scene, parts[1]);
    if (m < 0) return fail("no material named '" + parts[1] + "'" + closestOf(parts[1], scene.materials, [](const auto& x) { return x.name; }));
    const Material& mat = scene.materials[size_t(m)];
    slot.material = m;
    const Texture* tex = nullptr;
    if (parts[2] == "albedo") {
      if (!mat.hasAlbedo()) return fail("material '" + parts[1] + "' has no albedo (only diffuse and rough_plastic do)");
      slot.kind = ParamKind::Albedo;
      slot.channels = 3;
      slot.lower = kPositiveFloor;
      slot.upper = 1.f;
      tex = &mat.albedo;
    } else if (parts[2] == "roughness") {
      if (!mat.hasRoughness()) return fail("material '" + parts[1] + "' has no roughness (only rough_conductor and rough_plastic do)");
      slot.kind = ParamKind::Roughness;
      slot.channels = 1;
      slot.lower = 0.01f;
      slot.upper = 1.f;
      tex = &mat.roughness;
    } else {
      return fail("unknown material property '" + parts[2] + "' (use albedo or roughness)");
    }
    if (!tex->isConstant()) {
      if (tex->scale() == 0.f) return fail("texture scale is 0, so its texels cannot be recovered");
      slot.width = tex->image()->width();
      slot.height = tex->image()->height();
    }
  } else if (parts[0] == "lights") {
    int l = lightIndex(scene, parts[1]);
    if (l < 0) return fail("no light named '" + parts[1] + "'" + closestOf(parts[1], scene.lights, [](const auto& x) { return x.name; }));
    const Light& light = scene.lights[size_t(l)];
    const bool image = light.kind == LightKind::Environment;
    if (parts[2] == "texels") {
      if (!image) return fail("light '" + parts[1] + "' is not an image environment map: its value is lights/" + parts[1] + "/intensity");
      if (!(light.scale > 0.f)) return fail("the environment's scale is " + std::to_string(light.scale) + ", so its texels cannot be recovered");
      slot.kind = ParamKind::EnvironmentTexels;
      slot.width = light.envImage->width();
      slot.height = light.envImage->height();
    } else if (parts[2] == "intensity") {
      if (image)
        return fail("an image environment map's radiance is its texels: use lights/" + parts[1] + "/texels (Mitsuba: " + parts[1] + ".data)");
      slot.kind = ParamKind::LightIntensity;
    } else {
      return fail("unknown light property '" + parts[2] + "' (use " + (image ? "texels" : "intensity") + ")");
    }
    slot.light = l;
    slot.channels = 3;
    slot.lower = kPositiveFloor;
    slot.upper = std::numeric_limits<float>::infinity();
  } else {
    return fail("unknown parameter group '" + parts[0] + "' (use materials, lights, shapes, groups or sampling)");
  }
  slot.size = uint32_t(slot.channels * (slot.width > 0 ? slot.width * slot.height : 1));
  applyOptions(slot, o);
  auto& table = slot.kind == ParamKind::Albedo      ? albedo_
                : slot.kind == ParamKind::Roughness ? roughness_
                : slot.kind == ParamKind::EnvironmentTexels ? texels_
                                                            : intensity_;
  int owner = slot.material >= 0 ? slot.material : slot.light;
  if (size_t(owner) < table.size() && table[size_t(owner)] >= 0)
    for (const auto& other : slots_)
      if (int(other.offset) == table[size_t(owner)]) return fail("the same value as parameter '" + other.name + "', listed twice");
  size_ += slot.size;
  if (table.size() <= size_t(owner)) table.resize(size_t(owner) + 1, -1);
  table[size_t(owner)] = int(slot.offset);
  slots_.push_back(slot);
  return slots_.back();
}

void ParameterRegistry::applyOptions(ParameterSlot& slot, const ParameterOptions& o) const {
  auto fail = [&](const std::string& why) { throw InputError("parameter '" + slot.name + "': " + why); };
  slot.offset = uint32_t(size_);
  if (o.lower) slot.lower = *o.lower;
  if (o.upper) slot.upper = *o.upper;
  if (o.learningRate) slot.learningRate = *o.learningRate;
  if (o.largeStepsLambda) {
    if (slot.kind != ParamKind::ShapeVertices) fail("large_steps_lambda applies to vertex parameters (shapes/<name>/vertices) only");
    if (!(*o.largeStepsLambda >= 0.f) || !std::isfinite(*o.largeStepsLambda))
      fail("large_steps_lambda must be a finite number >= 0 (got " + std::to_string(*o.largeStepsLambda) + ")");
    slot.largeStepsLambda = *o.largeStepsLambda;
  }
  if (!(slot.lower <= slot.upper)) fail("bounds are inverted (lower " + std::to_string(slot.lower) + " > upper " + std::to_string(slot.upper) + ")");
  if (!(slot.learningRate > 0.f) || !std::isfinite(slot.learningRate)) fail("learning rate must be a positive finite number");
}

const ParameterSlot& ParameterRegistry::addSampling(const Scene& scene, const std::string& givenName, const std::vector<std::string>& parts,
                                                    const ParameterOptions& o) {
  auto fail = [&](const std::string& why) -> const ParameterSlot& { throw InputError("parameter '" + givenName + "': " + why); };
  const std::string usage = "use sampling/light_logits, sampling/pixel_light_logits/<view> or sampling/rr_survival";
  if (parts.size() < 2) return fail(usage);
  ParameterSlot slot;
  slot.name = givenName;
  slot.channels = 1;
  const int lights = int(scene.lights.size());
  if (parts[1] == "light_logits" && parts.size() == 2) {
    if (lights < 2) return fail("light selection needs at least two lights (the scene has " + std::to_string(lights) + ")");
    if (lightLogits_ >= 0) return fail("listed twice");
    slot.kind = ParamKind::LightLogits;
    slot.size = uint32_t(lights);
    slot.lower = -20.f;
    slot.upper = 20.f;
    slot.learningRate = 0.1f;
  } else if (parts[1] == "pixel_light_logits" && parts.size() == 3) {
    if (lights < 2) return fail("light selection needs at least two lights (the scene has " + std::to_string(lights) + ")");
    char* end = nullptr;
    long view = std::strtol(parts[2].c_str(), &end, 10);
    if (parts[2].empty() || *end != '\0' || view < 0 || view >= long(scene.cameras.size()))
      return fail("view '" + parts[2] + "' is not a view index (the scene has " + std::to_string(scene.cameras.size()) + " views, 0.." +
                  std::to_string(int(scene.cameras.size()) - 1) + ")");
    if (pixelLogits(int(view))) return fail("listed twice");
    const int w = o.mapWidth > 0 ? o.mapWidth : scene.width, h = o.mapHeight > 0 ? o.mapHeight : scene.height;
    if (w > scene.width || h > scene.height || o.mapWidth < 0 || o.mapHeight < 0)
      return fail("map resolution " + std::to_string(w) + "x" + std::to_string(h) + " must be positive and at most the film's (" +
                  std::to_string(scene.width) + "x" + std::to_string(scene.height) + ")");
    slot.kind = ParamKind::PixelLightLogits;
    slot.view = int(view);
    slot.width = w;
    slot.height = h;
    slot.channels = lights;
    slot.size = uint32_t(w * h * lights);
    slot.lower = -20.f;
    slot.upper = 20.f;
    slot.learningRate = 0.1f;
  } else if (parts[1] == "rr_survival" && parts.size() == 2) {
    if (scene.sampling.survival.empty())
      return fail("needs fixed-survival Russian roulette (render.russian_roulette \"fixed\"; a job naming this parameter gets it)");
    if (survival_ >= 0) return fail("listed twice");
    slot.kind = ParamKind::Survival;
    slot.size = uint32_t(scene.sampling.survival.size());
    slot.lower = 0.05f;
    slot.upper = 1.f;
    slot.learningRate = 0.02f;
  } else {
    return fail(usage);
  }
  applyOptions(slot, o);
  if (slot.kind == ParamKind::LightLogits) lightLogits_ = int(slot.offset);
  if (slot.kind == ParamKind::Survival) survival_ = int(slot.offset);
  if (slot.kind == ParamKind::PixelLightLogits) {
    if (pixelLogits_.size() <= size_t(slot.view)) pixelLogits_.resize(size_t(slot.view) + 1, -1);
    pixelLogits_[size_t(slot.view)] = int(slots_.size());
  }
  size_ += slot.size;
  slots_.push_back(slot);
  return slots_.back();
}

const ParameterSlot& ParameterRegistry::addShape(const Scene& scene, const std::string& givenName, const std::vector<std::string>& parts,
                                                 const ParameterOptions& o) {
  auto fail = [&](const std::string& why) -> const ParameterSlot& { throw InputError("parameter '" + givenName + "': " + why); };
  const bool isGroup = parts[0] == "groups";
  const std::string what = isGroup ? "group" : "shape";
  const std::string usage = "expected " + parts[0] +
                            (isGroup ? "/<name>/translation, rotation or scale" : "/<name>/translation, rotation, scale or vertices") +
                            ", or one component: " + parts[0] + "/<name>/translation/x (or y, z), .../rotation/x (or y, z)";
  if (parts.size() != 3 && parts.size() != 4) return fail(usage);
  // One component of a translation or rotation on its own: the degrees of freedom a problem has.
  int component = -1;
  if (parts.size() == 4) {
    if ((parts[2] != "translation" && parts[2] != "rotation") || parts[3].size() != 1 || parts[3][0] < 'x' || parts[3][0] > 'z')
      return fail(usage);
    component = parts[3][0] - 'x';
  }
  ParameterSlot slot;
  slot.name = givenName;
  std::vector<uint32_t> meshes;
  if (isGroup) {
    for (size_t g = 0; g < scene.groups.size(); ++g)
      if (scene.groups[g].name == parts[1]) slot.group = int(g);
    if (slot.group < 0) return fail("no group named '" + parts[1] + "' (scene.groups)" + closestOf(parts[1], scene.groups, [](const auto& x) { return x.name; }));
    meshes = scene.groups[size_t(slot.group)].meshes;
  } else {
    for (size_t m = 0; m < scene.meshNames.size(); ++m)
      if (scene.meshNames[m] == parts[1]) slot.shape = int(m);
    if (slot.shape < 0) return fail("no shape named '" + parts[1] + "'" + closestOf(parts[1], scene.meshNames, [](const auto& x) { return x; }));
    meshes = {uint32_t(slot.shape)};
  }
  for (uint32_t m : meshes)
    if (scene.meshLight[m] >= 0)
      return fail("shape '" + scene.meshNames[m] + "' emits light ('" + scene.lights[size_t(scene.meshLight[m])].name +
                  "'): moving emitters is not supported yet");
  // A mesh moves either rigidly or vertex by vertex.
  for (uint32_t m : meshes) {
    if (deforms(m) && parts[2] == "vertices") return fail("the vertices of shape '" + scene.meshNames[m] + "' are listed twice");
    if (deforms(m))
      return fail("shape '" + scene.meshNames[m] + "' has its vertices as a parameter; a pose parameter cannot move it too (move the vertices)");
  }
  if (parts[2] == "vertices") {
    if (isGroup) return fail("vertices are a parameter of a shape, not of a group (shapes/<name>/vertices)");
    return addVertices(scene, givenName, uint32_t(slot.shape), o);
  }
  int firstField = 0;
  if (parts[2] == "translation") {
    slot.kind = ParamKind::ShapeTranslation;
    slot.channels = 3;
    slot.lower = -std::numeric_limits<float>::infinity();
    slot.upper = std::numeric_limits<float>::infinity();
    // In the scene's units: a step of 1/400 of its radius (0.011 on the zoo's pose scene).
    slot.learningRate = 2.5e-3f * scene.radius;
  } else if (parts[2] == "rotation") {
    slot.kind = ParamKind::ShapeRotation;
    slot.channels = 3;
    slot.lower = -360.f;
    slot.upper = 360.f;
    slot.learningRate = 0.5f;  // degrees
    firstField = 3;
  } else if (parts[2] == "scale") {
    slot.kind = ParamKind::ShapeScale;
    slot.channels = 1;
    slot.lower = 0.01f;
    slot.upper = 100.f;
    slot.learningRate = 0.01f;
    firstField = 6;
  } else {
    return fail("unknown " + what + " property '" + parts[2] + (isGroup ? "' (use translation, rotation or scale)" : "' (use translation, rotation, scale or vertices)"));
  }
  if (component >= 0) {
    slot.channels = 1;
    slot.component = component;
    firstField += component;
  }
  for (const auto& other : slots_)
    if (other.kind == slot.kind && other.shape == slot.shape && other.group == slot.group &&
        (other.component < 0 || slot.component < 0 || other.component == slot.component))
      return fail("the same value as parameter '" + other.name + "', listed twice");
  slot.size = uint32_t(slot.channels);
  applyOptions(slot, o);
  if (slot.kind == ParamKind::ShapeScale && !(slot.lower > 0.f)) return fail("the lower bound of a scale must be positive");
  if (meshFields_.size() < scene.meshes.size()) meshFields_.resize(scene.meshes.size());
  for (uint32_t m : meshes) {
    for (int c = 0; c < slot.channels; ++c)
      meshFields_[m].push_back({slot.offset + uint32_t(c), firstField + c + (isGroup ? RigidMotion::kComponents : 0)});
    if (std::find(rigidMeshes_.begin(), rigidMeshes_.end(), m) == rigidMeshes_.end()) rigidMeshes_.push_back(m);
    markMoving(scene, m);
  }
  std::sort(rigidMeshes_.begin(), rigidMeshes_.end());
  size_ += slot.size;
  slots_.push_back(slot);
  return slots_.back();
}

void ParameterRegistry::markMoving(const Scene& scene, uint32_t m) {
  if (moving_.size() < scene.meshes.size()) moving_.resize(scene.meshes.size(), 0);
  if (moving_[m]) return;
  moving_[m] = 1;
  movingMeshes_.insert(std::lower_bound(movingMeshes_.begin(), movingMeshes_.end(), m), m);
}

const ParameterSlot& ParameterRegistry::addVertices(const Scene& scene, const std::string& givenName, uint32_t mesh, const ParameterOptions& o) {
  auto fail = [&](const std::string& why) -> const ParameterSlot& { throw InputError("parameter '" + givenName + "': " + why); };
  if (moves(mesh))
    return fail("shape '" + scene.meshNames[mesh] + "' already moves with a pose parameter (shapes/.../translation, rotation, scale or its group's); "
                "a mesh moves rigidly or vertex by vertex, not both");
  const TriangleMesh& m = scene.meshes[mesh];
  if (m.positions.empty()) return fail("shape '" + scene.meshNames[mesh] + "' has no vertices");
  // Copies of a vertex at uv or normal seams move as one, or the seams would open: the parameter
  // has one vertex per welded position, welded as the edge topology welds (edge_topology.h).
  const EdgeTopology topology = EdgeTopology::build(m);
  VertexField field;
  field.weld.resize(m.positions.size());
  field.representative.assign(topology.weldedVertices(), UINT32_MAX);
  for (uint32_t v = 0; v < m.positions.size(); ++v) {
    const uint32_t w = topology.welded(v);
    field.weld[v] = w;
    if (field.representative[w] == UINT32_MAX) field.representative[w] = v;
  }
  for (const MeshEdge& e : topology.edges()) field.edges.emplace_back(topology.welded(e.v0), topology.welded(e.v1));
  ParameterSlot slot;
  slot.name = givenName;
  slot.kind = ParamKind::ShapeVertices;
  slot.shape = int(mesh);
  slot.channels = 3;
  slot.size = uint32_t(3 * field.representative.size());
  slot.offset = uint32_t(size_);
  slot.lower = -std::numeric_limits<float>::infinity();
  slot.upper = std::numeric_limits<float>::infinity();
  // A step of a thousandth of the scene's size: vertices move in the scene's units.
  slot.learningRate = 1e-3f * 2.f * scene.radius;
  applyOptions(slot, o);
  field.offset = slot.offset;
  field.mesh = mesh;
  // Smooth meshes keep their shading: their vertex normals are recomputed from the positions
  // after every update (Scene::deformMesh), and differentiated through.
  if (!m.normals.empty()) {
    field.normalOffset = int64_t(normalAdjoints_);
    normalAdjoints_ += 3 * m.positions.size();
  }
  if (vertexField_.size() < scene.meshes.size()) vertexField_.resize(scene.meshes.size(), -1);
  vertexField_[mesh] = int(vertexFields_.size());
  vertexFields_.push_back(std::move(field));
  markMoving(scene, mesh);
  size_ += slot.size;
  slots_.push_back(slot);
  return slots_.back();
}

TriangleMesh ParameterRegistry::vertexMesh(const Scene& scene, const ParameterSlot& slot, const float* values) const {
  const VertexField& f = vertexFields_[size_t(vertexField_[size_t(slot.shape)])];
  TriangleMesh out;
  out.positions.resize(f.representative.size());
  for (size_t w = 0; w < out.positions.size(); ++w) out.positions[w] = Vec3(values[3 * w], values[3 * w + 1], values[3 * w + 2]);
  const TriangleMesh& m = scene.meshes[size_t(slot.shape)];
  for (size_t t = 0; t < m.triangleCount(); ++t) {
    const uint32_t a = f.weld[m.indices[3 * t]], b = f.weld[m.indices[3 * t + 1]], c = f.weld[m.indices[3 * t + 2]];
    if (a == b || b == c || a == c) continue;
    out.indices.insert(out.indices.end(), {a, b, c});
  }
  if (!m.normals.empty()) computeSmoothNormals(out);  // smooth meshes written smooth
  return out;
}

void ParameterRegistry::addHitGradient(const Scene& scene, const SurfaceHit& hit, Vec3 dLdp, Vec3 dLdn, PathGradient& grad) const {
  if (!moves(hit.mesh)) return;
  const bool normal = !(dLdn == Vec3(0.f));
  if (!deforms(hit.mesh)) {
    addPointGradient(scene, hit.mesh, hit.p, dLdp, grad);
    if (normal) addNormalGradient(scene, hit.mesh, hit.ns, dLdn, grad);
    return;
  }
  const VertexField& f = vertexFields_[size_t(vertexField_[hit.mesh])];
  const TriangleMesh& m = scene.meshes[hit.mesh];
  const uint32_t* idx = &m.indices[3 * size_t(hit.tri)];
  auto add = [&](uint32_t v, Vec3 g) {
    const uint32_t base = f.offset + 3 * f.weld[v];
    for (uint32_t c = 0; c < 3; ++c)
      if (g[int(c)] != 0.f) grad.add(base + c, g[int(c)]);
  };
  // p = b0 a + b1 b + b2 c: dp/dv_i = b_i.
  const float b[3] = {1.f - hit.b1 - hit.b2, hit.b1, hit.b2};
  Vec3 gv[3] = {dLdp * b[0], dLdp * b[1], dLdp * b[2]};
  if (normal && f.normalOffset >= 0) {
    // ns = ±n / |n| with n = sum b_i N_i, the vertex normals interpolated: dL/dN_i = b_i q with
    // q = ±(I - ns ns^T) dLdn / |n|. Those go to the hidden vertex-normal entries, folded into the
    // positions once per evaluation (foldNormalAdjoints).
    const Vec3 n = m.normals[idx[0]] * b[0] + m.normals[idx[1]] * b[1] + m.normals[idx[2]] * b[2];
    const float len = length(n);
    if (len > 0.f) {
      const float sign = dot(n, hit.ns) < 0.f ? -1.f : 1.f;
      const Vec3 q = (dLdn - hit.ns * dot(hit.ns, dLdn)) * (sign / len);
      for (int i = 0; i < 3; ++i) {
        const uint32_t base = uint32_t(size_ + size_t(f.normalOffset) + 3 * size_t(idx[i]));
        for (uint32_t c = 0; c < 3; ++c)
          if (q[int(c)] != 0.f && b[i] != 0.f) grad.add(base + c, q[int(c)] * b[i]);
      }
    }
  } else if (normal) {
    // ns = ng = N / |N|, N = (b - a) x (c - a) (flat shading): dN for a move d of vertex i is
    // d x (v_{i+1} - v_{i+2}), so dLoss/dv_i = (v_{i+1} - v_{i+2}) x q with q = (I - n n^T) dLdn / |N|.
    const Vec3 p[3] = {m.positions[idx[0]], m.positions[idx[1]], m.positions[idx[2]]};
    const Vec3 N = cross(p[1] - p[0], p[2] - p[0]);
    const float len = length(N);
    if (len > 0.f) {
      const Vec3 n = N / len;
      const Vec3 q = (dLdn - n * dot(n, dLdn)) / len;
      for (int i = 0; i < 3; ++i) gv[i] = gv[i] + cross(p[(i + 1) % 3] - p[(i + 2) % 3], q);
    }
  }
  for (int i = 0; i < 3; ++i) add(idx[i], gv[i]);
}

void ParameterRegistry::foldNormalAdjoints(const Scene& scene, std::vector<double>& gradient, bool normals) const {
  if (normalAdjoints_ == 0) return;
  INVR_INVARIANT(gradient.size() == adjointSize(), "the gradient holds the vertex-normal entries");
  if (normals)
    for (const VertexField& f : vertexFields_) {
      if (f.normalOffset < 0) continue;
      const TriangleMesh& m = scene.meshes[f.mesh];
      const double* dn = gradient.data() + size_ + size_t(f.normalOffset);
      std::vector<Vec3> dNormals(m.positions.size()), dPositions;
      for (size_t v = 0; v < dNormals.size(); ++v) dNormals[v] = Vec3(float(dn[3 * v]), float(dn[3 * v + 1]), float(dn[3 * v + 2]));
      computeSmoothNormalsAdjoint(m, dNormals, dPositions, &f.weld);
      for (size_t v = 0; v < dPositions.size(); ++v)
        for (int c = 0; c < 3; ++c) gradient[f.offset + 3 * size_t(f.weld[v]) + size_t(c)] += double(dPositions[v][c]);
    }
  gradient.resize(size_);
}

void ParameterRegistry::addEdgeGradient(const Scene& scene, uint32_t mesh, uint32_t v0, uint32_t v1, float t, Vec3 p, Vec3 dLdp,
                                        PathGradient& grad) const {
  if (!moves(mesh)) return;
  if (!deforms(mesh)) return addPointGradient(scene, mesh, p, dLdp, grad);
  const VertexField& f = vertexFields_[size_t(vertexField_[mesh])];
  for (const auto& [v, w] : {std::pair{v0, 1.f - t}, std::pair{v1, t}}) {
    const uint32_t base = f.offset + 3 * f.weld[v];
    for (uint32_t c = 0; c < 3; ++c)
      if (dLdp[int(c)] != 0.f && w != 0.f) grad.add(base + c, dLdp[int(c)] * w);
  }
}

void ParameterRegistry::addPointGradient(const Scene& scene, uint32_t mesh, Vec3 p, Vec3 dLdp, PathGradient& grad) const {
  if (!moves(mesh)) return;
  for (const auto& f : meshFields_[mesh]) grad.add(f.index, dot(dLdp, scene.motion.pointVelocity(mesh, f.field, p)));
}

void ParameterRegistry::addNormalGradient(const Scene& scene, uint32_t mesh, Vec3 n, Vec3 dLdn, PathGradient& grad) const {
  if (!moves(mesh)) return;
  for (const auto& f : meshFields_[mesh]) grad.add(f.index, dot(dLdn, scene.motion.normalVelocity(mesh, f.field, n)));
}

const ParameterSlot* ParameterRegistry::find(const std::string& name) const {
  for (const auto& s : slots_)
    if (s.name == name) return &s;
  return nullptr;
}

std::vector<float> ParameterRegistry::read(const Scene& scene) const {
  std::vector<float> theta(size_);
  for (const auto& s : slots_) {
    float* out = theta.data() + s.offset;
    if (readSampling(scene, s, out)) continue;
    if (readShape(scene, s, out)) continue;
    if (s.kind == ParamKind::ShapeVertices) {
      const VertexField& f = vertexFields_[size_t(vertexField_[size_t(s.shape)])];
      const auto& pos = scene.meshes[size_t(s.shape)].positions;
      for (size_t w = 0; w < f.representative.size(); ++w)
        for (int c = 0; c < 3; ++c) out[3 * w + size_t(c)] = pos[f.representative[w]][c];
      continue;
    }
    if (s.kind == ParamKind::LightIntensity) {
      const Light& l = scene.lights[size_t(s.light)];
      Rgb v = (l.kind == LightKind::Point || l.kind == LightKind::Spot) ? l.intensity : l.radiance;
      out[0] = v.x; out[1] = v.y; out[2] = v.z;
      continue;
    }
    if (s.kind == ParamKind::EnvironmentTexels) {
      const Light& l = scene.lights[size_t(s.light)];
      const Image& im = *l.envImage;
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x) {
          const Rgb v = im.rgb(x, y) * l.scale;
          for (int c = 0; c < 3; ++c) out[3 * (y * s.width + x) + c] = v[c];
        }
      continue;
    }
    const Material& m = scene.materials[size_t(s.material)];
    const Texture& t = s.kind == ParamKind::Albedo ? m.albedo : m.roughness;
    if (t.isConstant()) {
      for (int c = 0; c < s.channels; ++c) out[c] = t.constant()[c];
      continue;
    }
    const Image& im = *t.image();
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x)
        for (int c = 0; c < s.channels; ++c) out[(y * s.width + x) * s.channels + c] = im.at(x, y, std::min(c, im.channels() - 1)) * t.scale();
  }
  return theta;
}

void ParameterRegistry::write(const std::vector<float>& theta, Scene& scene, bool refreshSampling) const {
  if (theta.size() != size_) throw InputError("parameter vector has " + std::to_string(theta.size()) + " values, expected " + std::to_string(size_));
  bool emissionChanged = false, selectionChanged = false;
  for (const auto& s : slots_) {
    const float* in = theta.data() + s.offset;
    switch (s.kind) {
      case ParamKind::LightLogits:
        scene.sampling.lightLogits.assign(in, in + s.size);
        selectionChanged = true;
        continue;
      case ParamKind::PixelLightLogits: {
        if (scene.sampling.pixelLogits.size() <= size_t(s.view)) scene.sampling.pixelLogits.resize(size_t(s.view) + 1);
        auto& map = scene.sampling.pixelLogits[size_t(s.view)];
        map.width = s.width;
        map.height = s.height;
        map.logits.assign(in, in + s.size);
        continue;
      }
      case ParamKind::Survival: scene.sampling.survival.assign(in, in + s.size); continue;
      case ParamKind::ShapeVertices: {
        const VertexField& f = vertexFields_[size_t(vertexField_[size_t(s.shape)])];
        std::vector<Vec3> positions(f.weld.size());
        for (size_t v = 0; v < positions.size(); ++v) {
          const float* xyz = in + 3 * size_t(f.weld[v]);
          positions[v] = Vec3(xyz[0], xyz[1], xyz[2]);
        }
        scene.deformMesh(uint32_t(s.shape), positions, &f.weld);
        continue;
      }
      case ParamKind::ShapeTranslation:
      case ParamKind::ShapeRotation:
      case ParamKind::ShapeScale: {
        RigidMotion& m = s.group >= 0 ? scene.motion.group(uint32_t(s.group)) : scene.motion.mesh(uint32_t(s.shape));
        if (s.component >= 0) (s.kind == ParamKind::ShapeTranslation ? m.translation : m.rotationDegrees)[s.component] = in[0];
        else if (s.kind == ParamKind::ShapeTranslation) m.translation = Vec3(in[0], in[1], in[2]);
        else if (s.kind == ParamKind::ShapeRotation) m.rotationDegrees = Vec3(in[0], in[1], in[2]);
        else m.scale = in[0];
        continue;
      }
      default: break;
    }
    if (s.kind == ParamKind::EnvironmentTexels) {
      Light& l = scene.lights[size_t(s.light)];
      if (l.envImage->channels() < 3) l.envImage = std::make_shared<Image>(s.width, s.height, 3);  // a grey map turns colour
      Image& im = *l.envImage;
      const float inv = 1.f / l.scale;
      for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x) im.setRgb(x, y, Rgb(in[3 * (y * s.width + x)], in[3 * (y * s.width + x) + 1], in[3 * (y * s.width + x) + 2]) * inv);
      // The map is sampled by its texels' luminance: rebuilt here, and detached from the
      // derivative (an estimator's expectation does not depend on its sampling density).
      if (refreshSampling) buildEnvironmentDistribution(l);
      emissionChanged = true;
      continue;
    }
    if (s.kind == ParamKind::LightIntensity) {
      Light& l = scene.lights[size_t(s.light)];
      Rgb v(in[0], in[1], in[2]);
      if (l.kind == LightKind::Point || l.kind == LightKind::Spot) l.intensity = v;
      else l.radiance = v;
      emissionChanged = true;
      continue;
    }
    Material& m = scene.materials[size_t(s.material)];
    Texture& t = s.kind == ParamKind::Albedo ? m.albedo : m.roughness;
    if (t.isConstant()) {
      t.setConstant(s.channels == 3 ? Rgb(in[0], in[1], in[2]) : Rgb(in[0]));
      continue;
    }
    Image& im = *t.mutableImage();
    float inv = 1.f / t.scale();
    for (int y = 0; y < s.height; ++y)
      for (int x = 0; x < s.width; ++x)
        for (int c = 0; c < im.channels(); ++c) im.at(x, y, c) = in[(y * s.width + x) * s.channels + std::min(c, s.channels - 1)] * inv;
  }
  if (!rigidMeshes_.empty()) scene.applyShapeMotion(rigidMeshes_);
  // Logits are sampling itself: always applied. Power-based selection follows emission unless
  // the caller keeps sampling fixed.
  if (selectionChanged || (emissionChanged && refreshSampling)) scene.updateLightSelection();
}

void ParameterRegistry::clampToBounds(std::vector<float>& theta) const {
  for (const auto& s : slots_)
    for (uint32_t i = 0; i < s.size; ++i) theta[s.offset + i] = std::clamp(theta[s.offset + i], s.lower, s.upper);
}

bool ParameterRegistry::readShape(const Scene& scene, const ParameterSlot& s, float* out) const {
  if (s.kind != ParamKind::ShapeTranslation && s.kind != ParamKind::ShapeRotation && s.kind != ParamKind::ShapeScale) return false;
  const RigidMotion& m = s.group >= 0 ? scene.motion.group(uint32_t(s.group)) : scene.motion.mesh(uint32_t(s.shape));
  Vec3 v = s.kind == ParamKind::ShapeTranslation ? m.translation : s.kind == ParamKind::ShapeRotation ? m.rotationDegrees : Vec3(m.scale);
  if (s.component >= 0) out[0] = v[s.component];
  else
    for (int c = 0; c < s.channels; ++c) out[c] = v[c];
  return true;
}

bool ParameterRegistry::readSampling(const Scene& scene, const ParameterSlot& s, float* out) const {
  // The pmf logits start from: the scene's selection now (log pmf, floored at the lower bound).
  auto currentLogits = [&](float* dst) {
    for (size_t i = 0; i < scene.lights.size(); ++i) {
      float p = scene.lightSelection().pmf(i);
      dst[i] = p > 0.f ? std::max(std::log(p), s.lower) : s.lower;
    }
  };
  switch (s.kind) {
    case ParamKind::LightLogits:
      if (scene.sampling.lightLogits.size() == s.size) std::copy(scene.sampling.lightLogits.begin(), scene.sampling.lightLogits.end(), out);
      else currentLogits(out);
      return true;
    case ParamKind::PixelLightLogits: {
      const auto* map = size_t(s.view) < scene.sampling.pixelLogits.size() ? &scene.sampling.pixelLogits[size_t(s.view)] : nullptr;
      if (map && map->logits.size() == s.size) {
        std::copy(map->logits.begin(), map->logits.end(), out);
      } else {
        for (int c = 0; c < s.width * s.height; ++c) currentLogits(out + size_t(c) * size_t(s.channels));
      }
      return true;
    }
    case ParamKind::Survival:
      std::copy(scene.sampling.survival.begin(), scene.sampling.survival.end(), out);
      return true;
    default: return false;
  }
}

std::string describeParameters(const ParameterRegistry& r) {
  std::string out;
  for (const auto& s : r.slots()) {
    out += s.name + "[" + std::to_string(s.size) + "]";
    if (s.width > 0) out += " (" + std::to_string(s.width) + "x" + std::to_string(s.height) + (s.kind == ParamKind::PixelLightLogits ? " map)" : " texture)");
    out += "\n";
  }
  return out;
}

}  // namespace invr
