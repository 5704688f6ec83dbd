// lights/<l>/intensity: an area or constant-environment light's radiance, or a point or spot
// light's intensity (3 values). An image environment's radiance is its texels
// (param_environment_texels.cc).
#include <limits>

#include "core/diff/parameter_kind.h"
#include "core/error.h"

namespace invr {

namespace {

class LightIntensityKind final : public ParameterKind {
 public:
  const char* name() const override { return "light_intensity"; }
  std::vector<std::string> groups() const override { return {"lights"}; }
  std::string property() const override { return "intensity"; }
  std::string usage() const override { return "lights/<name>/intensity"; }

  ParameterSlot bind(const Scene& scene, const ParameterName& n, const ParameterOptions&, const ParameterTables& tables,
                     const std::vector<ParameterSlot>& earlier) const override {
    if (n.parts.size() != 3) failParameter(n.given, "expected " + usage());
    const int l = namedLight(scene, n);
    if (scene.lights[size_t(l)].kind == LightKind::Environment)
      failParameter(n.given, "an image environment map's radiance is its texels: use lights/" + n.parts[1] + "/texels (Mitsuba: " + n.parts[1] + ".data)");
    ParameterSlot slot;
    slot.light = l;
    slot.channels = 3;
    slot.size = 3;
    slot.lower = kPositiveFloor;
    slot.upper = std::numeric_limits<float>::infinity();
    refuseSameValue(n, ParameterTables::lookup(tables.intensity, l), earlier);
    return slot;
  }
  void attach(const Scene&, const ParameterSlot& slot, ParameterTables& tables) const override {
    ParameterTables::put(tables.intensity, size_t(slot.light), int(slot.offset));
  }
  void read(const Scene& scene, const ParameterSlot& s, const ParameterTables&, float* out) const override {
    const Light& l = scene.lights[size_t(s.light)];
    const Rgb v = l.isDelta() ? l.intensity : l.radiance;
    out[0] = v.x;
    out[1] = v.y;
    out[2] = v.z;
  }
  void write(const float* in, const ParameterSlot& s, const ParameterTables&, Scene& scene, bool, SceneChanges& changes) const override {
    Light& l = scene.lights[size_t(s.light)];
    (l.isDelta() ? l.intensity : l.radiance) = Rgb(in[0], in[1], in[2]);
    changes.emission = true;
  }
  void offer(const Scene& scene, std::vector<OfferedName>& out) const override {
    for (size_t l = 0; l < scene.lights.size(); ++l) {
      const std::string& n = scene.lights[l].name;
      std::vector<std::string> mi = {n + ".radiance.value", n + ".intensity.value"};
      for (size_t s = 0; s < scene.meshLight.size(); ++s)
        if (scene.meshLight[s] == int(l)) mi.push_back(scene.meshNames[s] + ".emitter.radiance.value");
      out.push_back({"lights/" + n + "/intensity", mi, int(l)});
    }
  }
  std::string fromMitsuba(const Scene& scene, const std::vector<std::string>& owner, const std::string& prop, bool) const override {
    if (prop != "radiance" && prop != "intensity") return "";
    auto fail = [&](const std::string& why) -> std::string {
      std::string key;
      for (const auto& o : owner) key += o + ".";
      throw InputError("parameter '" + key + prop + "' (a Mitsuba name): " + why);
    };
    if (owner.size() == 1 && lightIndex(scene, owner[0]) >= 0) return "lights/" + owner[0] + "/intensity";
    // <shape id>.emitter: the area light on that shape.
    if (owner.size() == 2 && owner[1] == "emitter") {
      const int m = meshIndex(scene, owner[0]);
      if (m < 0) return fail("no shape with id '" + owner[0] + "'");
      if (scene.meshLight[size_t(m)] < 0) return fail("shape '" + owner[0] + "' does not emit");
      return "lights/" + scene.lights[size_t(scene.meshLight[size_t(m)])].name + "/intensity";
    }
    return fail("no emitter with id '" + owner[0] + "'");
  }
  std::string mitsubaProperties() const override { return "radiance or intensity of an emitter"; }
  bool zeroBiasesReuse() const override { return true; }
};

const RegisterParameterKind kLightIntensity(20, std::make_unique<LightIntensityKind>());

}  // namespace

}  // namespace invr
