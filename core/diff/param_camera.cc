// Camera parameters (calibration): a view's pose relative to the camera as described, about its
// eye (Scene::cameraMotion):
//   cameras/<view>/translation   x, y, z in world space: 3 values, starting at 0
//   cameras/<view>/rotation      Euler degrees about the world's x, then y, then z: 3 values
//   .../translation/x (y, z), .../rotation/x (y, z)   one component alone
// <view> is a camera's name or index, or * for every view together (one offset applied to each
// camera about its own eye: a rig's shared error). Moving a camera moves every image point, so
// these take the interior term of every camera hit (shape_interior.h) and the boundary terms of
// every mesh edge and shadow border in the moving view (ParameterRegistry::movesOnFilm).
#include <cstdlib>
#include <limits>

#include "core/diff/parameter_kind.h"
#include "core/error.h"

namespace invr {

namespace {

class CameraPoseKind : public ParameterKind {
 public:
  std::vector<std::string> groups() const override { return {"cameras"}; }
  std::string usage() const override { return "cameras/<view>/" + property() + " (<view>: a camera's name or index, or * for all; one component: .../" + property() + "/x, y or z)"; }

  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>& earlier) const override {
    const auto& parts = n.parts;
    int component = -1;
    if (parts.size() == 4 && parts[3].size() == 1 && parts[3][0] >= 'x' && parts[3][0] <= 'z') component = parts[3][0] - 'x';
    else if (parts.size() != 3)
      failParameter(n.given, "expected cameras/<view>/translation or rotation, or one component: cameras/<view>/translation/x (or y, z), .../rotation/x (or y, z)");
    if (scene.cameras.empty()) failParameter(n.given, "the scene has no camera");
    ParameterSlot slot;
    slot.view = viewIndex(scene, n);
    slot.channels = component >= 0 ? 1 : 3;
    slot.component = component;
    slot.size = uint32_t(slot.channels);
    defaults(slot, scene);
    for (const auto& other : earlier) {
      if (other.kind != this) continue;
      const bool sameView = other.view == slot.view || other.view < 0 || slot.view < 0;
      if (sameView && (other.component < 0 || slot.component < 0 || other.component == slot.component))
        failParameter(n.given, "the same value as parameter '" + other.name + "', listed twice (cameras/*/... moves every view)");
    }
    (void)tables;
    return slot;
  }
  void attach(const Scene& scene, const ParameterSlot& slot, ParameterTables& t) const override {
    if (t.cameraFields.size() < scene.cameras.size()) t.cameraFields.resize(scene.cameras.size());
    const int first = firstField() + std::max(slot.component, 0);
    for (size_t v = 0; v < scene.cameras.size(); ++v)
      if (slot.view < 0 || size_t(slot.view) == v)
        for (int c = 0; c < slot.channels; ++c) t.cameraFields[v].push_back({slot.offset + uint32_t(c), first + c});
  }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables&, float* out) const override {
    const size_t v = size_t(std::max(s.view, 0));
    const Vec3 x = v < scene.cameraMotion.size() ? motionVector(scene.cameraMotion[v], firstField()) : Vec3(0.f);
    if (s.component >= 0) out[0] = x[s.component];
    else
      for (int c = 0; c < 3; ++c) out[c] = x[c];
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool, SceneChanges&) const override {
    scene.cameraMotion.resize(scene.cameras.size());
    for (size_t v = 0; v < scene.cameras.size(); ++v)
      if (s.view < 0 || size_t(s.view) == v) setMotionVector(scene.cameraMotion[v], firstField(), in, s.component);  // the registry applies it
  }
  void offer(const Scene& scene, std::vector<OfferedName>& out) const override {
    for (size_t v = 0; v < scene.cameras.size(); ++v) {
      const std::string& name = scene.cameras[v].name;
      out.push_back({"cameras/" + (name.empty() ? std::to_string(v) : name) + "/" + property(), {}, int(v)});
    }
    if (scene.cameras.size() > 1) out.push_back({"cameras/*/" + property(), {}, int(scene.cameras.size())});
  }
  int catalogChannels(const ParameterSlot& slot) const override { return slot.component >= 0 ? 1 : 3; }
  // An exported scene holds the moved cameras as its sensors.
  bool relativeToGeometry() const override { return true; }
  bool varianceDerivatives() const override { return false; }

 protected:
  virtual int firstField() const = 0;  // RigidMotion's component of x: 0 translation, 3 rotation
  virtual void defaults(ParameterSlot& slot, const Scene& scene) const = 0;

 private:
  // A camera's name, else its index; * for every view (-1).
  static int viewIndex(const Scene& scene, const ParameterName& n) {
    const std::string& v = n.parts[1];
    if (v == "*") return -1;
    std::vector<std::string> names;
    for (size_t i = 0; i < scene.cameras.size(); ++i) {
      names.push_back(scene.cameras[i].name);
      if (scene.cameras[i].name == v) return int(i);
    }
    char* end = nullptr;
    const long i = std::strtol(v.c_str(), &end, 10);
    if (!v.empty() && *end == '\0' && i >= 0 && i < long(scene.cameras.size())) return int(i);
    failParameter(n.given, "no camera named '" + v + "' (the scene's views: " + std::to_string(scene.cameras.size()) +
                               ", by name or index 0.." + std::to_string(scene.cameras.size() - 1) + ", or * for all)" + closestName(v, names));
  }
};

class CameraTranslationKind final : public CameraPoseKind {
 public:
  const char* name() const override { return "camera_translation"; }
  std::string property() const override { return "translation"; }

 protected:
  int firstField() const override { return 0; }
  void defaults(ParameterSlot& slot, const Scene& scene) const override {
    slot.lower = -std::numeric_limits<float>::infinity();
    slot.upper = std::numeric_limits<float>::infinity();
    slot.learningRate = 2.5e-3f * scene.radius;  // as a shape's translation
  }
};

class CameraRotationKind final : public CameraPoseKind {
 public:
  const char* name() const override { return "camera_rotation"; }
  std::string property() const override { return "rotation"; }

 protected:
  int firstField() const override { return 3; }
  void defaults(ParameterSlot& slot, const Scene&) const override {
    slot.lower = -180.f;
    slot.upper = 180.f;
    // Degrees: a camera's turn moves the whole image (a degree is about H / (2 * fov) pixels), so
    // a tenth of a shape's default.
    slot.learningRate = 0.05f;
  }
};

const RegisterParameterKind kCameraTranslation(50, std::make_unique<CameraTranslationKind>());
const RegisterParameterKind kCameraRotation(51, std::make_unique<CameraRotationKind>());

}  // namespace

}  // namespace invr
