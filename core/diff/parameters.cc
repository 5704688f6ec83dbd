#include "core/diff/parameters.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>

#include "core/diff/parameter_kind.h"
#include "core/error.h"
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

// "a, b or c"
std::string listOf(const std::vector<std::string>& items) {
  std::string out;
  for (size_t i = 0; i < items.size(); ++i) out += (i == 0 ? "" : i + 1 == items.size() ? " or " : ", ") + items[i];
  return out;
}

struct KindRegistry {
  std::vector<std::pair<int, std::unique_ptr<ParameterKind>>> owned;
  std::vector<const ParameterKind*> ordered;
};
KindRegistry& kinds() {
  static KindRegistry r;
  return r;
}

}  // namespace

RegisterParameterKind::RegisterParameterKind(int order, std::unique_ptr<ParameterKind> kind) {
  KindRegistry& r = kinds();
  for (const auto& [o, k] : r.owned)
    if (std::string(k->name()) == kind->name()) throw std::logic_error(std::string("parameter kind '") + kind->name() + "' registered twice");
  r.owned.emplace_back(order, std::move(kind));
  std::stable_sort(r.owned.begin(), r.owned.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  r.ordered.clear();
  for (const auto& [o, k] : r.owned) r.ordered.push_back(k.get());
}

const std::vector<const ParameterKind*>& parameterKinds() { return kinds().ordered; }

bool ParameterKind::claims(const std::vector<std::string>& parts) const {
  if (parts.empty()) return false;
  const auto g = groups();
  if (std::find(g.begin(), g.end(), parts[0]) == g.end()) return false;
  const size_t at = parts[0] == "sampling" ? 1 : 2;
  return parts.size() > at && parts[at] == property();
}

std::string ParameterKind::fromMitsuba(const Scene&, const std::vector<std::string>&, const std::string&, bool) const { return ""; }

int ParameterKind::catalogChannels(const ParameterSlot& slot) const { return slot.channels; }

int materialIndex(const Scene& scene, const std::string& name) {
  for (size_t i = 0; i < scene.materials.size(); ++i)
    if (scene.materials[i].name == name) return int(i);
  for (size_t i = 0; i < scene.materials.size(); ++i)
    for (const auto& a : scene.materials[i].aliases)
      if (a == name) return int(i);
  return -1;
}

int lightIndex(const Scene& scene, const std::string& name) {
  for (size_t i = 0; i < scene.lights.size(); ++i)
    if (scene.lights[i].name == name) return int(i);
  return -1;
}

int meshIndex(const Scene& scene, const std::string& name) {
  for (size_t m = 0; m < scene.meshNames.size(); ++m)
    if (scene.meshNames[m] == name) return int(m);
  return -1;
}

std::string closestName(const std::string& given, const std::vector<std::string>& names) { return didYouMean(given, names); }

void failParameter(const std::string& given, const std::string& why) { throw InputError("parameter '" + given + "': " + why); }

int namedLight(const Scene& scene, const ParameterName& n) {
  const int l = lightIndex(scene, n.parts[1]);
  if (l >= 0) return l;
  std::vector<std::string> names;
  for (const auto& x : scene.lights) names.push_back(x.name);
  failParameter(n.given, "no light named '" + n.parts[1] + "'" + closestName(n.parts[1], names));
}

Vec3 motionVector(const RigidMotion& m, int firstField) { return firstField == 0 ? m.translation : m.rotationDegrees; }

void setMotionVector(RigidMotion& m, int firstField, const float* in, int component) {
  Vec3& v = firstField == 0 ? m.translation : m.rotationDegrees;
  if (component >= 0) v[component] = in[0];
  else v = Vec3(in[0], in[1], in[2]);
}

void refuseSameValue(const ParameterName& n, int offset, const std::vector<ParameterSlot>& earlier) {
  if (offset < 0) return;
  for (const auto& other : earlier)
    if (int(other.offset) == offset) failParameter(n.given, "the same value as parameter '" + other.name + "', listed twice");
}

void ParameterTables::markMoving(const Scene& scene, uint32_t m) {
  if (moving.size() < scene.meshes.size()) moving.resize(scene.meshes.size(), 0);
  if (moving[m]) return;
  moving[m] = 1;
  movingMeshes.insert(std::lower_bound(movingMeshes.begin(), movingMeshes.end(), m), m);
}

std::string invrParameterName(const Scene& scene, const std::string& name) {
  if (name.find('/') != std::string::npos || name.find('.') == std::string::npos) return name;
  // A Mitsuba 3 key (mi.traverse): <object path>.<property>[.value|.data], in each kind's terms.
  auto fail = [&](const std::string& why) -> std::string { throw InputError("parameter '" + name + "' (a Mitsuba name): " + why); };
  auto parts = split(name, '.');
  for (const auto& p : parts)
    if (p.empty()) return fail("empty component");
  // <id>.data alone: a bitmap that is the object's value itself (an envmap's).
  const bool data = parts.back() == "data";
  if (parts.size() == 2 && data)
    for (const ParameterKind* k : parameterKinds())
      if (std::string invr = k->fromMitsuba(scene, {parts[0]}, "", true); !invr.empty()) return invr;
  if (parts.back() == "value" || data) parts.pop_back();
  if (parts.size() < 2) return fail("expected <id>.<property>.value (or .data for a bitmap), e.g. red.reflectance.value");
  const std::string prop = parts.back();
  const std::vector<std::string> owner(parts.begin(), parts.end() - 1);
  std::vector<std::string> known;
  for (const ParameterKind* k : parameterKinds()) {
    if (std::string invr = k->fromMitsuba(scene, owner, prop, data); !invr.empty()) return invr;
    if (std::string p = k->mitsubaProperties(); !p.empty() && std::find(known.begin(), known.end(), p) == known.end()) known.push_back(p);
  }
  return fail("property '" + prop + "' has no invr parameter (" + [&] {
    std::string out;
    for (size_t i = 0; i < known.size(); ++i) out += (i == 0 ? "" : "; ") + known[i];
    return out;
  }() + ")");
}

const ParameterSlot& ParameterRegistry::add(const Scene& scene, const std::string& givenName, const ParameterOptions& o) {
  auto fail = [&](const std::string& why) -> const ParameterSlot& { failParameter(givenName, why); };
  if (find(givenName)) return fail("listed twice");
  const ParameterName name{givenName, split(invrParameterName(scene, givenName))};
  const auto& parts = name.parts;
  const ParameterKind* kind = nullptr;
  std::vector<std::string> groups, inGroup, usages, usagesInGroup;
  for (const ParameterKind* k : parameterKinds()) {
    for (const std::string& g : k->groups())
      if (std::find(groups.begin(), groups.end(), g) == groups.end()) groups.push_back(g);
    usages.push_back(k->usage());
    const auto g = k->groups();
    if (!parts.empty() && std::find(g.begin(), g.end(), parts[0]) != g.end()) {
      inGroup.push_back(k->property());
      usagesInGroup.push_back(k->usage());
    }
    if (!kind && k->claims(parts)) kind = k;
  }
  if (!kind) {
    if (inGroup.empty()) {
      if (parts.size() != 3) return fail("expected " + listOf(usages));
      return fail("unknown parameter group '" + parts[0] + "' (use " + listOf(groups) + ")");
    }
    if (parts[0] == "sampling" || parts.size() < 3) return fail("expected " + listOf(usagesInGroup));
    const std::string noun = parts[0].substr(0, parts[0].size() - 1);  // materials -> material
    return fail("unknown " + noun + " property '" + parts[2] + "' (use " + listOf(inGroup) + ")");
  }
  ParameterSlot slot = kind->bind(scene, name, o, t_, slots_);
  slot.name = givenName;
  slot.kind = kind;
  applyOptions(slot, o);
  t_.nextSlot = int(slots_.size());
  kind->attach(scene, slot, t_);
  size_ += slot.size;
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
    if (!slot.kind->isMesh()) fail("large_steps_lambda applies to vertex parameters (shapes/<name>/vertices) only");
    if (!(*o.largeStepsLambda >= 0.f) || !std::isfinite(*o.largeStepsLambda))
      fail("large_steps_lambda must be a finite number >= 0 (got " + std::to_string(*o.largeStepsLambda) + ")");
    slot.largeStepsLambda = *o.largeStepsLambda;
  }
  if (!(slot.lower <= slot.upper)) fail("bounds are inverted (lower " + std::to_string(slot.lower) + " > upper " + std::to_string(slot.upper) + ")");
  if (!(slot.learningRate > 0.f) || !std::isfinite(slot.learningRate)) fail("learning rate must be a positive finite number");
}

void ParameterRegistry::addHitGradient(const Scene& scene, const SurfaceHit& hit, Vec3 dLdp, Vec3 dLdn, PathGradient& grad) const {
  if (!moves(hit.mesh)) return;
  const bool normal = !(dLdn == Vec3(0.f));
  if (!deforms(hit.mesh)) {
    addPointGradient(scene, hit.mesh, hit.p, dLdp, grad);
    if (normal) addNormalGradient(scene, hit.mesh, hit.ns, dLdn, grad);
    return;
  }
  const ParameterTables::VertexField& f = t_.vertices(hit.mesh);
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
  if (t_.normalAdjoints == 0) return;
  INVR_INVARIANT(gradient.size() == adjointSize(), "the gradient holds the vertex-normal entries");
  if (normals)
    for (const ParameterTables::VertexField& f : t_.vertexFields) {
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
  const ParameterTables::VertexField& f = t_.vertices(mesh);
  for (const auto& [v, w] : {std::pair{v0, 1.f - t}, std::pair{v1, t}}) {
    const uint32_t base = f.offset + 3 * f.weld[v];
    for (uint32_t c = 0; c < 3; ++c)
      if (dLdp[int(c)] != 0.f && w != 0.f) grad.add(base + c, dLdp[int(c)] * w);
  }
}

void ParameterRegistry::addPointGradient(const Scene& scene, uint32_t mesh, Vec3 p, Vec3 dLdp, PathGradient& grad) const {
  if (!moves(mesh)) return;
  for (const auto& f : t_.meshFields[mesh]) grad.add(f.index, dot(dLdp, scene.motion.pointVelocity(mesh, f.field, p)));
}

void ParameterRegistry::addCameraPointGradient(const Scene& scene, int view, Vec3 p, Vec3 dLdp, PathGradient& grad) const {
  if (!movesCamera(view)) return;
  for (const auto& f : t_.cameraFields[size_t(view)]) grad.add(f.index, dot(dLdp, scene.cameraPointVelocity(view, f.field, p)));
}

void ParameterRegistry::addNormalGradient(const Scene& scene, uint32_t mesh, Vec3 n, Vec3 dLdn, PathGradient& grad) const {
  if (!moves(mesh)) return;
  for (const auto& f : t_.meshFields[mesh]) grad.add(f.index, dot(dLdn, scene.motion.normalVelocity(mesh, f.field, n)));
}

const ParameterSlot* ParameterRegistry::find(const std::string& name) const {
  for (const auto& s : slots_)
    if (s.name == name) return &s;
  return nullptr;
}

std::vector<float> ParameterRegistry::read(const Scene& scene) const {
  std::vector<float> theta(size_);
  for (const auto& s : slots_) s.kind->read(scene, s, t_, theta.data() + s.offset);
  return theta;
}

void ParameterRegistry::write(const std::vector<float>& theta, Scene& scene, bool refreshSampling) const {
  if (theta.size() != size_) throw InputError("parameter vector has " + std::to_string(theta.size()) + " values, expected " + std::to_string(size_));
  SceneChanges changes;
  for (const auto& s : slots_) s.kind->write(theta.data() + s.offset, s, t_, scene, refreshSampling, changes);
  if (!t_.rigidMeshes.empty()) scene.applyShapeMotion(t_.rigidMeshes);
  if (hasCameraParameters()) scene.applyCameraMotion();
  // Logits are sampling itself: always applied. Power-based selection follows emission unless
  // the caller keeps sampling fixed.
  if (changes.selection || (changes.emission && refreshSampling)) scene.updateLightSelection();
}

void ParameterRegistry::clampToBounds(std::vector<float>& theta) const {
  for (const auto& s : slots_)
    for (uint32_t i = 0; i < s.size; ++i) theta[s.offset + i] = std::clamp(theta[s.offset + i], s.lower, s.upper);
}

std::string describeParameters(const ParameterRegistry& r) {
  std::string out;
  for (const auto& s : r.slots()) {
    out += s.name + "[" + std::to_string(s.size) + "]";
    if (s.width > 0) out += " (" + std::to_string(s.width) + "x" + std::to_string(s.height) + (s.kind->changesNoiseOnly() ? " map)" : " texture)");
    out += "\n";
  }
  return out;
}

}  // namespace invr
