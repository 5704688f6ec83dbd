// Shape parameters (Wang et al. 2023's shape half; core/scene/shape_motion.h): a shape's or a
// group's pose relative to the scene as described, about its pivot.
//   shapes/<name>/translation   x, y, z: 3 values, starting at 0
//   shapes/<name>/rotation      Euler degrees about x, then y, then z: 3 values, starting at 0
//   shapes/<name>/scale         uniform: 1 value, starting at 1
//   .../translation/x (y, z), .../rotation/x (y, z)   one component alone
//   groups/<name>/...           the same for a group of shapes (applied after the members' own)
// The estimators read the velocity fields of each moving mesh (ParameterTables::meshFields).
#include <algorithm>
#include <limits>

#include "core/diff/parameter_kind.h"
#include "core/error.h"

namespace invr {

namespace {

class PoseKind : public ParameterKind {
 public:
  std::vector<std::string> groups() const override { return {"shapes", "groups"}; }
  std::string usage() const override {
    return "shapes/<name>/" + property() + " (groups/<name>/" + property() + " for a group" +
           (hasComponents() ? "; one component: .../" + property() + "/x, y or z)" : ")");
  }

  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>& earlier) const override {
    const auto& parts = n.parts;
    const bool isGroup = parts[0] == "groups";
    // One component of a translation or rotation on its own: the degrees of freedom a problem has.
    int component = -1;
    if (parts.size() == 4 && hasComponents() && parts[3].size() == 1 && parts[3][0] >= 'x' && parts[3][0] <= 'z') component = parts[3][0] - 'x';
    else if (parts.size() != 3)
      failParameter(n.given, "expected " + parts[0] + "/<name>/translation, rotation or scale, or one component: " + parts[0] +
                                 "/<name>/translation/x (or y, z), .../rotation/x (or y, z)");
    ParameterSlot slot;
    std::vector<uint32_t> meshes;
    if (isGroup) {
      std::vector<std::string> names;
      for (size_t g = 0; g < scene.groups.size(); ++g) {
        names.push_back(scene.groups[g].name);
        if (scene.groups[g].name == parts[1]) slot.group = int(g);
      }
      if (slot.group < 0) failParameter(n.given, "no group named '" + parts[1] + "' (scene.groups)" + closestName(parts[1], names));
      meshes = scene.groups[size_t(slot.group)].meshes;
    } else {
      slot.shape = meshIndex(scene, parts[1]);
      if (slot.shape < 0) failParameter(n.given, "no shape named '" + parts[1] + "'" + closestName(parts[1], scene.meshNames));
      meshes = {uint32_t(slot.shape)};
    }
    for (uint32_t m : meshes) {
      if (scene.meshLight[m] >= 0)
        failParameter(n.given, "shape '" + scene.meshNames[m] + "' emits light ('" + scene.lights[size_t(scene.meshLight[m])].name +
                                   "'): moving emitters is not supported yet");
      // A mesh moves either rigidly or vertex by vertex.
      if (tables.deforms(m))
        failParameter(n.given, "shape '" + scene.meshNames[m] + "' has its vertices as a parameter; a pose parameter cannot move it too (move the vertices)");
    }
    defaults(slot, scene);
    if (component >= 0) {
      slot.channels = 1;
      slot.component = component;
    }
    slot.size = uint32_t(slot.channels);
    for (const auto& other : earlier)
      if (other.kind == this && other.shape == slot.shape && other.group == slot.group &&
          (other.component < 0 || slot.component < 0 || other.component == slot.component))
        failParameter(n.given, "the same value as parameter '" + other.name + "', listed twice");
    return slot;
  }
  void attach(const Scene& scene, const ParameterSlot& slot, ParameterTables& t) const override {
    checkBounds(slot);
    const bool isGroup = slot.group >= 0;
    const std::vector<uint32_t> meshes = isGroup ? scene.groups[size_t(slot.group)].meshes : std::vector<uint32_t>{uint32_t(slot.shape)};
    const int first = firstField() + std::max(slot.component, 0);
    if (t.meshFields.size() < scene.meshes.size()) t.meshFields.resize(scene.meshes.size());
    for (uint32_t m : meshes) {
      for (int c = 0; c < slot.channels; ++c)
        t.meshFields[m].push_back({slot.offset + uint32_t(c), first + c + (isGroup ? RigidMotion::kComponents : 0)});
      if (std::find(t.rigidMeshes.begin(), t.rigidMeshes.end(), m) == t.rigidMeshes.end()) t.rigidMeshes.push_back(m);
      t.markMoving(scene, m);
    }
    std::sort(t.rigidMeshes.begin(), t.rigidMeshes.end());
  }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables&, float* out) const override {
    const Vec3 v = value(motion(scene, s));
    if (s.component >= 0) out[0] = v[s.component];
    else
      for (int c = 0; c < s.channels; ++c) out[c] = v[c];
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool, SceneChanges&) const override {
    RigidMotion& m = s.group >= 0 ? scene.motion.group(uint32_t(s.group)) : scene.motion.mesh(uint32_t(s.shape));
    set(m, in, s.component);  // the registry applies the motion once every kind has written
  }
  void offer(const Scene& scene, std::vector<OfferedName>& out) const override {
    for (size_t m = 0; m < scene.meshNames.size(); ++m) out.push_back({"shapes/" + scene.meshNames[m] + "/" + property(), {}, int(m)});
    for (size_t g = 0; g < scene.groups.size(); ++g) out.push_back({"groups/" + scene.groups[g].name + "/" + property(), {}, kGroupsAfterShapes + int(g)});
  }
  // Listed as vectors of 3 (a component alone as 1).
  int catalogChannels(const ParameterSlot& slot) const override { return slot.component >= 0 ? 1 : 3; }
  bool relativeToGeometry() const override { return true; }

  static constexpr int kGroupsAfterShapes = 1 << 20;

 protected:
  virtual bool hasComponents() const { return true; }
  virtual int firstField() const = 0;  // ShapeMotion's field of the first component
  virtual void defaults(ParameterSlot& slot, const Scene& scene) const = 0;
  virtual void checkBounds(const ParameterSlot&) const {}
  virtual Vec3 value(const RigidMotion& m) const = 0;
  virtual void set(RigidMotion& m, const float* in, int component) const = 0;
  static const RigidMotion& motion(const Scene& scene, const ParameterSlot& s) {
    return s.group >= 0 ? scene.motion.group(uint32_t(s.group)) : scene.motion.mesh(uint32_t(s.shape));
  }
};

class TranslationKind final : public PoseKind {
 public:
  const char* name() const override { return "translation"; }
  std::string property() const override { return "translation"; }

 protected:
  int firstField() const override { return 0; }
  void defaults(ParameterSlot& slot, const Scene& scene) const override {
    slot.channels = 3;
    slot.lower = -std::numeric_limits<float>::infinity();
    slot.upper = std::numeric_limits<float>::infinity();
    // In the scene's units: a step of 1/400 of its radius (0.011 on the zoo's pose scene).
    slot.learningRate = 2.5e-3f * scene.radius;
  }
  Vec3 value(const RigidMotion& m) const override { return motionVector(m, 0); }
  void set(RigidMotion& m, const float* in, int c) const override { setMotionVector(m, 0, in, c); }
};

class RotationKind final : public PoseKind {
 public:
  const char* name() const override { return "rotation"; }
  std::string property() const override { return "rotation"; }

 protected:
  int firstField() const override { return 3; }
  void defaults(ParameterSlot& slot, const Scene&) const override {
    slot.channels = 3;
    slot.lower = -360.f;
    slot.upper = 360.f;
    slot.learningRate = 0.5f;  // degrees
  }
  Vec3 value(const RigidMotion& m) const override { return motionVector(m, 3); }
  void set(RigidMotion& m, const float* in, int c) const override { setMotionVector(m, 3, in, c); }
};

class ScaleKind final : public PoseKind {
 public:
  const char* name() const override { return "scale"; }
  std::string property() const override { return "scale"; }

 protected:
  bool hasComponents() const override { return false; }
  int firstField() const override { return 6; }
  void defaults(ParameterSlot& slot, const Scene&) const override {
    slot.channels = 1;
    slot.lower = 0.01f;
    slot.upper = 100.f;
    slot.learningRate = 0.01f;
  }
  void checkBounds(const ParameterSlot& slot) const override {
    if (!(slot.lower > 0.f)) failParameter(slot.name, "the lower bound of a scale must be positive");
  }
  Vec3 value(const RigidMotion& m) const override { return Vec3(m.scale); }
  void set(RigidMotion& m, const float* in, int) const override { m.scale = in[0]; }
};

const RegisterParameterKind kTranslation(30, std::make_unique<TranslationKind>());
const RegisterParameterKind kRotation(31, std::make_unique<RotationKind>());
const RegisterParameterKind kScale(32, std::make_unique<ScaleKind>());

}  // namespace

}  // namespace invr
